"""A solved ANYmal trot's contact forces, friction-cone margins, replay and figures
(:mod:`geoddp.problem.legged_forces`, :mod:`geoddp.viz.legged`, :mod:`geoddp.viz.contact_shapes`).

Physics: at every contact node the feet's forces sum to m (a_com - g) (Newton's law for the whole
robot, a_com the CoM acceleration of the node's dynamics) and at every impulse node the impulses to
m (v_com+ - v_com); over the gait the vertical forces and impulses average the weight (up to the
momentum gained and the semi-implicit step's discretisation). The stance feet hold: their speed is
the Baumgarte-damped drift of semi-implicit Euler (millimetres per second, not zero: the contact
is a constraint on accelerations), and the force stays inside Crocoddyl's four-facet cone up to
the soft barrier's slack. The replay page holds the ground, the contact points shown at the frames
their foot is on the ground, and arrows whose lengths are force times scale; the figures' lines are
the forces.

Needs example-robot-data (the ``test`` extra): imported at module top, so a missing install fails.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import example_robot_data  # noqa: F401  (required: see the module docstring)
import numpy as np
import pinocchio as pin
import pytest

from geoddp.problem.legged_forces import ContactForces, contact_forces
from geoddp.scene.legged import anymal_trot, load_anymal
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError
from geoddp.viz import animation_frame_count
from geoddp.viz.contact_shapes import HEAD_LENGTH, ContactScene
from geoddp.viz.html import STATUS_ID, decode_commands
from geoddp.viz.legged import LEGGED_FIGURES, export_legged_html, legged_figures, legged_forces, plot_legged
from viz_fixtures import OFFLINE_FLAG, chromium_or_skip, keyframes, run_chromium, screenshot

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


def _pixels(img: np.ndarray) -> dict[str, int]:
    """Pixels of the force arrows' blue (0x20C0FF) and the contact points' yellow (0xFFD020)."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return {"arrows": int(np.count_nonzero((r < 90) & (g > 150) & (b > 200))),
            "points": int(np.count_nonzero((r > 200) & (g > 160) & (b < 90)))}


@pytest.fixture(scope="module")
def solved():
    problem = anymal_trot(load_anymal())
    result = solve(problem, SolverOptions(expansion="first"))
    assert result.converged, result.message
    return problem, result, legged_forces(result, problem)


# ------------------------------------------------------------------ physics


def test_forces_balance_the_momentum_at_every_node(solved):
    problem, res, c = solved
    weight = c.mass * 9.81
    assert c.forces.shape == (problem.horizon, 4, 3) and c.feet == ("LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT")
    contact = ~c.impulse
    assert c.impulse.sum() == 2 and np.array_equal(np.flatnonzero(c.impulse), [27, 55])
    # Newton: sum_f f = m (a_com - g) at each contact node, to round-off
    np.testing.assert_allclose(c.total[contact], c.momentum_change[contact], rtol=0, atol=1e-9 * weight)
    # and the impulses: sum_f Lambda = m (v_com+ - v_com)
    np.testing.assert_allclose(c.total[c.impulse], c.momentum_change[c.impulse], rtol=0, atol=1e-12 * c.mass)
    # the forces are the node dynamics' own (world frame) and zero off the feet of the node
    for k in (0, 10, 27, 40):
        node = problem.nodes[k]
        ev = problem.node(k, res.q[k], res.v[k], res.controls[k])[0]
        cols = [c.frame_ids.index(f) for f in node.feet]
        np.testing.assert_array_equal(c.forces[k, cols].ravel(), ev.forces)
        assert not np.any(np.delete(c.forces[k], cols, axis=0))
        assert list(np.flatnonzero(c.active[k])) == cols


