"""Multibody scene files ([model] kind = "multibody"): the three example files build the same
problems as the frozen Python builders (tests/multibody_reference_scenes.py), solve to the same
optimum, and every bad key or value fails with an InputError naming its key path -- through
``load_scene`` and through ``geoddp run`` (exit code 2, one line)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import multibody_reference_scenes as ref
from geoddp.scene import builtin as multibody_scenes
from geoddp import solve_scene
from geoddp.scene import initial_controls
from geoddp.data import urdf_path
from geoddp.cli import EXIT_BAD_INPUT, EXIT_CONVERGED, EXIT_NOT_CONVERGED, main
from geoddp.scene import MultibodySceneSpec, terminal_frame_errors
from geoddp.scene import SceneSpec, build_problem, load_scene, parse_scene
from geoddp.solver import SolverOptions, cost_gradient, solve
from geoddp.validate import InputError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "multibody"
SCENES_GUIDE = ROOT / "docs" / "guide" / "scenes.md"
NAMES = ("spacecraft_docking", "space_manipulator", "quadrotor")


def _reference_guess(name, problem):
    return ref.hover_controls(problem) if name == "quadrotor" else None


# ------------------------------------------------------------------ the examples are the scenes


@pytest.mark.parametrize("name", NAMES)
def test_scene_file_builds_the_reference_problem(name):
    """Model, state, grid, rollout, cost, cost derivatives and the exact gradient dJ/dU all
    agree with the frozen Python builder, on the full horizon, at a random control sequence."""
    spec = load_scene(EXAMPLES / f"{name}.toml")
    assert isinstance(spec, MultibodySceneSpec) and spec.name == name
    a, b = getattr(ref, name)(), build_problem(spec)
    assert (b.horizon, b.model.dt, b.model.integrator, b.model.root) == (a.horizon, a.model.dt, a.model.integrator,
                                                                           a.model.root)
    assert np.array_equal(b.model.actuation, a.model.actuation)
    assert np.array_equal(b.model.pin_model.gravity.linear, a.model.pin_model.gravity.linear)
    assert np.array_equal(b.q0, a.q0) and np.array_equal(b.v0, a.v0)
    U = np.random.default_rng(3).normal(size=(a.horizon, a.nu))
    if name == "quadrotor":
        U += ref.hover_controls(a)
    Qa, Va = a.rollout(U)
    Qb, Vb = b.rollout(U)
    assert np.array_equal(Qa, Qb) and np.array_equal(Va, Vb)
    Ja, Jb = a.cost(Qa, Va, U), b.cost(Qb, Vb, U)
    assert abs(Ja - Jb) <= 1e-13 * Ja, (Ja, Jb)
    for da, db in zip(a.cost_derivatives(Qa, Va, U), b.cost_derivatives(Qb, Vb, U)):
        for k in ("l", "lx", "lxx", "lu", "luu"):
            x, y = getattr(da, k), getattr(db, k)
            assert np.allclose(x, y, rtol=1e-13, atol=1e-13 * max(1.0, np.abs(x).max(initial=0.0))), k
    ga, gb = cost_gradient(a, U)[1], cost_gradient(b, U)[1]
    assert np.abs(ga - gb).max() <= 1e-12 * np.abs(ga).max()
    # the initial guess: hover thrust for the quadrotor, zeros otherwise
    Ua, Ub = _reference_guess(name, a), initial_controls(spec)
    assert (Ua is None) == (Ub is None)
    if Ua is not None:
        assert np.allclose(Ua, Ub, rtol=1e-14, atol=0.0)


def test_quadrotor_file_solves_to_the_reference_optimum_and_the_readme_numbers():
    """Full scene (H = 150): same J* (1e-10 relative) and iterations as the Python builder; the
    benchmarks page's measured row (switch: J* = 1.5520335279; 10 iterations at the relative default
    stopping tests, 9 at the absolute tol = 1e-8 the file set before)."""
    a = ref.quadrotor()
    ra = solve(a, SolverOptions(verbose=False), initial_controls=ref.hover_controls(a))
    rb = solve_scene(EXAMPLES / "quadrotor.toml", verbose=False)
    assert rb.converged and ra.converged
    assert rb.iterations == ra.iterations == 10
    assert abs(rb.cost - ra.cost) <= 1e-10 * ra.cost, (rb.cost, ra.cost)
    assert abs(rb.cost - 1.5520335279) < 1e-9
    assert rb.extra["scene"] == "quadrotor"
    assert rb.configurations.shape == (151, 7) and rb.controls.shape == (150, 4)


@pytest.mark.parametrize("name,dt,H", [("spacecraft_docking", 0.25, 40), ("space_manipulator", 0.06, 50)])
def test_other_files_solve_like_the_builders_on_coarse_grids(name, dt, H):
    a = getattr(ref, name)(dt=dt, horizon=H)
    ra = solve(a, SolverOptions(verbose=False))
    spec = load_scene(EXAMPLES / f"{name}.toml").with_overrides(dt=dt, horizon=H)
    rb = solve_scene(spec, verbose=False)
    assert ra.converged and rb.converged
    assert rb.iterations == ra.iterations
    assert abs(rb.cost - ra.cost) <= 1e-10 * ra.cost, (rb.cost, ra.cost)


def test_builtin_builders_load_the_files_and_take_overrides():
    p = multibody_scenes.spacecraft_docking(integrator="euler", dt=0.1, horizon=7)
    assert (p.model.integrator, p.model.dt, p.horizon) == ("euler", 0.1, 7)
    assert multibody_scenes.scene_path("quadrotor").samefile(EXAMPLES / "quadrotor.toml")  # examples/ links there
    with pytest.raises(InputError) as info:
        multibody_scenes.scene_spec("quadrotor", horizon=0)
    assert info.value.parameter == "horizon"


def test_terminal_frame_errors_of_the_initial_state():
    spec = load_scene(EXAMPLES / "spacecraft_docking.toml")
    (e,) = terminal_frame_errors(spec, spec.q0)
    assert e["frame"] == "bus" and e["type"] == "frame_placement"
    assert e["position_error_m"] == pytest.approx(np.linalg.norm([-4.0, 1.5, 0.5]), rel=1e-14)
    # from a 50 deg tilt about (1, 1, 0) to a 90 deg yaw
    R0 = pin.exp3(np.radians(50.0) * np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0))
    Rd = pin.exp3(np.array([0.0, 0.0, np.pi / 2]))
    assert e["rotation_error_deg"] == pytest.approx(np.degrees(np.linalg.norm(pin.log3(Rd.T @ R0))), rel=1e-12)


def test_new_integrators_of_the_model_are_accepted(monkeypatch):
    """Validation reads models.multibody.INTEGRATORS at load time: a new entry needs no schema edit."""
    from geoddp.models import multibody as mbm

    text = (EXAMPLES / "space_manipulator.toml").read_text().replace('"semi_implicit"', '"variational_test"')
    data = _toml(text)
    with pytest.raises(InputError) as info:
        parse_scene(data, str(EXAMPLES / "x.toml"))
    assert info.value.parameter == "[horizon].integrator" and "semi_implicit" in info.value.detail
    monkeypatch.setattr(mbm, "INTEGRATORS", mbm.INTEGRATORS + ("variational_test",))
    assert parse_scene(data, str(EXAMPLES / "x.toml")).integrator == "variational_test"


# ------------------------------------------------------------------ schema features


def _toml(text: str) -> dict:
    import tomllib

    return tomllib.loads(text)


URDF_SC = urdf_path("spacecraft.urdf").as_posix()
URDF_ARM = urdf_path("space_manipulator.urdf").as_posix()
URDF_QUAD = urdf_path("quadrotor.urdf").as_posix()

# A small spacecraft scene (H = 20) with an absolute URDF path, so that it can live in tmp_path.
GOOD = f"""\
name = "small_docking"

