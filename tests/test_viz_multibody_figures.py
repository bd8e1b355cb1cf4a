"""Figures of a multibody Result (``geoddp run SCENE --plots DIR``, :func:`geoddp.viz.plot_multibody`):
the files the CLI writes, read back as images, and the data drawn in them (the matplotlib lines and
step patches) against the Result's arrays and the scene's frame targets.

The UR5 scene needs example-robot-data (the ``test`` extra): imported at module top on purpose, so
a missing install fails here instead of skipping.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import example_robot_data  # noqa: F401  (required: see the module docstring)
import matplotlib.image as mpimg
import numpy as np
import pinocchio as pin
import pytest
from matplotlib.lines import Line2D
from matplotlib.patches import StepPatch

from geoddp import cli, viz
from geoddp import solve_scene
from geoddp import Result
from geoddp.scene import frame_errors, load_scene, terminal_frame_errors
from geoddp.validate import InputError
from geoddp.viz.multibody_figures import joint_panels, rotation_vectors
from viz_fixtures import synthetic_result
from viz_meshes import trajectory_result

MULTIBODY_FILES = {f"{n}.png" for n in viz.MULTIBODY_FIGURES}


@functools.lru_cache(maxsize=None)
def solved(name: str):
    spec = load_scene(name)
    return spec, solve_scene(spec, verbose=False)


def read_png(path: Path) -> np.ndarray:
    """The image as matplotlib reads it back: (h, w, 4) floats in [0, 1], checked not blank."""
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4) and img.shape[0] > 300 and img.shape[1] > 500, img.shape
    rgb = img[..., :3]
    # not a blank canvas: white background with a few percent of drawn pixels, many distinct colours
    drawn = np.mean(rgb.min(axis=2) < 0.9)
    assert 0.01 < drawn < 0.6, f"{path.name}: {drawn:.1%} of the pixels drawn"
    assert len(np.unique((rgb * 255).astype(np.uint8).reshape(-1, 3), axis=0)) > 50
    return img


def lines_of(ax) -> dict[str, Line2D]:
    """The labelled lines of an axes (legend-only entries and markers left out), label -> line."""
    return {ln.get_label(): ln for ln in ax.get_lines() if not ln.get_label().startswith("_") and len(ln.get_xdata())}


def run_cli(argv, capsys) -> tuple[int, str]:
    code = cli.main(argv)
    return code, capsys.readouterr().out


# ----------------------------------------------------------------------------- the CLI


@pytest.mark.parametrize("scene", ["ur5_reach", "quadrotor_thrust_limits"])
def test_cli_run_writes_the_multibody_figures(scene, tmp_path, capsys):
    """`geoddp run SCENE --plots DIR` exits 0 and writes exactly the five figures (no temporary file
    left), each a readable, non-blank image; they are the figures of the Result it wrote (--json),
    pixel for pixel as plot_multibody draws them from that Result and the scene."""
    out, res = tmp_path / "figs", tmp_path / "r.json"
    code, text = run_cli(["run", scene, "--quiet", "--plots", str(out), "--json", str(res)], capsys)
    assert code == 0
    assert {p.name for p in out.iterdir()} == MULTIBODY_FILES
    for name in MULTIBODY_FILES:
        assert f"wrote {out / name}" in text
    result = Result.read_json(res)
    figs = viz.plot_multibody(result, tmp_path / "api", scene=load_scene(scene))
    assert set(figs) == set(viz.MULTIBODY_FIGURES)
    for name, path in figs.items():
        np.testing.assert_array_equal(read_png(out / f"{name}.png"), mpimg.imread(path))


def test_multibody_alias_takes_plots_too(tmp_path, capsys):
    """`geoddp multibody NAME` is `geoddp run NAME`: it has --plots as well."""
    code, _ = run_cli(["multibody", "space_manipulator", "--quiet", "--plots", str(tmp_path)], capsys)
    assert code == 0 and {p.name for p in tmp_path.iterdir()} == MULTIBODY_FILES


def test_cli_satellite_plots_add_the_solver_history(tmp_path, capsys):
    """A satellite scene keeps its three figures and gets the solver history as well."""
    code, _ = run_cli(["run", "satellite_paper", "--quiet", "--plots", str(tmp_path)], capsys)
    assert code == 0
    assert {p.name for p in tmp_path.iterdir()} == {"quaternion.png", "angular_velocity.png", "controls.png",
                                                      "solver_history.png"}
    read_png(tmp_path / "solver_history.png")


# ----------------------------------------------------------------------------- the data drawn


def test_ur5_joint_figures_draw_the_result(tmp_path):
    """Fixed base: one panel of the six joint angles (rad) and one of their velocities (rad/s),
    each line the Result's column of that joint, labelled with its name, against time."""
    spec, result = solved("ur5_reach")
    figs = viz.plot_multibody(result, tmp_path, scene=spec)
    model = viz.load_model(result.multibody)
    names = [model.names[j] for j in range(1, model.njoints)]
    for key, X in (("joint_positions", result.configurations), ("joint_velocities", result.velocities)):
        (ax,) = figs.data[key].figure.axes
        lines = lines_of(ax)
        assert list(lines) == names
        for j, name in enumerate(names):
            np.testing.assert_array_equal(lines[name].get_xdata(), result.times)
            np.testing.assert_array_equal(lines[name].get_ydata(), X[:, j])
        assert ax.get_ylabel() == ("angle [rad]" if key == "joint_positions" else "velocity [rad/s]")