def test_vertical_forces_average_the_weight(solved):
    problem, res, c = solved
    m, d = problem.model, problem.model.createData()
    contact = ~c.impulse
    T = contact.sum() * c.dt  # impulse nodes take no time
    vz = []
    for k in (0, problem.horizon):
        pin.centerOfMass(m, d, res.q[k], res.v[k])
        vz.append(d.vcom[0][2])
    vertical = c.dt * c.total[contact, 2].sum() + c.total[c.impulse, 2].sum()  # N s over the gait
    weight = c.mass * 9.81
    expected = weight * T + c.mass * (vz[1] - vz[0])
    assert vertical == pytest.approx(expected, rel=1e-4)
    assert vertical / T == pytest.approx(weight, rel=1e-3)  # on average the feet carry the weight
    assert c.dt * c.total[contact, 2].sum() / T == pytest.approx(weight, rel=1e-3)


def test_stance_feet_hold_and_forces_stay_in_the_cone(solved):
    problem, res, c = solved
    contact = ~c.impulse
    stance = c.active & contact[:, None]
    speed = np.linalg.norm(c.velocities[:-1], axis=-1)[stance]
    # Baumgarte damping (Kd = 50/s) of semi-implicit Euler's drift: millimetres per second, where
    # the swinging feet move at a metre per second
    swing = np.linalg.norm(c.velocities[:-1], axis=-1)[~c.on_ground[:-1]]
    assert speed.max() < 2e-3, speed.max()
    assert speed.max() < 2e-3 * swing.max()
    # over a whole stance the foot stays put (under 0.2 mm)
    for i in range(4):
        run = np.flatnonzero(stance[:, i])
        for seg in np.split(run, np.flatnonzero(np.diff(run) > 1) + 1):
            p = c.positions[seg[0]:seg[-1] + 2, i]
            assert np.linalg.norm(p - p[0], axis=-1).max() < 2e-4
    # every stance force pushes, and stays in the 4-facet cone up to the barrier's slack (0.1 % of
    # the weight): the cone is a cost (weight 10), not a constraint
    fz = c.normal[stance]
    assert fz.min() > 0.0
    facet = c.facet_margin[stance]
    assert facet.min() > -1e-3 * c.mass * 9.81, facet.min()
    # the circular cone is inside the facets' pyramid: its margin is never larger
    assert np.all(c.cone_margin[stance] <= facet + 1e-12)
    # the margins by their formulas
    f = c.forces[stance]
    np.testing.assert_allclose(c.cone_margin[stance], 0.7 * f[:, 2] - np.hypot(f[:, 0], f[:, 1]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(facet, 0.7 * f[:, 2] - np.abs(f[:, :2]).max(axis=1), rtol=0, atol=1e-12)
    assert np.all(np.isnan(c.cone_margin[~c.active]))


def test_margins_of_another_friction_coefficient(solved):
    problem, res, c = solved
    c2 = legged_forces(res, problem, mu=0.5, facets=8)
    np.testing.assert_array_equal(c2.forces, c.forces)
    stance = c.active
    assert np.allclose(c2.cone_margin[stance], c.cone_margin[stance] - 0.2 * c.forces[stance][:, 2])
    # 8 facets: an outer approximation tighter than 4
    cone = c2.cone_margin[stance]
    assert np.all(cone <= c2.facet_margin[stance] + 1e-12)
    gap = c2.facet_margin[stance] - cone  # |f_t| (1 - cos(angle to the nearest facet)), at most 22.5 deg
    assert np.all(gap <= c.tangential[stance] * (1 - np.cos(np.pi / 8)) + 1e-9)
    assert np.all(gap <= c.facet_margin[stance] - c.cone_margin[stance] + 1e-9)


def test_bad_inputs_name_the_parameter(solved):
    problem, res, c = solved
    with pytest.raises(InputError, match="configurations"):
        contact_forces(problem, res.q[:-1], res.v, res.controls)
    with pytest.raises(InputError, match="controls"):
        contact_forces(problem, res.q, res.v, res.controls[:, :3])
    with pytest.raises(InputError, match="mu"):
        contact_forces(problem, res.q, res.v, res.controls, mu=-1.0)
    with pytest.raises(InputError, match="facets"):
        contact_forces(problem, res.q, res.v, res.controls, facets=3)
    with pytest.raises(InputError, match="force_scale"):
        ContactScene(c, force_scale=0.0)
    with pytest.raises(InputError, match="problem"):
        legged_forces(res, object())


# ------------------------------------------------------------------ replay


def _clips(commands: list[dict]) -> dict[str, dict]:
    anim = [cmd for cmd in commands if cmd.get("type") == "set_animation"][-1]
    return {e["path"]: e["clip"] for e in anim["animations"]}


def _track(clip: dict, name: str) -> list:
    return [k["value"] for k in next(t for t in clip["tracks"] if t["name"] == name)["keys"]]


@pytest.fixture(scope="module")
def page(solved, tmp_path_factory):
    problem, res, c = solved
    path = export_legged_html(res, problem, tmp_path_factory.mktemp("legged") / "trot.html", force_scale=2e-3,
                              impulse_scale=0.5, geometry="collision")
    text = path.read_text()
    return path, text, decode_commands(text)


def test_replay_holds_the_ground_points_and_arrows(solved, page):
    problem, res, c = solved
    path, text, cmds = page
    H = problem.horizon
    assert animation_frame_count(text) == H + 1  # every track, the contacts' too, has H + 1 keys
    objects = {cmd["path"]: cmd for cmd in cmds if cmd.get("type") == "set_object"}
    ground = next(cmd for p, cmd in objects.items() if p.endswith("/contacts/ground"))
    geom = ground["object"]["geometries"][0]
    lo, hi = c.positions.reshape(-1, 3).min(axis=0), c.positions.reshape(-1, 3).max(axis=0)
    assert geom["type"] == "BoxGeometry"
    assert geom["width"] == pytest.approx(hi[0] - lo[0] + 1.0) and geom["height"] == pytest.approx(hi[1] - lo[1] + 1.0)
    top = [cmd for cmd in cmds if cmd.get("type") == "set_transform" and cmd["path"].endswith("/contacts/ground")][-1]
    T = np.array(top["matrix"]).reshape(4, 4).T
    assert T[2, 3] + 0.5 * geom["depth"] == pytest.approx(c.positions[0, :, 2].mean(), abs=1e-12)  # feet at z = 2e-6
    clips = _clips(cmds)
    for i, foot in enumerate(c.feet):
        # contact points: at the foot, shown exactly when the foot is on the ground
        pt = next(v for p, v in clips.items() if p.endswith(f"/contacts/points/{foot}"))
        np.testing.assert_allclose(keyframes(pt)[:, :3, 3], c.positions[:, i], atol=1e-12)
        assert _track(pt, ".visible") == list(c.on_ground[:, i])
        # force arrows: shaft length = |f| * 2 mm/N at each contact node where the foot carries a force
        shaft = next(v for p, v in clips.items() if p.endswith(f"/contacts/forces/{foot}/shaft"))
        head = next(v for p, v in clips.items() if p.endswith(f"/contacts/forces/{foot}/head"))
        shown = np.array(_track(shaft, ".visible"))
        assert list(shown) == list(np.append(c.active[:, i] & ~c.impulse, False))
        assert _track(head, ".visible") == list(shown)
        L = np.array([s[1] for s in _track(shaft, ".scale")])
        f = np.linalg.norm(c.forces[:, i], axis=-1)
        np.testing.assert_allclose(L[:-1][shown[:-1]], 2e-3 * f[shown[:-1]], rtol=1e-12)
        S, Hd = keyframes(shaft), keyframes(head)
        for k in np.flatnonzero(shown)[::7]:
            d = c.forces[k, i] / f[k]
            np.testing.assert_allclose(S[k, :3, 3], c.positions[k, i] + 0.5 * L[k] * d, atol=1e-12)
            np.testing.assert_allclose(S[k, :3, 1], d, atol=1e-12)  # the cylinder's +y along the force
            np.testing.assert_allclose(Hd[k, :3, 3], c.positions[k, i] + (L[k] + 0.5 * HEAD_LENGTH) * d, atol=1e-12)
    # the impulses of the landing feet at the impulse nodes, 0.5 m/(N s)
    for k in np.flatnonzero(c.impulse):
        for i in np.flatnonzero(c.active[k]):
            shaft = next(v for p, v in clips.items() if p.endswith(f"/contacts/impulses/{c.feet[i]}/shaft"))
            vis = _track(shaft, ".visible")
            assert vis[k] and sum(vis) == 1
            assert _track(shaft, ".scale")[k][1] == pytest.approx(0.5 * np.linalg.norm(c.forces[k, i]), rel=1e-12)


def test_replay_page_loads_in_chromium(solved, page):
    chromium_or_skip()
    problem, res, c = solved
    path, text, cmds = page
    dom = run_chromium(path.as_uri(), "--dump-dom", OFFLINE_FLAG).stdout
    m = re.search(r'<pre id="%s"[^>]*>(.*?)</pre>' % STATUS_ID, dom, flags=re.DOTALL)
    import json

    status = json.loads(m.group(1))
    assert status["loaded"] is True and status["commands"] == len(cmds)
    # every clip's every track (position, quaternion, scale, visible) has H + 1 keys in the viewer
    assert {n for clip in status["frames"] for n in clip} == {problem.horizon + 1}
    assert status["duration"] == pytest.approx(problem.horizon * c.dt)
    # drawn: at a stance frame the arrows and points are on screen; at the last frame (no node
    # dynamics) the arrows are hidden while the points stay
    shots = {}
    for tag, t in (("stance", 0.15), ("last", problem.horizon * c.dt)):
        img = screenshot(f"{path.as_uri()}#t={t}", path.with_name(f"{tag}.png"), OFFLINE_FLAG)
        shots[tag] = _pixels(img)
    print(shots)
    assert shots["stance"]["arrows"] > 150 and shots["stance"]["points"] > 50
    assert shots["last"]["arrows"] == 0 and shots["last"]["points"] > 50
    if os.environ.get("GEODDP_WRITE_FIGURES"):
        shutil.copy(path.with_name("stance.png"), FIGURES / "replay_anymal_trot.png")


# ------------------------------------------------------------------ figures


def test_figures_hold_the_forces(solved, tmp_path):
    problem, res, c = solved
    paths = legged_figures(res, problem, tmp_path)
    assert {p.name for p in paths} >= {f"{n}.png" for n in LEGGED_FIGURES} | {"joint_positions.png", "controls.png"}
    assert all(p.stat().st_size > 10_000 for p in paths)
    figs = plot_legged(res, problem, tmp_path / "again", forces=c)
    contact = ~c.impulse
    fig = figs.data["contact_forces"].figure
    axes = fig.axes
    total, needed = axes[0].lines[0], axes[0].lines[1]
    np.testing.assert_array_equal(total.get_xdata(), c.times)
    np.testing.assert_allclose(total.get_ydata()[contact], c.total[contact, 2], rtol=0, atol=0)
    assert np.all(np.isnan(total.get_ydata()[c.impulse]))
    np.testing.assert_allclose(needed.get_ydata()[contact], total.get_ydata()[contact], rtol=0, atol=1e-9 * c.mass * 9.81)
    for i, foot in enumerate(c.feet):
        ax = axes[1 + i]
        assert ax.get_title().startswith(foot)
        fz, ft = ax.lines[0].get_ydata(), ax.lines[1].get_ydata()
        on = c.active[:, i] & contact
        np.testing.assert_array_equal(fz[on], c.forces[on, i, 2])
        np.testing.assert_allclose(ft[on], np.hypot(c.forces[on, i, 0], c.forces[on, i, 1]), rtol=1e-14, atol=0)
        assert np.all(np.isnan(fz[~on]))
        # the impulse nodes are marked: dotted vertical lines at their times
        marks = [ln.get_xdata()[0] for ln in ax.lines if ln.get_linestyle() == ":"]
        np.testing.assert_allclose(marks, c.times[c.impulse])
    margins = figs.data["friction_margin"].figure.axes
    for i in range(4):
        on = c.active[:, i] & contact
        np.testing.assert_array_equal(margins[i].lines[0].get_ydata()[on], c.cone_margin[on, i])
        np.testing.assert_array_equal(margins[i].lines[1].get_ydata()[on], c.facet_margin[on, i])
    assert isinstance(c, ContactForces)