[model]
kind = "multibody"
urdf = "{URDF_SC}"
root = "free_flyer"
gravity = false

[actuation]
type = "thrusters"
positions = [[0.0, 0.8, 0.0], [0.0, -0.8, 0.0], [0.0, 0.0, 0.8], [0.0, 0.0, -0.8], [0.8, 0.0, 0.0], [-0.8, 0.0, 0.0]]
directions = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]

[initial]
translation = [-1.0, 0.5, 0.2]
quaternion = [0.0, 0.0, 0.0, 1.0]
v = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[horizon]
dt = 0.25
steps = 20
integrator = "semi_implicit"

[[running_costs]]
type = "control"
weight = 1e-3

[[terminal_costs]]
type = "frame_placement"
frame = "bus"
translation = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
angle_deg = 30.0
weight = 1e4

[[terminal_costs]]
type = "state_regularisation"
v_weight = 1e4

[solver]
expansion = "switch"
max_iter = 100
"""
H_GOOD, NQ, NV, M = 20, 7, 6, 6


def _sub(old: str, new: str, text: str = GOOD) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


def _load(tmp_path: Path, text: str):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return load_scene(p)


def test_good_scene_values(tmp_path):
    s = _load(tmp_path, GOOD)
    assert (s.horizon, s.dt, s.tf, s.num_inputs, s.integrator) == (20, 0.25, 5.0, 6, "semi_implicit")
    assert np.array_equal(s.q0, [-1.0, 0.5, 0.2, 0.0, 0.0, 0.0, 1.0])
    place = s.terminal_costs[0]
    assert place.frame == "bus" and np.allclose(place.reference[:3, :3], pin.exp3(np.array([0, 0, np.pi / 6])),
                                                atol=1e-15)
    assert np.array_equal(place.weight, 1e4 * np.eye(6))
    W = s.terminal_costs[1].weight
    assert np.array_equal(np.diag(W), [0.0] * 6 + [1e4] * 6) and np.count_nonzero(W - np.diag(np.diag(W))) == 0
    assert s.running_costs[0].type == "control" and np.array_equal(s.running_costs[0].reference, np.zeros(6))


def test_tf_form_equals_steps_form(tmp_path):
    a = _load(tmp_path, GOOD)
    b = _load(tmp_path, _sub("steps = 20", "tf = 5.0"))
    assert (a.horizon, a.dt) == (b.horizon, b.dt)


def test_initial_q_equals_pose_form(tmp_path):
    a = _load(tmp_path, _sub('quaternion = [0.0, 0.0, 0.0, 1.0]', "axis = [1.0, 2.0, 3.0]\nangle_deg = 40.0"))
    q = "q = [" + ", ".join(repr(float(x)) for x in a.q0) + "]"
    b = _load(tmp_path, _sub("translation = [-1.0, 0.5, 0.2]\nquaternion = [0.0, 0.0, 0.0, 1.0]", q))
    assert np.array_equal(a.q0, b.q0)
    R = pin.Quaternion(a.q0[6], *a.q0[3:6]).toRotationMatrix()
    assert np.allclose(R, pin.exp3(np.radians(40.0) * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)), atol=1e-15)


def test_reference_forms_agree(tmp_path):
    """quaternion, rotation matrix and axis-angle give one placement; frame_rotation and
    frame_translation take the parts; at_configuration is the frame's placement there."""
    R = pin.exp3(np.array([0.0, 0.0, np.radians(30.0)]))
    quat = pin.Quaternion(R).coeffs()  # x, y, z, w
    rot = "rotation = " + json.dumps(R.tolist())
    qtxt = "quaternion = " + json.dumps(quat.tolist())
    axis = "axis = [0.0, 0.0, 1.0]\nangle_deg = 30.0"
    refs = [_load(tmp_path, _sub(axis, form)).terminal_costs[0].reference for form in (axis, rot, qtxt)]
    assert np.allclose(refs[0], refs[1], atol=1e-15) and np.allclose(refs[0], refs[2], atol=1e-15)
    split = _sub(
        'type = "frame_placement"\nframe = "bus"\ntranslation = [0.0, 0.0, 0.0]\n' + axis + "\nweight = 1e4",
        'type = "frame_rotation"\nframe = "bus"\n' + axis + '\nweight = 1e4\n\n[[terminal_costs]]\n'
        'type = "frame_translation"\nframe = "bus"\ntranslation = [0.0, 0.0, 0.0]\nweight = 1e4')
    s = _load(tmp_path, split)
    assert np.array_equal(s.terminal_costs[0].reference, refs[0][:3, :3])
    assert np.array_equal(s.terminal_costs[1].reference, np.zeros(3))
    at = _load(tmp_path, _sub("translation = [0.0, 0.0, 0.0]\n" + axis,
                              "at_configuration = [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]"))
    assert np.array_equal(at.terminal_costs[0].reference, pin.SE3(np.eye(3), np.array([1.0, 2.0, 3.0])).homogeneous)


