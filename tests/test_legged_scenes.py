"""Legged scene files ([model] kind = "legged", geoddp.scene.legged) and their result JSON.

The built-in scenes anymal_walk, anymal_trot and anymal_jump build the problems of
geoddp.scene.legged.anymal_walk / anymal_trot / anymal_jump (Crocoddyl's, node for node:
tests/test_contact_crocoddyl.py), node for node, and the same J on random controls; written as
[[phases]], the walk and the trot are those nodes too. Every bad key or value is refused naming
its key path. ``geoddp run anymal_trot --json`` writes configurations (H+1, 19), velocities
(H+1, 18), controls (H, 12) with zero rows exactly at the impulse nodes, the contact schedule, and
J* equal to the cost of its own controls.
"""
from __future__ import annotations

import copy
import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from geoddp import data
from geoddp.cli import EXIT_BAD_INPUT, EXIT_CONVERGED, EXIT_NOT_CONVERGED, main
from geoddp.scene import LeggedSceneSpec, load_scene, parse_scene
from geoddp.scene.legged import FEET, anymal_gait, load_anymal
from geoddp.validate import InputError

LF, RF, LH, RH = FEET


@pytest.fixture(scope="module")
def robot():
    return load_anymal()


def _same_nodes(a, b) -> None:
    """Node lists (terminal node last) equal: kinds, feet, CoM and swing targets bit for bit."""
    assert len(a) == len(b)
    for k, (x, y) in enumerate(zip(a, b)):
        assert (x.kind, x.feet) == (y.kind, y.feet), k
        assert (x.com is None) == (y.com is None), k
        if x.com is not None:
            assert np.array_equal(x.com, y.com), k
        assert [f for f, _ in x.swing] == [f for f, _ in y.swing], k
        assert all(np.array_equal(p, q) for (_, p), (_, q) in zip(x.swing, y.swing)), k


def _same_problem(ours, ref, seed=0) -> None:
    _same_nodes(ours.nodes + [ours.terminal_node], ref.nodes + [ref.terminal_node])
    assert ours.dt == ref.dt and ours.dyn.gains == ref.dyn.gains
    assert np.array_equal(ours.q0, ref.q0) and np.array_equal(ours.q_ref, ref.q_ref)
    U = np.random.default_rng(seed).standard_normal((ref.horizon, ref.nu))
    J, J_ref = (p.trajectory_cost(p.trajectory(U)) for p in (ours, ref))
    assert np.isfinite(J_ref) and J_ref > 0
    assert J == pytest.approx(J_ref, rel=1e-12, abs=0)


@pytest.mark.parametrize("gait,H,impulses", [("walk", 108, 4), ("trot", 56, 2), ("jump", 60, 1)])
def test_builtin_scene_is_the_python_problem(robot, gait, H, impulses):
    spec = load_scene(f"anymal_{gait}")
    assert isinstance(spec, LeggedSceneSpec) and spec.horizon == H and spec.num_inputs == 12
    ours = spec.build(robot)
    assert ours.horizon == H and int(ours.impulse_rows.sum()) == impulses
    _same_problem(ours, anymal_gait(gait, robot))


def _phase(contacts, knots, length=None, height=None, **kw):
    t = {"contacts": list(contacts), "knots": knots, **kw}
    if length is not None:
        t.update(step_length=length, step_height=height)
    return t


BASE = {"model": {"kind": "legged", "robot": "anymal", "feet": list(FEET)}, "contact": {"dt": 0.01}}
# Crocoddyl's walk and trot as phases: support knots, (half) steps of the swing feet, each landing
# by an impulse node because the next phase (or the terminal node) has the foot down
WALK = [_phase(FEET, 2), _phase((LF, RF, LH), 25, 0.125, 0.15), _phase((LF, LH, RH), 25, 0.125, 0.15),
        _phase(FEET, 2), _phase((LF, RF, RH), 25, 0.25, 0.15), _phase((RF, LH, RH), 25, 0.25, 0.15)]
TROT = [_phase(FEET, 2), _phase((LF, RH), 25, 0.075, 0.1), _phase(FEET, 2), _phase((RF, LH), 25, 0.15, 0.1)]