def test_free_flyer_root_drawn_as_translation_and_rotation_vector(tmp_path):
    """Quadrotor (free-flyer root): the positions are the world translation (m) and the rotation
    vector r_k with exp3(r_k) = R_k (not the quaternion), continuous in time; the velocities the
    body-frame linear and angular velocity, columns of v."""
    spec, result = solved("quadrotor_thrust_limits")
    figs = viz.plot_multibody(result, tmp_path, scene=spec)
    ax_t, ax_r = figs.data["joint_positions"].figure.axes
    Q = result.configurations
    for i, line in enumerate(lines_of(ax_t).values()):
        np.testing.assert_array_equal(line.get_ydata(), Q[:, i])
    r = np.column_stack([ln.get_ydata() for ln in lines_of(ax_r).values()])
    R = result.rotations
    assert max(np.abs(pin.exp3(r[k]) - R[k]).max() for k in range(len(r))) < 1e-12
    assert np.abs(np.diff(r, axis=0)).max() < 0.05  # continuous: no 2 pi jump
    ax_v, ax_w = figs.data["joint_velocities"].figure.axes
    V = result.velocities
    np.testing.assert_array_equal(np.column_stack([ln.get_ydata() for ln in lines_of(ax_v).values()]), V[:, 0:3])
    np.testing.assert_array_equal(np.column_stack([ln.get_ydata() for ln in lines_of(ax_w).values()]), V[:, 3:6])
    assert "m/s" in ax_v.get_ylabel() and "rad/s" in ax_w.get_ylabel()