def test_actuation_forms(tmp_path):
    quad = f'[model]\nkind = "multibody"\nurdf = "{URDF_QUAD}"\n[horizon]\ndt = 0.1\nsteps = 3\n' \
           '[[terminal_costs]]\ntype = "state_regularisation"\nweight = 1.0\n'
    s = _load(tmp_path, quad)
    assert np.array_equal(s.actuation, np.eye(6)) and s.gravity is True and s.integrator == "euler"
    s = _load(tmp_path, quad + '[actuation]\ntype = "quadrotor"\narm_length = 0.25\ntorque_coefficient = 0.02\n')
    assert np.array_equal(s.actuation, ref.quadrotor_actuation(0.25, 0.02))
    arm = quad.replace(URDF_QUAD, URDF_ARM)
    s = _load(tmp_path, arm + '[actuation]\ntype = "thrusters"\npositions = [[0.0, 0.0, 1.0]]\n'
              'directions = [[1.0, 0.0, 0.0]]\njoints = ["elbow", "shoulder_yaw"]\n')
    expected = np.zeros((9, 3))
    expected[:6, 0] = [1, 0, 0, 0, 1, 0]  # force along x at z = 1: torque e_z x e_x = e_y
    expected[8, 1] = expected[6, 2] = 1.0  # elbow then shoulder_yaw motors
    assert np.array_equal(s.actuation, expected)
    s = _load(tmp_path, arm + '[actuation]\ntype = "matrix"\nmatrix = ' + json.dumps(expected.tolist()) + "\n")
    assert np.array_equal(s.actuation, expected)


