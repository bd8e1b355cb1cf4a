"""The default start: a multibody problem solved without initial controls starts from the controls
that hold its initial posture against gravity where the actuation can (least squares through the
actuation matrix: Crocoddyl's quasiStatic where gravity can be balanced, the mass matrix's metric
where it cannot), clipped into the limits; zero without gravity.

Requires example-robot-data (the ``test`` extra): the Panda, the UR5 and Solo12.
"""
from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import example_robot_data  # noqa: F401  (required)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import solve_scene
from geoddp.models.actuation import quasi_static_inputs
from geoddp.problem import paper_problem
from geoddp.scene import build_problem, initial_controls, load_scene, parse_scene, scene_file
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tests_panda  # noqa: E402

QUIET = SolverOptions(verbose=False)


def _gravity(problem) -> np.ndarray:
    pm = problem.model.pin_model
    return pin.computeGeneralizedGravity(pm, pm.createData(), problem.q0)


@pytest.fixture(scope="module")
def panda_files(tmp_path_factory):
    """The Panda reach of tests_panda written with each initial_controls form (and without one)."""
    folder = tmp_path_factory.mktemp("panda")
    text = tests_panda.panda_scene(folder).read_text()
    out = {}
    for name in ("default", "quasi_static", "gravity_compensation", "hover", "zero"):
        line = "" if name == "default" else f'initial_controls = "{name}"'
        path = folder / f"panda_{name}.toml"
        path.write_text(text.replace('initial_controls = "hover"', line))
        out[name] = path
    return out


def test_panda_reach_without_initial_controls_starts_quasi_static_and_converges(panda_files):
    spec = load_scene(panda_files["default"])
    assert spec.initial_controls is None and initial_controls(spec) is None  # nothing given: the default
    p = build_problem(spec)
    g = _gravity(p)
    u_ls = np.linalg.lstsq(p.model.actuation, g, rcond=None)[0]
    U_qs = p.quasi_static_controls()
    assert U_qs.shape == (p.horizon, p.nu) and np.array_equal(U_qs, np.tile(u_ls, (p.horizon, 1)))
    # fully actuated: the gravity torques themselves, residual at round-off
    assert np.abs(p.model.actuation @ U_qs[0] - g).max() <= 1e-12 * np.abs(g).max()
    r = solve_scene(spec, verbose=False)
    assert r.converged, r.message
    J_qs = p.total_cost(U_qs)
    assert r.cost_history[0] == J_qs  # J(U) of the default start is J at the quasi-static controls
    assert 519.0 < J_qs < 521.0 and r.cost < 0.7 and r.iterations <= 25, (J_qs, r.cost, r.iterations)
    # every name of the quasi-static start gives the very same solve
    for name in ("quasi_static", "gravity_compensation", "hover"):
        other = solve_scene(str(panda_files[name]), verbose=False)
        assert other.cost_history[0] == J_qs and other.cost == r.cost and other.iterations == r.iterations, name
    # and the Python route, solve(problem) without initial controls, too
    direct = solve(p, QUIET)
    assert direct.cost_history[0] == J_qs and direct.cost == r.cost


def test_zero_start_stays_available_explicitly(panda_files):
    spec = load_scene(panda_files["zero"])
    assert np.array_equal(initial_controls(spec), np.zeros((spec.horizon, spec.num_inputs)))
    # from zero torque the arm falls: at dt = 0.05 s the rollout overflows (the J = 3.2e11
    # at dt = 0.01 s), a clear error naming the initial guess, where the default start converges
    with pytest.raises(InputError) as e:
        solve_scene(spec, verbose=False)
    assert e.value.parameter == "initial_controls" and "non-finite" in str(e.value)


def test_free_flyer_with_gravity_falls_with_its_posture_held():
    """Solo12 on a free-flyer root with gravity, the base unactuated, no contacts: no input can
    balance the robot's weight. The least squares in the metric of the mass matrix give zero joint
    torques (in uniform gravity g = M a_fall: the robot falls with its posture held), where the
    Euclidean pinv(H) g (Crocoddyl's quasiStatic: the joint rows of g, as if the base were held)
    makes the falling robot flail until the rollout overflows."""
    path = scene_file("solo12_reorient")
    d = tomllib.loads(path.read_text())
    d["model"]["gravity"] = True
    del d["solver"]["initial_controls"]
    p = build_problem(parse_scene(d, str(path)))
    pm, A = p.model.pin_model, p.model.actuation
    g = _gravity(p)
    assert np.linalg.norm(g[:6]) > 20.0  # the unbalanced weight, N (Solo12: 2.5 kg)
    U = p.quasi_static_controls()
    M = pin.crba(pm, pm.createData(), p.q0)
    M = np.triu(M) + np.triu(M, 1).T
    # the normal equations of min (A u - g)^T M^-1 (A u - g) hold, and u is zero to round-off
    assert np.abs(A.T @ np.linalg.solve(M, A @ U[0] - g)).max() <= 1e-12 * np.abs(np.linalg.solve(M, g)).max()
    assert np.abs(U).max() <= 1e-12 * np.abs(g).max()
    # the Euclidean least squares: the joint rows of g, and a start whose rollout overflows
    u_euclid = np.linalg.lstsq(A, g, rcond=None)[0]
    np.testing.assert_allclose(u_euclid, g[6:], rtol=0, atol=1e-13 * np.abs(g).max())
    assert not np.isfinite(p.total_cost(np.tile(u_euclid, (p.horizon, 1))))
    # solve() starts from the default: J(U) of the default start is J at those controls, finite
    r = solve(p, SolverOptions(verbose=False, max_iter=1))
    assert r.cost_history[0] == p.total_cost(U) and 1246.0 < r.cost_history[0] < 1247.0