@pytest.mark.parametrize("gait,phases", [("walk", WALK), ("trot", TROT)])
def test_phases_are_the_gait(robot, gait, phases):
    spec = parse_scene({**BASE, "phases": phases})
    assert spec.gait is None and spec.horizon == anymal_gait(gait, robot).horizon
    _same_problem(spec.build(robot), anymal_gait(gait, robot), seed=1)


def test_phases_land_the_feet_that_touch_down(robot):
    """A flight (no foot down) lands all four feet by one impulse; a rising flight followed by a
    falling one has none between them; impulse = false drops a touch-down; a phase without a step
    has no targets."""
    spec = parse_scene({**BASE, "phases": [_phase(FEET, 3), _phase((), 4), _phase((), 4), _phase(FEET, 3),
                                           _phase((LF, RF), 5, impulse=False), _phase(FEET, 2)]})
    p = spec.build(robot)
    kinds = [n.kind for n in p.nodes]
    assert spec.horizon == p.horizon == 3 + 4 + 4 + 1 + 3 + 5 + 2
    assert [k for k, kind in enumerate(kinds) if kind == "impulse"] == [11]
    ids = tuple(int(robot.model.getFrameId(f)) for f in FEET)
    assert p.nodes[11].feet == ids and p.nodes[10].feet == () and p.nodes[15].feet == ids[:2]
    assert all(n.com is None and not n.swing for n in p.nodes)
    assert p.terminal_node.feet == ids and p.terminal_node.kind == "contact"


# ------------------------------------------------------------------ bad tables
def _gait_scene(**gait):
    return {**copy.deepcopy(BASE), "gait": {"type": "trot", "step_length": 0.15, "step_height": 0.1, "step_knots": 25,
                                            "support_knots": 2, **gait}}


def _edit(table, key, value):
    def f(d):
        if value is None:
            del d[table][key]
        else:
            d[table][key] = value
        return d
    return f


def _phases(phases):
    return lambda d: {**{k: val for k, val in d.items() if k != "gait"}, "phases": phases}