def test_state_regularisation_full_weight_and_references(tmp_path):
    s = _load(tmp_path, _sub("v_weight = 1e4", 'weight = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0]'
                             '\nq_reference = "initial"\nv_reference = [0.1, 0.0, 0.0, 0.0, 0.0, 0.0]'))
    c = s.terminal_costs[1]
    assert np.array_equal(np.diag(c.weight), np.arange(1.0, 13.0))
    assert np.array_equal(c.reference[:NQ], s.q0) and np.array_equal(c.reference[NQ:], [0.1, 0, 0, 0, 0, 0])


def test_hover_needs_an_actuation_that_balances_gravity(tmp_path):
    quad = (f'[model]\nkind = "multibody"\nurdf = "{URDF_QUAD}"\n[horizon]\ndt = 0.1\nsteps = 3\n'
            '[actuation]\ntype = "quadrotor"\narm_length = 0.25\ntorque_coefficient = 0.02\n'
            '[[running_costs]]\ntype = "control"\nweight = 1.0\nreference = "hover"\n'
            '[solver]\ninitial_controls = "hover"\n')
    s = _load(tmp_path, quad)
    assert np.allclose(s.initial_controls, 1.5 * 9.81 / 4, rtol=1e-14)
    assert np.array_equal(s.running_costs[0].reference, s.initial_controls)
    tilted = quad.replace("[horizon]", "[initial]\naxis = [1.0, 0.0, 0.0]\nangle_deg = 30.0\n[horizon]")
    with pytest.raises(InputError) as info:
        _load(tmp_path, tilted)
    assert info.value.parameter == "running_costs[0].reference" and "balance gravity" in info.value.detail


