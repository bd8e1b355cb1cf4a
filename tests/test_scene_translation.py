"""The satellite schema as a translator into the general one, and the one builder (issue 11).

A satellite scene is written in the general schema by ``SceneSpec.general()`` (the one-body model
of satellite.urdf with the scene's inertia; the paper's costs as frame_rotation,
state_regularisation and control terms), and ``build_problem`` reads only that, choosing the
TSO(3) backend by structure. What must hold:

- the translation is lossless: the problem it builds gives the same costs and expansions as the
  paper's problem built from the scene's numbers (``satellite_problem``), on every satellite scene
  (the built-in ones and the 13 hard cases), and the same solve on the paper's scene;
- the general terms mean the same on both backends: the translated geodesic satellite built on the
  general model (Pinocchio frame kinematics) has the TSO(3) costs, gradients and optimum;
- a hand-written general scene of the satellite gets the TSO(3) backend and the paper's J*;
- what TSO(3) alone can do is refused elsewhere, naming the key.
"""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geoddp import data
from geoddp.constraints import ConstrainedProblem
from geoddp.models.multibody import Multibody
from geoddp.models.satellite import Satellite
from geoddp.problem import satellite_problem
from geoddp.scene import build_problem, load_scene, parse_scene
from geoddp.scene.build import _multibody
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError

SATELLITE_SCENES = sorted(p for p in data.scene_dir().glob("*.toml")) + sorted((data.scene_dir() / "hard").glob("*.toml"))


def _from_numbers(spec):
    """The paper's problem from the scene's numbers, the TSO(3) constructor without the translation."""
    p = satellite_problem(inertia=spec.inertia, actuation=spec.actuation, dt=spec.dt, horizon=spec.horizon,
                          R0=spec.R0, Omega0=spec.Omega0, R_d=spec.Rd, Omega_d=spec.Omegad, S_u=spec.S_u,
                          S_R=spec.S_R, S_Omega=spec.S_Omega, attitude_kind=spec.attitude_kind,
                          running_S_R=spec.running_S_R, running_S_Omega=spec.running_S_Omega,
                          integrator=spec.integrator, second_order=spec.second_order, urdf=spec.urdf)
    return p


def test_the_scene_files_are_the_satellite_ones():
    kinds = {p.name: load_scene(p).kind for p in SATELLITE_SCENES}
    assert set(kinds.values()) == {"satellite"} and len(kinds) >= 17, kinds


def test_translation_writes_the_paper_scene_in_the_general_schema():
    spec = load_scene("satellite_paper")
    g = spec.general()
    assert (g.kind, g.root, g.gravity, g.integrator, g.horizon, g.dt) == ("multibody", "spherical", False, "euler",
                                                                         300, 0.01)
    assert Path(g.urdf) == data.urdf_path("satellite.urdf")
    np.testing.assert_array_equal(g.inertia, np.diag([10.0, 11.1, 13.0]))
    np.testing.assert_array_equal(g.actuation, np.eye(3))
    np.testing.assert_allclose(pin.Quaternion(np.array(g.q0)).toRotationMatrix(), spec.R0, atol=1e-15)
    np.testing.assert_array_equal(g.v0, spec.Omega0)
    (control,) = g.running_costs
    assert (control.type, control.path) == ("control", "[cost].control")
    np.testing.assert_array_equal(control.weight, spec.S_u)
    attitude, rate = g.terminal_costs
    assert (attitude.type, attitude.frame, attitude.distance, attitude.path) == (
        "frame_rotation", "bus", "chordal", "[cost].attitude")
    np.testing.assert_array_equal(attitude.reference, spec.Rd)
    np.testing.assert_array_equal(attitude.weight, spec.S_R)
    assert (rate.type, rate.path) == ("state_regularisation", "[cost].angular_velocity")
    np.testing.assert_array_equal(rate.weight[3:, 3:], spec.S_Omega)
    assert not rate.weight[:3].any() and not rate.weight[:, :3].any()
    np.testing.assert_array_equal(rate.reference[4:], spec.Omegad)
    # the shared tables travel as they are
    assert (g.expansion, g.tol, g.max_iter, g.second_order) == (spec.expansion, spec.tol, spec.max_iter,
                                                                spec.second_order)