BAD = {
    "step_knots_zero": (_edit("gait", "step_knots", 0), "[gait].step_knots", "integer >= 1"),
    "step_knots_float": (_edit("gait", "step_knots", 2.5), "[gait].step_knots", "integer >= 1"),
    "support_knots_bool": (_edit("gait", "support_knots", True), "[gait].support_knots", "integer >= 1"),
    "step_length_nan": (_edit("gait", "step_length", float("nan")), "[gait].step_length", "finite"),
    "gait_type": (_edit("gait", "type", "gallop"), "[gait].type", "walk"),
    "gait_key_of_jump": (_edit("gait", "jump_height", 0.1), "[gait].jump_height", 'not used by type = "trot"'),
    "gait_missing_key": (_edit("gait", "step_height", None), "[gait].step_height", "missing"),
    "gait_unknown_key": (lambda d: {**d, "gait": {**d["gait"], "step_lenght": 0.1}}, "[gait].step_lenght",
                         "did you mean 'step_length'"),
    "jump_length": (lambda d: {**d, "gait": {"type": "jump", "jump_height": 0.1, "jump_length": [0.3, 0.0],
                                             "ground_knots": 2, "flying_knots": 2}}, "[gait].jump_length", "(3,)"),
    "unknown_table": (lambda d: {**d, "gaits": {}}, "[gaits]", "did you mean [gait]"),
    "robot_unknown": (_edit("model", "robot", "anymall"), "[model].robot", "'anymal'"),
    "robot_fixed_base": (_edit("model", "robot", "ur5"), "[model].robot", "free-flyer"),
    "robot_missing": (_edit("model", "robot", None), "[model].robot", "missing"),
    "posture": (_edit("model", "posture", "sitting"), "[model].posture", "standing"),
    "foot_typo": (_edit("model", "feet", ["LF_FOT", RF, LH, RH]), "[model].feet[0]", "did you mean 'LF_FOOT'"),
    "foot_twice": (_edit("model", "feet", [LF, RF, LH, LF]), "[model].feet[3]", "twice"),
    "feet_not_a_list": (_edit("model", "feet", "LF_FOOT"), "[model].feet", "list of contact frame names"),
    "gait_three_feet": (_edit("model", "feet", [LF, RF, LH]), "[model].feet", "four feet"),
    "model_unknown_key": (_edit("model", "urdf", "anymal.urdf"), "[model].urdf", "unknown key"),
    "dt_negative": (_edit("contact", "dt", -0.01), "[contact].dt", "> 0"),
    "dt_missing": (_edit("contact", "dt", None), "[contact].dt", "missing"),
    "gains_negative": (_edit("contact", "baumgarte", [0.0, -50.0]), "[contact].baumgarte", ">= 0"),
    "gains_shape": (_edit("contact", "baumgarte", [0.0, 50.0, 1.0]), "[contact].baumgarte", "(2,)"),
    "both_schedules": (lambda d: {**d, "phases": [_phase(FEET, 2)]}, "[gait]", "exactly one"),
    "no_schedule": (lambda d: {k: val for k, val in d.items() if k != "gait"}, "[gait]", "exactly one"),
    "phases_empty": (_phases([]), "phases", "at least one"),
    "phase_foot": (_phases([_phase(FEET, 2), _phase((LF, "RH_FOT"), 4)]), "phases[1].contacts[1]",
                   "did you mean 'RH_FOOT'"),
    "phase_knots_missing": (_phases([{"contacts": list(FEET)}]), "phases[0].knots", "missing"),
    "phase_knots_negative": (_phases([_phase(FEET, -2)]), "phases[0].knots", "integer >= 1"),
    "phase_unknown_key": (_phases([{**_phase(FEET, 2), "stepheight": 0.1}]), "phases[0].stepheight",
                          "did you mean 'step_height'"),
    "phase_step_without_swing": (_phases([_phase(FEET, 2, 0.1, 0.1)]), "phases[0].step_length", "swing foot"),
    "phase_height_without_length": (_phases([_phase((LF, RF), 2, step_height=0.1)]), "phases[0].step_height",
                                    "step_length"),
    "phase_impulse_nothing_lands": (_phases([_phase((), 3, impulse=True), _phase((), 3)]), "phases[0].impulse",
                                    "nothing touches down"),
    "phase_impulse_not_bool": (_phases([_phase((LF, RF), 3, impulse=1)]), "phases[0].impulse", "true or false"),
    "cost_mu_zero": (lambda d: {**d, "costs": {"mu": 0.0}}, "[costs].mu", "> 0"),
    "cost_negative": (lambda d: {**d, "costs": {"com": -1.0}}, "[costs].com", ">= 0"),
    "cost_unknown": (lambda d: {**d, "costs": {"impulse_control": 1.0}}, "[costs].impulse_control", "unknown key"),
    "initial_controls": (lambda d: {**d, "solver": {"initial_controls": "hover"}}, "[solver].initial_controls",
                         "quasi_static"),
    "max_iter": (lambda d: {**d, "solver": {"max_iter": 0}}, "[solver].max_iter", "integer >= 1"),
    "solver_limits_key": (lambda d: {**d, "solver": {"constraint_tol": 1e-6}}, "[solver].constraint_tol",
                          "only with [[constraints]]"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_legged_table_names_the_key(case):
    edit, parameter, fragment = BAD[case]
    with pytest.raises(InputError) as e:
        parse_scene(edit(_gait_scene()), "scene.toml")
    assert e.value.parameter == parameter, str(e.value)
    assert fragment in str(e.value) and "scene.toml" in str(e.value)


def test_a_bad_file_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('[model]\nkind = "legged"\nrobot = "anymal"\nfeet = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\n'
                    '[contact]\ndt = 0.01\n[gait]\ntype = "walk"\nstep_length = 0.25\nstep_height = 0.15\n'
                    'step_knots = 0\nsupport_knots = 2\n')
    assert main(["run", str(path), "--quiet"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("geoddp: error: [gait].step_knots: expected an integer >= 1")


@pytest.mark.parametrize("command", ["simulate", "compare"])
def test_commands_without_a_legged_form_refuse_before_solving(command, capsys):
    assert main([command, "anymal_trot"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "legged scene" in err and "geoddp run anymal_trot" in err


# ------------------------------------------------------------------ the result JSON
def _check_json(d, problem) -> None:
    """Shapes, zero rows exactly at the impulse nodes, the schedule as built, J* the cost of the
    file's own controls, no null inside any array."""
    H = problem.horizon
    Q, V, U = (np.array(d[k], dtype=float) for k in ("configurations", "velocities", "controls"))
    assert Q.shape == (H + 1, 19) and V.shape == (H + 1, 18) and U.shape == (H, 12)
    sched = d["model"]["contact_schedule"]
    impulse = np.array(sched["impulse"])
    assert impulse.shape == (H,) and np.array_equal(impulse, problem.impulse_rows)
    assert np.all(U[impulse] == 0.0) and np.all(np.any(U[~impulse] != 0.0, axis=1))
    ids = [int(problem.model.getFrameId(f)) for f in sched["feet"]]
    assert sched["feet"] == list(FEET) and sched["baumgarte"] == [0.0, 50.0]
    assert sched["contact"] == [[int(i in n.feet) for i in ids] for n in problem.nodes + [problem.terminal_node]]
    traj = problem.trajectory(U)
    assert np.allclose(traj.q, Q, rtol=0, atol=1e-12) and np.allclose(traj.v, V, rtol=0, atol=1e-12)
    assert d["cost"] == pytest.approx(problem.trajectory_cost(traj), rel=1e-12)
    assert d["iterations"] == len(d["cost_history"]) - 1 >= 1

    def no_null_in_arrays(x):
        if isinstance(x, list):
            assert all(item is not None for item in x)
            for item in x:
                no_null_in_arrays(item)
        elif isinstance(x, dict):
            for item in x.values():
                no_null_in_arrays(item)
    no_null_in_arrays(d)


def test_run_anymal_trot_writes_the_result_json(robot, tmp_path, capsys):
    out = tmp_path / "out" / "trot.json"
    assert main(["run", "anymal_trot", "--json", str(out), "--quiet"]) == EXIT_CONVERGED
    text = out.read_text()
    assert "NaN" not in text and "Infinity" not in text
    d = json.loads(text)
    assert d["status"].startswith("converged") and d["converged"] and d["expansion"] == "first"
    _check_json(d, load_scene("anymal_trot").build(robot))
    printed = capsys.readouterr().out
    assert f"J* = {d['cost']:.12f}" in printed and "56 nodes (2 impulse)" in printed


def test_run_a_short_phase_schedule_stopped_early(robot, tmp_path, capsys):
    """A scene of one's own: 2 support knots, a 6-knot trot step of LF and RH (their landing impulse),
    2 support knots; stopped after 2 iterations (exit 1), its JSON complete all the same."""
    scene = tmp_path / "short.toml"
    scene.write_text('[model]\nkind = "legged"\nrobot = "anymal"\nfeet = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\n'
                     '[contact]\ndt = 0.01\n'
                     '[[phases]]\ncontacts = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\nknots = 2\n'
                     '[[phases]]\ncontacts = ["RF_FOOT", "LH_FOOT"]\nknots = 6\nstep_length = 0.05\nstep_height = 0.05\n'
                     '[[phases]]\ncontacts = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]\nknots = 2\n'
                     '[solver]\nmax_iter = 2\n')
    out = tmp_path / "short.json"
    assert main(["run", str(scene), "--json", str(out), "--quiet"]) == EXIT_NOT_CONVERGED
    d = json.loads(out.read_text())
    problem = load_scene(scene).build(robot)
    assert problem.horizon == 11 and np.flatnonzero(problem.impulse_rows).tolist() == [8]
    assert d["iterations"] == 2 and not d["converged"]
    _check_json(d, problem)


# ------------------------------------------------------------------ the guide
GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "legged.md"


def test_the_guides_scene_and_errors_are_the_code():
    """The legged guide's TOML block is the built-in trot's file (but for its max_iter), and its
    error lines are the parser's messages (up to the file name and the list of feet)."""
    text = GUIDE.read_text()
    block = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    ours, builtin = parse_scene(tomllib.loads(block)), load_scene("anymal_trot")
    for field in ("robot", "feet", "posture", "dt", "baumgarte", "gait", "phases", "costs", "expansion",
                  "initial_controls"):  # the file also caps max_iter
        assert getattr(ours, field) == getattr(builtin, field), field
    errors = re.search(r"```text\n(.*?)```", text[text.index("Errors name the key path"):], re.S).group(1)
    cases = [_edit("gait", "step_knots", 0), BAD["phase_foot"][0]]
    for line, edit in zip(errors.strip().splitlines(), cases):
        with pytest.raises(InputError) as e:
            parse_scene(edit(_gait_scene()), "trot.toml")
        shown = line.removeprefix("geoddp: error: ").removesuffix(" ...")
        assert str(e.value).startswith(shown), (str(e.value), shown)


def test_solve_scene_takes_a_legged_scene_and_its_solver_keywords(robot):
    """``geoddp.solve_scene`` overrides [solver] keys of a legged scene: initial_controls = "zero"
    starts from zero torques (the first J is their cost), max_iter stops; a key a legged scene has
    no use for, or a bad value, is refused naming it."""
    from geoddp import solve_scene

    res = solve_scene("anymal_trot", initial_controls="zero", max_iter=1)
    problem = load_scene("anymal_trot").build(robot)
    J_zero = problem.trajectory_cost(problem.trajectory(np.zeros((problem.horizon, problem.nu))))
    assert res.iterations == 1 and res.cost_history[0] == pytest.approx(J_zero, rel=1e-12)
    assert res.cost < res.cost_history[0] and res.extra["scene"] == "anymal_trot"
    for key, value in (("initial_controls", "hover"), ("second_order", "paper"), ("constraint_tol", 1e-6)):
        with pytest.raises(InputError) as e:
            solve_scene("anymal_trot", **{key: value})
        assert e.value.parameter == key


def test_a_sweep_over_gait_parameters(tmp_path):
    """A sweep file varies a legged scene's [gait] keys like any other key: each case is the scene
    with that value, solved (the J of each row is that scene's own solve)."""
    from geoddp import solve_scene
    from geoddp.sweep import read_table, run_sweep

    sweep = tmp_path / "trot_knots.toml"
    sweep.write_text('[sweep]\nscene = "anymal_trot"\nname = "trot_knots"\n[grid]\n"gait.step_knots" = [4, 6]\n'
                     '"solver.max_iter" = [2]\n')
    run_sweep(sweep, tmp_path / "out", serial=True)
    df = read_table(tmp_path / "out").sort_values("gait.step_knots")
    assert df["error"].tolist() == ["", ""] and df["iterations"].tolist() == [2, 2]
    base = tomllib.loads(data.scene_path("anymal_trot").read_text())
    for knots, J in zip(df["gait.step_knots"], df["J"]):
        scene = {**base, "gait": {**base["gait"], "step_knots": int(knots)}, "solver": {**base["solver"], "max_iter": 2}}
        assert J == pytest.approx(solve_scene(parse_scene(scene)).cost, rel=1e-12)


def test_run_anymal_trot_draws_forces_and_contacts(robot, tmp_path, capsys):
    """``geoddp run anymal_trot --plots DIR --html PAGE``: the legged figures (contact forces,
    friction-cone margins beside the joints and controls) and a replay whose force arrows are the
    contact forces of the solved trajectory (1 mm per newton), on the collision geometry."""
    from geoddp.scene import build_problem
    from geoddp.solver.result import Result
    from geoddp.viz import legged_forces
    from geoddp.viz.html import decode_commands

    out, plots, page = tmp_path / "trot.json", tmp_path / "plots", tmp_path / "trot.html"
    assert main(["run", "anymal_trot", "--quiet", "--json", str(out), "--plots", str(plots), "--html", str(page)]) \
        == EXIT_CONVERGED
    assert {p.name for p in plots.iterdir()} >= {"contact_forces.png", "friction_margin.png", "joint_positions.png",
                                                 "controls.png", "solver_history.png"}
    res = Result.read_json(out)
    c = legged_forces(res, build_problem(load_scene("anymal_trot")))
    cmds = decode_commands(page.read_text())
    assert any(cmd.get("type") == "set_object" and cmd["path"].endswith("/contacts/ground") for cmd in cmds)
    anim = [cmd for cmd in cmds if cmd.get("type") == "set_animation"][-1]
    clips = {e["path"]: e["clip"] for e in anim["animations"]}
    i = c.feet.index("LF_FOOT")
    shaft = next(v for p, v in clips.items() if p.endswith("/contacts/forces/LF_FOOT/shaft"))
    scale = [k["value"][1] for k in next(t for t in shaft["tracks"] if t["name"] == ".scale")["keys"]]
    on = np.flatnonzero(c.active[:, i] & ~c.impulse)
    assert on.size > 10
    np.testing.assert_allclose(np.asarray(scale)[on], 1e-3 * np.linalg.norm(c.forces[on, i], axis=-1), rtol=1e-9)
    assert page.stat().st_size < 4e6  # the collision geometry, not ANYmal's 30 MB of visual meshes