def test_satellite_scenes_unchanged_and_kind_satellite_accepted(tmp_path):
    paper = (ROOT / "examples" / "satellite_paper.toml").read_text()
    a = load_scene(ROOT / "examples" / "satellite_paper.toml")
    b = _load(tmp_path, paper.replace("[model]\n", '[model]\nkind = "satellite"\n'))
    assert isinstance(a, SceneSpec) and a.with_overrides(source=b.source, name=b.name) == b


def test_overrides_are_validated(tmp_path):
    s = _load(tmp_path, GOOD)
    assert s.with_overrides(expansion="second", max_iter=3).max_iter == 3
    for kw, param in (({"expansion": "third"}, "expansion"), ({"dt": 0.0}, "dt"), ({"frame": "x"}, "frame"),
                      ({"initial_controls": np.zeros((3, 6))}, "initial_controls")):
        with pytest.raises(InputError) as info:
            s.with_overrides(**kw)
        assert info.value.parameter == param


# ------------------------------------------------------------------ bad scene files

ACT_POS = "positions = [[0.0, 0.8, 0.0], [0.0, -0.8, 0.0], [0.0, 0.0, 0.8], [0.0, 0.0, -0.8], [0.8, 0.0, 0.0], [-0.8, 0.0, 0.0]]"
PLACEMENT_W = "angle_deg = 30.0\nweight = 1e4"