def test_running_attitude_and_rate_terms_translate_where_non_zero():
    spec = load_scene("satellite_paper").with_overrides(running_S_R=2.0 * np.eye(3), running_S_Omega=np.diag([1, 2, 3.0]))
    g = spec.general()
    assert [(c.type, c.path) for c in g.running_costs] == [
        ("control", "[cost].control"), ("frame_rotation", "[cost].running_attitude"),
        ("state_regularisation", "[cost].running_angular_velocity")]
    np.testing.assert_array_equal(g.running_costs[2].weight[3:, 3:], np.diag([1, 2, 3.0]))


@pytest.mark.parametrize("path", SATELLITE_SCENES, ids=lambda p: p.name)
def test_translation_is_lossless_on_every_satellite_scene(path):
    spec = load_scene(path)
    built, direct = build_problem(spec), _from_numbers(spec)
    if isinstance(built, ConstrainedProblem):  # satellite_keep_out: its costs and dynamics, translated
        assert len(built.constraints) == len(spec.constraints) >= 1
        built = built.problem
    assert isinstance(built.model, Satellite)
    np.testing.assert_allclose(built.R0, direct.R0, rtol=0, atol=2e-16)  # through the quaternion q0
    U = np.random.default_rng(3).normal(scale=0.5, size=(spec.horizon, spec.num_inputs))
    a, b = built.trajectory(U), direct.trajectory(U)
    Ja, Jb = built.trajectory_cost(a), direct.trajectory_cost(b)
    assert Ja == pytest.approx(Jb, rel=1e-12)
    la, lb = built.linearise(a, 2), direct.linearise(b, 2)
    for name in ("Phi", "B", "l_x", "l_u", "l_xx", "l_uu", "lf_x", "lf_xx"):
        x, y = getattr(la, name), getattr(lb, name)
        np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-10 * max(1.0, np.abs(y).max()), err_msg=name)


def test_paper_scene_solves_as_before():
    spec = load_scene("satellite_paper")
    opt = SolverOptions(verbose=False)
    a, b = solve(build_problem(spec), opt), solve(_from_numbers(spec), opt)
    assert a.cost == b.cost == pytest.approx(510.372636558827, rel=1e-13)
    np.testing.assert_array_equal(a.controls, b.controls)  # R0 = I: the same numbers bit for bit


def _on_both_backends(attitude_kind):
    """The paper's satellite (from a turning start) on the TSO(3) closed forms and on the general
    model, and both trajectories under the same random controls, whose costs must agree."""
    g = parse_scene(_paper_dict(attitude_kind=attitude_kind, R0=_rot(0.4, -0.2, 0.7),
                                Omega0=[0.1, -0.2, 0.05])).general()
    tso3, general = build_problem(g), _multibody(g)
    assert isinstance(tso3.model, Satellite) and isinstance(general.model, Multibody)
    U = np.random.default_rng(5).normal(scale=2.0, size=(g.horizon, 3))
    a, b = tso3.trajectory(U), general.trajectory(U)
    assert tso3.trajectory_cost(a) == pytest.approx(general.trajectory_cost(b), rel=1e-12)
    return tso3, general, a, b