def test_controls_figure_draws_the_controls_and_the_limits(tmp_path):
    """Quadrotor with rotor thrusts in [0, 4] N: the four inputs as steps equal to the controls, the
    two bounds dashed (shared by the four rotors: once each, in grey), and one shaded span per
    saturated interval of the active set (138 (node, rotor) pairs on the upper bound)."""
    spec, result = solved("quadrotor_thrust_limits")
    figs = viz.plot_multibody(result, tmp_path, scene=spec)
    (ax,) = figs.data["controls"].figure.axes
    steps = [p for p in ax.patches if isinstance(p, StepPatch)]
    solid = [p for p in steps if p.get_linestyle() == "solid"]
    dashed = [p for p in steps if p.get_linestyle() == "--"]
    assert len(solid) == 4
    for j, p in enumerate(solid):
        values, edges, _ = p.get_data()
        np.testing.assert_array_equal(values, result.controls[:, j])
        np.testing.assert_array_equal(edges, result.times)
    assert sorted(float(np.unique(p.get_data()[0])[0]) for p in dashed) == [0.0, 4.0]
    assert all(np.unique(p.get_data()[0]).size == 1 for p in dashed)
    act = result.active_set
    assert (act == 1).sum() == 138
    runs = sum(int(np.sum(np.diff(np.concatenate(([0], (act[:, j] != 0).astype(int), [0]))) == 1))
               for j in range(act.shape[1]))
    spans = figs.data["controls"].arrays["saturated"]
    assert len(spans) == runs > 0
    shaded = [p for p in ax.patches if not isinstance(p, StepPatch)]
    assert len(shaded) == runs


def test_frame_errors_are_the_scenes_terms_along_the_trajectory(tmp_path):
    """UR5: the tool0 placement term's position error (m) and rotation error (deg) at every time
    step, computed here from Pinocchio directly; the last values are what `geoddp run` prints."""
    spec, result = solved("ur5_reach")
    figs = viz.plot_multibody(result, tmp_path, scene=spec)
    ax_p, ax_r = figs.data["frame_errors"].figure.axes
    ((label, line_p),) = lines_of(ax_p).items()
    ((_, line_r),) = lines_of(ax_r).items()
    assert label == "frame_placement (tool0)" and ax_p.get_yscale() == "log"
    (term,) = [c for c in spec.terminal_costs if c.frame == "tool0"]
    model = viz.load_model(result.multibody)
    data = model.createData()
    p_err, r_err = [], []
    for q in result.configurations:
        pin.framesForwardKinematics(model, data, q)
        M = data.oMf[model.getFrameId("tool0")]
        p_err.append(np.linalg.norm(M.translation - term.reference[:3, 3]))
        r_err.append(np.degrees(np.linalg.norm(pin.log3(term.reference[:3, :3].T @ M.rotation))))
    np.testing.assert_allclose(line_p.get_ydata(), p_err, rtol=1e-12, atol=0)
    np.testing.assert_allclose(line_r.get_ydata(), r_err, rtol=1e-12, atol=0)
    (printed,) = terminal_frame_errors(spec, result.configurations[-1])
    assert line_p.get_ydata()[-1] == printed["position_error_m"] and line_r.get_ydata()[-1] == printed["rotation_error_deg"]
    assert line_p.get_ydata()[0] > 50 * line_p.get_ydata()[-1]  # the reach: 0.40 m to 4.7 mm


def test_frame_errors_without_the_scene_use_the_results_targets(tmp_path):
    """Without the scene, the frame targets the Result records (its terminal frame_placement term)
    give the same errors as the scene's term."""
    spec, result = solved("ur5_reach")
    (from_scene,) = frame_errors(spec, result.configurations)
    arrays = viz.plot_multibody(result, tmp_path).data["frame_errors"].arrays
    np.testing.assert_array_equal(arrays["tool0/position_error_m"], from_scene["position_error_m"])
    np.testing.assert_array_equal(arrays["tool0/rotation_error_deg"], from_scene["rotation_error_deg"])