def test_underactuated_thrusters_least_squares_where_hover_is_refused():
    """A quadrotor tilted by 30 deg cannot balance gravity with its four parallel rotors:
    "hover" is refused, "quasi_static" (and the default start) takes the least-squares thrusts."""
    path = scene_file("quadrotor")
    d = tomllib.loads(path.read_text())
    d["initial"]["axis"], d["initial"]["angle_deg"] = [1.0, 0.0, 0.0], 30.0
    with pytest.raises(InputError) as e:
        parse_scene(d, str(path))
    assert "balance gravity" in str(e.value) and "quasi_static" in str(e.value)
    for ref in ("quasi_static", "gravity_compensation"):
        d["running_costs"][0]["reference"] = ref
        d["solver"]["initial_controls"] = ref
        spec = parse_scene(d, str(path))
        assert spec.initial_controls is None  # the default start
        p = build_problem(spec)
        g = _gravity(p)
        U = p.quasi_static_controls()
        np.testing.assert_array_equal(spec.running_costs[0].reference, U[0])  # one function for both
        # the thrusts balance the weight's component along the body z axis, m g cos(30 deg) / 4 (the
        # rotor rows decouple from the lateral force here: the Euclidean least squares agree)
        np.testing.assert_allclose(U[0], 1.5 * 9.81 * np.cos(np.radians(30.0)) / 4, rtol=1e-12)
        np.testing.assert_allclose(U[0], np.linalg.lstsq(p.model.actuation, g, rcond=None)[0], rtol=1e-12)
        assert np.linalg.norm(p.model.actuation @ U[0] - g) > 1.0  # the lateral part stays


def test_default_start_is_clipped_into_the_limits():
    """Rotor thrusts limited to [0, 3] N, below the hover thrust 3.68 N: "hover" is refused there,
    the default start is the hover thrust clipped to 3 N."""
    path = scene_file("quadrotor")
    d = tomllib.loads(path.read_text())
    d["limits"] = {"control_min": 0.0, "control_max": 3.0}
    with pytest.raises(InputError) as e:
        parse_scene(d, str(path))
    assert e.value.parameter == "[solver].initial_controls" and "outside the limits" in str(e.value)
    del d["solver"]["initial_controls"]
    p = build_problem(parse_scene(d, str(path)))
    U = p.quasi_static_controls()
    assert np.array_equal(U, np.full((p.horizon, 4), 3.0))
    r = solve(p, SolverOptions(verbose=False, max_iter=2))
    assert r.cost_history[0] == p.total_cost(U)


def test_no_gravity_means_zeros_and_bitwise_the_zero_start():
    for p in (paper_problem(), build_problem(load_scene("spacecraft_docking")),
              build_problem(load_scene("space_manipulator"))):
        U = p.quasi_static_controls()
        assert U.shape == (p.horizon, p.nu) and not np.any(U) and not np.any(np.signbit(U))
        a = solve(p, SolverOptions(verbose=False, max_iter=3))
        b = solve(p, SolverOptions(verbose=False, max_iter=3), initial_controls=np.zeros((p.horizon, p.nu)))
        assert np.array_equal(a.cost_history, b.cost_history) and np.array_equal(a.controls, b.controls)
    # the model-level function: exact zeros without gravity, least squares with it
    pm = pin.buildSampleModelManipulator()
    q = pin.neutral(pm)
    A = np.eye(pm.nv)[:, :3]  # three of six joints actuated
    g = pin.computeGeneralizedGravity(pm, pm.createData(), q)
    np.testing.assert_array_equal(quasi_static_inputs(pm, A, q), np.linalg.lstsq(A, g, rcond=None)[0])
    pm.gravity = pin.Motion.Zero()
    assert np.array_equal(quasi_static_inputs(pm, A, q), np.zeros(3))


def test_a_problem_without_the_member_starts_from_zeros():
    """quasi_static_controls is an optional member of the contract: without it, zeros (projected
    into the limits) as before."""
    p = build_problem(load_scene("quadrotor"))

    class Bare:  # the contract's members only
        def __init__(self, inner):
            self._p = inner
            self.nx, self.nu, self.horizon, self.dt = inner.nx, inner.nu, inner.horizon, inner.dt

        def __getattr__(self, name):
            if name == "quasi_static_controls":
                raise AttributeError(name)
            return getattr(self._p, name)

    r = solve(Bare(p), SolverOptions(verbose=False, max_iter=1))
    assert r.cost_history[0] == p.total_cost(np.zeros((p.horizon, p.nu)))
    assert solve(p, SolverOptions(verbose=False, max_iter=1)).cost_history[0] == p.total_cost(
        p.quasi_static_controls())


def test_cli_run_starts_quasi_static(panda_files, tmp_path, capsys):
    import json

    from geoddp.cli import EXIT_CONVERGED, main

    out = tmp_path / "panda.json"
    code = main(["run", str(panda_files["default"]), "--quiet", "--json", str(out)])
    assert code == EXIT_CONVERGED, capsys.readouterr()
    d = json.loads(out.read_text())
    p = build_problem(load_scene(panda_files["default"]))
    assert d["converged"] and d["cost_history"][0] == p.total_cost(p.quasi_static_controls())