def test_the_general_terms_mean_the_same_on_both_backends():
    """The translated geodesic satellite built on the general model (Pinocchio frame kinematics
    through the compiled or python multibody path) against the TSO(3) closed forms."""
    tso3, general, a, b = _on_both_backends("geodesic")
    la, lb = tso3.linearise(a, 1), general.linearise(b, 1)
    np.testing.assert_allclose(la.l_x, lb.l_x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(la.lf_x, lb.lf_x, rtol=1e-9, atol=1e-9)
    # exact on both: the same iterates (measured: controls to 1.6e-14)
    ra, rb = solve(tso3, SolverOptions(verbose=False, expansion="second")), solve(general, SolverOptions(
        verbose=False, expansion="second"))
    assert ra.cost == pytest.approx(rb.cost, rel=1e-11)
    np.testing.assert_allclose(ra.controls, rb.controls, atol=1e-8)
    # switch: the general model's first order is Gauss-Newton, TSO(3)'s the paper's exact one;
    # both end at the same verified minimum (measured: J to 3e-16, controls to 4.5e-7 of 11.4:
    # each stops within tol = 1e-8 of it)
    opt = SolverOptions(verbose=False)
    ra, rb = solve(tso3, opt), solve(general, opt)
    assert ra.converged and rb.converged
    assert ra.cost == pytest.approx(rb.cost, rel=1e-11)
    np.testing.assert_allclose(ra.controls, rb.controls, atol=5e-6)


def _rot(*w):
    return pin.exp3(np.array(w, dtype=float)).tolist()


def _paper_dict(attitude_kind="chordal", R0=None, Omega0=(0.0, 0.0, 0.0)):
    return {
        "name": "t", "model": {"inertia": [10.0, 11.1, 13.0]},
        "initial": {"rotation": R0 or np.eye(3).tolist(), "angular_velocity": list(Omega0)},
        "target": {"euler_intrinsic": [["x", 30.0], ["z", 70.0]]},
        "horizon": {"tf": 1.0, "dt": 0.01},
        "cost": {"control": 0.1, "attitude": 1e4, "attitude_kind": attitude_kind, "angular_velocity": 1e4},
    }


GENERAL_SATELLITE = """
name = "satellite, general schema"
[model]
kind = "multibody"
urdf = "{urdf}"
root = "spherical"
gravity = {gravity}
inertia = [10.0, 11.1, 13.0]
[horizon]
dt = 0.01
steps = 300
[[running_costs]]
type = "control"
weight = 0.1
[[terminal_costs]]
type = "frame_rotation"
frame = "bus"
weight = 1e4
rotation = {Rd}
distance = "{distance}"
[[terminal_costs]]
type = "state_regularisation"
v_weight = 1e4
{solver}
"""


def _general(tmp_path, gravity="false", distance="chordal", solver=""):
    Rd = load_scene("satellite_paper").Rd
    text = GENERAL_SATELLITE.format(urdf=data.urdf_path("satellite.urdf"), gravity=gravity, distance=distance,
                                    Rd=json.dumps(Rd.tolist()),
                                    solver=solver)
    path = tmp_path / "general_satellite.toml"
    path.write_text(textwrap.dedent(text))
    return path


def test_a_hand_written_general_satellite_runs_on_tso3_with_the_papers_optimum(tmp_path):
    spec = load_scene(_general(tmp_path))
    assert spec.kind == "multibody"
    problem = build_problem(spec)
    assert isinstance(problem.model, Satellite)
    r = solve(problem, SolverOptions(verbose=False))
    paper = solve(build_problem(load_scene("satellite_paper")), SolverOptions(verbose=False))
    assert r.cost == pytest.approx(paper.cost, rel=1e-13)
    np.testing.assert_allclose(r.controls, paper.controls, rtol=0, atol=1e-12)


def test_with_gravity_the_same_scene_runs_on_the_general_model(tmp_path):
    problem = build_problem(load_scene(_general(tmp_path, gravity="true", distance="geodesic")))
    assert isinstance(problem.model, Multibody)
    np.testing.assert_array_equal(problem.model.pin_model.inertias[1].inertia, np.diag([10.0, 11.1, 13.0]))


def test_the_papers_chordal_problem_means_the_same_on_the_general_model():
    """The paper's scene (chordal attitude cost, explicit Euler) built on the general model
    (FrameRotationChordal through the compiled frame kinematics) against the TSO(3) closed forms:
    the same cost, gradients and, with exact second order on both, the same optimum."""
    tso3, general, a, b = _on_both_backends("chordal")
    la, lb = tso3.linearise(a, 2), general.linearise(b, 2)
    np.testing.assert_allclose(la.lf_x, lb.lf_x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(la.lf_xx, lb.lf_xx, rtol=1e-9, atol=1e-9 * np.abs(la.lf_xx).max())
    opt = SolverOptions(verbose=False, expansion="second")
    ra, rb = solve(tso3, opt), solve(general, opt)
    assert ra.converged and rb.converged and ra.iterations == rb.iterations
    assert ra.cost == pytest.approx(rb.cost, rel=1e-11)
    np.testing.assert_allclose(ra.controls, rb.controls, atol=1e-8)


def test_the_papers_problem_under_gravity_runs_on_the_general_model(tmp_path):
    """Chordal cost, gravity on: the general model. The body's centre of mass sits at the joint,
    so gravity exerts no torque and the optimum is the paper's."""
    problem = build_problem(load_scene(_general(tmp_path, gravity="true")))
    assert isinstance(problem.model, Multibody) and problem.model.gravity
    r = solve(problem, SolverOptions(verbose=False))
    paper = solve(build_problem(load_scene("satellite_paper")), SolverOptions(verbose=False))
    assert r.converged and r.cost == pytest.approx(paper.cost, rel=1e-9)


def test_paper_second_order_needs_tso3(tmp_path):
    with pytest.raises(InputError, match=r"\[solver\]\.second_order"):
        load_scene(_general(tmp_path, gravity="true", distance="geodesic",
                            solver='[solver]\nsecond_order = "paper"'))
    spec = load_scene(_general(tmp_path, solver='[solver]\nsecond_order = "paper"'))
    assert build_problem(spec).model.second_order == "paper"
    gn = spec.with_overrides(integrator="rk4")
    with pytest.raises(InputError, match=r"second_order.*TSO\(3\) backend only"):
        build_problem(gn)


def test_inertia_needs_a_one_body_spherical_root(tmp_path):
    text = _general(tmp_path).read_text()
    bad = tmp_path / "ff.toml"
    bad.write_text(text.replace('root = "spherical"', 'root = "free_flyer"'))
    with pytest.raises(InputError, match=r"\[model\]\.inertia.*spherical"):
        load_scene(bad)
    arm = tmp_path / "arm.toml"
    arm.write_text(text.replace(str(data.urdf_path("satellite.urdf")), str(data.urdf_path("space_manipulator.urdf")))
                   .replace('frame = "bus"', 'frame = "ee"'))
    with pytest.raises(InputError, match=r"\[model\]\.inertia.*one-body"):
        load_scene(arm)


@pytest.mark.parametrize("integrator", ["rk4", "variational"])
def test_the_satellite_schema_takes_every_integrator(integrator):
    """rk4 and the variational step have no TSO(3) closed forms: the satellite scene runs on the
    general one-body model, chordal cost included, and reaches the optimum of its own
    discretisation, within the integrators' O(dt) of the paper's (measured on the full paper
    scene: J* 509.938 (rk4) and 510.372 (variational) against 510.373)."""
    spec = load_scene("satellite_paper").with_overrides(integrator=integrator, tf=0.5)
    problem = build_problem(spec)
    assert isinstance(problem.model, Multibody) and problem.model.integrator == integrator
    r = solve(problem, SolverOptions(verbose=False))
    euler = solve(build_problem(spec.with_overrides(integrator="euler")), SolverOptions(verbose=False))
    assert isinstance(build_problem(spec.with_overrides(integrator="euler")).model, Satellite)
    assert r.converged and euler.converged
    assert r.cost == pytest.approx(euler.cost, rel=1e-2) and r.cost != euler.cost