# id -> (scene text, key path the message must name, fragment the message must contain)
BAD = {
    "unknown_frame": (_sub('frame = "bus"', 'frame = "buss"'), "terminal_costs[0].frame", "'bus'"),
    "unknown_frame_lists_frames": (_sub('frame = "bus"', 'frame = "tool"'), "terminal_costs[0].frame",
                                   "frames: 'root_joint', 'bus'"),
    "unknown_cost_type": (_sub('type = "control"', 'type = "controls"'), "running_costs[0].type", "did you mean"),
    "unknown_cost_key": (_sub("weight = 1e-3", "weight = 1e-3\nframe = \"bus\""), "running_costs[0].frame",
                         "unknown key"),
    "misspelled_cost_key": (_sub('frame = "bus"', 'fram = "bus"'), "terminal_costs[0].fram", "did you mean 'frame'"),
    "missing_frame": (_sub('frame = "bus"\n', ""), "terminal_costs[0].frame", "missing"),
    "missing_type": (_sub('type = "control"\n', ""), "running_costs[0].type", "missing"),
    "missing_weight": (_sub("weight = 1e-3", ""), "running_costs[0].weight", "missing"),
    "control_in_terminal": (GOOD + '\n[[terminal_costs]]\ntype = "control"\nweight = 1.0\n', "terminal_costs[2].type",
                            "running_costs"),
    "weight_not_psd": (_sub(PLACEMENT_W, "angle_deg = 30.0\nweight = -1e4"), "terminal_costs[0].weight",
                       "positive semidefinite"),
    "weight_indefinite_matrix": (_sub("weight = 1e-3", "weight = [[1.0, 2.0, 0, 0, 0, 0], [2.0, 1.0, 0, 0, 0, 0], "
                                      "[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]"),
                                 "running_costs[0].weight", "smallest eigenvalue"),
    "weight_wrong_shape": (_sub(PLACEMENT_W, "angle_deg = 30.0\nweight = [1.0, 2.0, 3.0]"), "terminal_costs[0].weight",
                           "length-6"),
    "v_weight_wrong_shape": (_sub("v_weight = 1e4", "v_weight = [1.0, 2.0]"), "terminal_costs[1].v_weight",
                             "length-6"),
    "weight_and_v_weight": (_sub("v_weight = 1e4", "v_weight = 1e4\nweight = 1.0"), "terminal_costs[1].weight",
                            "got both"),
    "control_reference_shape": (_sub("weight = 1e-3", "weight = 1e-3\nreference = [1.0, 2.0]"),
                                "running_costs[0].reference", "shape (6,)"),
    "dt_zero": (_sub("dt = 0.25", "dt = 0.0"), "[horizon].dt", "> 0"),
    "dt_negative": (_sub("dt = 0.25", "dt = -0.25"), "[horizon].dt", "> 0"),
    "steps_and_tf": (_sub("steps = 20", "steps = 20\ntf = 5.0"), "[horizon]", "exactly one of steps"),
    "steps_float": (_sub("steps = 20", "steps = 20.0"), "[horizon].steps", "integer"),
    "tf_not_multiple": (_sub("steps = 20", "tf = 5.1"), "[horizon].tf", "integer multiple"),
    "unknown_integrator": (_sub('integrator = "semi_implicit"', 'integrator = "semi-implicit"'),
                           "[horizon].integrator", "did you mean 'semi_implicit'"),
    "quaternion_not_normalised": (_sub("quaternion = [0.0, 0.0, 0.0, 1.0]", "quaternion = [0.0, 0.0, 0.1, 1.0]"),
                                  "[initial].quaternion", "unit quaternion"),
    "quaternion_3_entries": (_sub("quaternion = [0.0, 0.0, 0.0, 1.0]", "quaternion = [0.0, 0.0, 1.0]"),
                             "[initial].quaternion", "shape (4,)"),
    "two_rotation_forms": (_sub("quaternion = [0.0, 0.0, 0.0, 1.0]",
                                "quaternion = [0.0, 0.0, 0.0, 1.0]\naxis = [1.0, 0.0, 0.0]\nangle_deg = 3.0"),
                           "[initial]", "exactly one rotation form"),
    "axis_without_angle": (_sub(PLACEMENT_W, "weight = 1e4"), "terminal_costs[0].angle_deg", "angle_deg"),
    "zero_axis": (_sub("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 0.0]"), "terminal_costs[0].axis", "non-zero"),
    "placement_without_rotation": (_sub("axis = [0.0, 0.0, 1.0]\n" + PLACEMENT_W, "weight = 1e4"),
                                   "terminal_costs[0]", "exactly one rotation form"),
    "rotation_matrix_not_orthonormal": (
        _sub("axis = [0.0, 0.0, 1.0]\nangle_deg = 30.0", "rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.1, 1.0]]"),
        "terminal_costs[0].rotation", "orthonormal"),
    "initial_q_shape": (_sub("translation = [-1.0, 0.5, 0.2]\nquaternion = [0.0, 0.0, 0.0, 1.0]",
                             "q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]"), "[initial].q", "shape (7,)"),
    "initial_q_not_normalised": (_sub("translation = [-1.0, 0.5, 0.2]\nquaternion = [0.0, 0.0, 0.0, 1.0]",
                                      "q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]"), "[initial].q", "non-normalised"),
    "initial_v_shape": (_sub("v = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]", "v = [0.0, 0.0, 0.0]"), "[initial].v",
                        "shape (6,)"),
    "q_and_pose": (_sub("v = [0.0", "q = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]\nv = [0.0"), "[initial]", "got q and"),
    "at_configuration_shape": (_sub("translation = [0.0, 0.0, 0.0]\naxis = [0.0, 0.0, 1.0]\nangle_deg = 30.0",
                                    "at_configuration = [0.0, 0.0, 1.0]"), "terminal_costs[0].at_configuration",
                               "shape (7,)"),
    "q_reference_word": (_sub("v_weight = 1e4", 'v_weight = 1e4\nq_reference = "start"'),
                         "terminal_costs[1].q_reference", "initial | neutral"),
    "thruster_directions_shape": (_sub("directions = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], ",
                                       "directions = ["), "[actuation].directions", "shape (6, 3)"),
    "thruster_positions_shape": (_sub(ACT_POS, "positions = [0.0, 0.8, 0.0]"), "[actuation].positions", "(k, 3)"),
    "thruster_zero_direction": (_sub("directions = [[1.0, 0.0, 0.0]", "directions = [[0.0, 0.0, 0.0]"),
                                "[actuation].directions", "non-zero"),
    "actuation_key_of_other_type": (_sub('type = "thrusters"', 'type = "thrusters"\narm_length = 0.2'),
                                    "[actuation].arm_length", 'not used by type = "thrusters"'),
    "unknown_actuation_type": (_sub('type = "thrusters"', 'type = "thruster"'), "[actuation].type",
                               "did you mean 'thrusters'"),
    "unknown_joint": (_sub('type = "thrusters"', 'type = "thrusters"\njoints = ["elbow"]'), "[actuation].joints[0]",
                      "joints: none"),
    "unknown_model_key": (_sub("gravity = false", "gravity = false\nmass = 3.0"), "[model].mass", "unknown key"),
    "gravity_not_bool": (_sub("gravity = false", "gravity = 0"), "[model].gravity", "true or false"),
    "unknown_root": (_sub('root = "free_flyer"', 'root = "freeflyer"'), "[model].root", "did you mean 'free_flyer'"),
    "unknown_kind": (_sub('kind = "multibody"', 'kind = "multi_body"'), "[model].kind", "multibody | satellite"),
    "missing_urdf": (_sub(f'urdf = "{URDF_SC}"', 'urdf = "no_such.urdf"'), "[model].urdf", "not found"),
    "unknown_section": (GOOD + "\n[costs]\ncontrol = 1.0\n", "[costs]", "unknown"),
    "costs_as_table": (GOOD.replace("[[running_costs]]", "[running_costs]"), "running_costs",
                       "expected an array of tables"),
    "no_costs": ("\n".join(GOOD.split("\n[[running_costs]]")[0:1]) + "\n[solver]\n", "[[running_costs]]",
                 "at least one cost term"),
    "initial_controls_shape": (_sub("max_iter = 100", "max_iter = 100\ninitial_controls = [1.0, 2.0]"),
                               "[solver].initial_controls", "shape (6,)"),
    "initial_controls_word": (_sub("max_iter = 100", 'max_iter = 100\ninitial_controls = "hoover"'),
                              "[solver].initial_controls", "did you mean 'hover'"),
    "second_order_paper": (_sub("max_iter = 100", 'max_iter = 100\nsecond_order = "paper"'),
                           "[solver].second_order", "exact"),
    "unknown_solver_key": (_sub("max_iter = 100", "max_iter = 100\nmaxiter = 3"), "[solver].maxiter",
                           "did you mean 'max_iter'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_multibody_scene_names_the_key(tmp_path, case):
    text, param, fragment = BAD[case]
    p = tmp_path / f"{case}.toml"
    p.write_text(text)
    with pytest.raises(InputError) as info:
        load_scene(p)
    err = info.value
    assert err.parameter == param, (err.parameter, str(err))
    assert fragment in err.detail, (fragment, str(err))
    assert str(p) in str(err)


CLI_CASES = ["unknown_frame", "weight_not_psd", "dt_zero", "quaternion_not_normalised", "unknown_cost_key",
             "thruster_directions_shape", "control_in_terminal", "unknown_kind", "missing_urdf", "steps_and_tf"]


def _run(capsys, argv):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.mark.parametrize("case", CLI_CASES)
def test_bad_multibody_scene_exits_2_with_one_line(tmp_path, capsys, case):
    text, param, _ = BAD[case]
    p = tmp_path / f"{case}.toml"
    p.write_text(text)
    code, out, err = _run(capsys, ["run", str(p), "--quiet", "--json", str(tmp_path / "out.json")])
    assert code == EXIT_BAD_INPUT, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"geoddp: error: {param}: "), err
    assert "Traceback" not in err + out and out == ""
    assert not (tmp_path / "out.json").exists()


def test_run_multibody_scene_writes_the_json(tmp_path, capsys):
    p = tmp_path / "good.toml"
    p.write_text(GOOD)
    out_json = tmp_path / "r.json"
    code, out, err = _run(capsys, ["run", str(p), "--quiet", "--json", str(out_json)])
    assert code == EXIT_CONVERGED, (out, err)
    assert err == ""
    assert out.startswith("J* = ") and "terminal frame_placement 'bus': position error = " in out
    d = json.loads(out_json.read_text())
    assert d["converged"] is True and np.asarray(d["configurations"]).shape == (H_GOOD + 1, NQ)
    assert np.asarray(d["velocities"]).shape == (H_GOOD + 1, NV) and np.asarray(d["controls"]).shape == (H_GOOD, M)
    assert d["cost"] == d["cost_history"][-1] and np.all(np.diff(d["cost_history"]) <= 0.0)
    # the same number as the API
    r = solve_scene(p, verbose=False)
    assert r.cost == d["cost"] and r.iterations == d["iterations"]
    # --expansion overrides [solver].expansion
    code, out, _ = _run(capsys, ["run", str(p), "--quiet", "--expansion", "first"])
    assert code in (EXIT_CONVERGED, EXIT_NOT_CONVERGED) and out.startswith("J* = ")


def test_run_multibody_max_iter_1_exits_1(tmp_path, capsys):
    p = tmp_path / "capped.toml"
    p.write_text(_sub("max_iter = 100", "max_iter = 1"))
    code, out, err = _run(capsys, ["run", str(p), "--quiet"])
    assert code == EXIT_NOT_CONVERGED and err == "" and "max_iter" in out


def test_run_multibody_refuses_a_plots_path_that_is_a_file_before_solving(tmp_path, capsys):
    """--plots of a multibody scene writes its figures (tests/test_viz_multibody_figures.py); a
    --plots path that cannot be a folder is bad input, refused before the solve (nothing printed)."""
    p = tmp_path / "good.toml"
    p.write_text(GOOD)
    (tmp_path / "figs").write_text("a file, not a folder")
    code, out, err = _run(capsys, ["run", str(p), "--quiet", "--plots", str(tmp_path / "figs")])
    assert code == EXIT_BAD_INPUT and out == ""
    assert err.startswith("geoddp: error: --plots: ") and len(err.splitlines()) == 1


def test_the_guides_example_is_the_docking_scene(tmp_path):
    """The full example in the scenes guide parses and states the same problem as the example file."""
    text = SCENES_GUIDE.read_text()
    block = text.split("## The general schema: any Pinocchio model", 1)[1].split("```toml\n", 1)[1].split("```", 1)[0]
    p = tmp_path / "guide_example.toml"  # anywhere: the bare URDF name resolves to the built-in one
    p.write_text(block)
    a = load_scene(p)
    b = load_scene(EXAMPLES / "spacecraft_docking.toml")
    for f in ("urdf", "root", "gravity", "dt", "horizon", "integrator", "expansion", "tol", "max_iter"):
        assert getattr(a, f) == getattr(b, f), f
    for f in ("actuation", "q0", "v0"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    for ca, cb in zip(a.running_costs + a.terminal_costs, b.running_costs + b.terminal_costs, strict=True):
        assert (ca.type, ca.frame) == (cb.type, cb.frame)
        assert np.array_equal(ca.reference, cb.reference) and np.array_equal(ca.weight, cb.weight)


@pytest.mark.parametrize("case,message", [
    ("unknown_frame_lists_frames", "terminal_costs[0].frame: expected a frame of model 'spacecraft', got 'tool'; "
                                   "frames: 'root_joint', 'bus'"),
    ("quaternion_not_normalised", "[initial].quaternion: expected a unit quaternion (x, y, z, w) with norm 1 +- 1e-09, "
                                  "got norm 1.00498756211"),
    ("dt_zero", "[horizon].dt: expected a number > 0, got 0.0"),
])
def test_the_guides_error_messages_are_verbatim(tmp_path, case, message):
    p = tmp_path / "s.toml"
    p.write_text(BAD[case][0])
    with pytest.raises(InputError) as info:
        load_scene(p)
    assert str(info.value) == f"{message} (in {p})"
    assert message in SCENES_GUIDE.read_text().replace("\n  ", " ")