def test_solver_history_draws_cost_and_gradient_per_iteration(tmp_path):
    """J_i and ||dJ/dU||_i at every iterate (0 .. iterations), log scale; the second-order iterates
    filled, as the Result's expansion history says."""
    spec, result = solved("quadrotor_thrust_limits")
    figs = viz.plot_multibody(result, tmp_path, scene=spec)
    ax_j, ax_g = figs.data["solver_history"].figure.axes
    for ax, y in ((ax_j, result.cost_history), (ax_g, result.grad_norm_history)):
        (curve,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
        np.testing.assert_array_equal(curve.get_xdata(), np.arange(result.iterations + 1))
        np.testing.assert_array_equal(curve.get_ydata(), y)
        assert ax.get_yscale() == "log"
        marks = {ln.get_label(): ln for ln in ax.get_lines() if ln.get_linestyle() in ("None", "")}
        # iterate i (1 ..) was reached by iteration i - 1's step
        second = [i + 1 for i, e in enumerate(result.expansion_history) if e == "second"]
        assert list(marks["second-order step"].get_xdata()) == second and second
        assert list(marks["first-order step"].get_xdata()) == [i for i in range(result.iterations + 1) if i not in second]


# ----------------------------------------------------------------------------- joints of every kind

CONTINUOUS_URDF = """<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="spin" type="continuous"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="slide" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="10"/></joint>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>
"""


def test_continuous_and_prismatic_joints(tmp_path):
    """A continuous joint (q = (cos theta, sin theta)) is drawn as its angle theta, unwrapped past
    pi; a prismatic joint in its own panel, in metres."""
    urdf = tmp_path / "mixed.urdf"
    urdf.write_text(CONTINUOUS_URDF)
    theta = np.linspace(0.0, 5.0, 31)  # beyond pi: atan2 alone would jump by 2 pi
    x = 0.3 * np.sin(theta)
    Q = np.column_stack([np.cos(theta), np.sin(theta), x])
    result = trajectory_result(urdf, Q, dt=0.1)
    figs = viz.plot_multibody(result, tmp_path / "figs")
    assert "frame_errors" not in figs and {p.name for p in (tmp_path / "figs").iterdir()} == MULTIBODY_FILES - {
        "frame_errors.png"}
    ax_r, ax_p = figs.data["joint_positions"].figure.axes
    np.testing.assert_allclose(lines_of(ax_r)["spin"].get_ydata(), theta, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(lines_of(ax_p)["slide"].get_ydata(), x)
    assert ax_r.get_ylabel() == "angle [rad]" and ax_p.get_ylabel() == "position [m]"


def test_spherical_root_and_rotation_vectors():
    """A spherical root is one panel of its rotation vector; rotation_vectors follows a turn of
    5 rad about a fixed axis as theta * axis (past pi, no jump)."""
    a = np.array([1.0, 2.0, 2.0]) / 3.0
    th = np.linspace(0.0, 5.0, 60)
    r = rotation_vectors(np.stack([pin.exp3(t * a) for t in th]))
    np.testing.assert_allclose(r, th[:, None] * a, rtol=0, atol=1e-10)
    model = pin.buildModelFromUrdf(str(viz.model.SATELLITE_URDF), pin.JointModelSpherical())
    Q = np.array([pin.Quaternion(pin.exp3(t * a)).coeffs() for t in th])
    pos, vel = joint_panels(model, "spherical", Q, np.zeros((len(th), 3)))
    assert [p.key for p in pos] == ["root_rotation"] and [p.key for p in vel] == ["root_angular_velocity"]
    np.testing.assert_allclose(pos[0].values, th[:, None] * a, rtol=0, atol=1e-10)


def test_bad_input_names_the_parameter(tmp_path):
    with pytest.raises(InputError) as info:
        viz.plot_multibody(synthetic_result(), tmp_path)
    assert info.value.parameter == "result.multibody"
    with pytest.raises(InputError) as info:
        viz.plot_multibody(None, tmp_path)
    assert info.value.parameter == "result"
    _, result = solved("ur5_reach")
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError) as info:
        viz.plot_multibody(result, tmp_path / "file")
    assert info.value.parameter == "out_dir"
    broken = Result.from_dict(json.loads(json.dumps(result.to_dict())))
    broken.velocities = broken.velocities[:, :3]
    with pytest.raises(InputError) as info:
        viz.plot_multibody(broken, tmp_path / "figs")
    assert info.value.parameter == "result.velocities"
    assert not (tmp_path / "figs").exists()  # checked before the folder is made
