"""The problem/solver contract (geoddp.problem.contract): every built-in scene's problem satisfies it, with
the documented shapes, and the solver needs nothing else (a proxy exposing only the contract
solves to the same iterates, bit for bit)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from geoddp.constraints import ConstrainedProblem
from geoddp.problem.contract import Linearisation, OptimalControlProblem, Trajectory
from geoddp.scene import SceneSpec, build_problem, load_scene
from geoddp.solver import SolverOptions, cost_gradient, solve
from geoddp.validate import InputError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENES = sorted(EXAMPLES.glob("*.toml")) + sorted((EXAMPLES / "hard").glob("*.toml")) + sorted(
    (EXAMPLES / "multibody").glob("*.toml"))
H_SHORT = 6


def _short(path: Path):
    spec = load_scene(path)
    if isinstance(spec, SceneSpec):
        return spec.with_overrides(tf=H_SHORT * spec.dt)
    return spec.with_overrides(horizon=H_SHORT)


def _clip(problem, U: np.ndarray) -> np.ndarray:
    """U clipped into the problem's control limits (issue 15), if it has some."""
    bounds = problem.control_bounds()
    return U if bounds is None else np.clip(U, *bounds)


def _controls(problem, rng) -> np.ndarray:
    return _clip(problem, 0.1 * rng.normal(size=(problem.horizon, problem.nu)))


def test_every_example_scene_is_covered():
    # satellite_paper, _semi_implicit, _authors_code, _wheel_limits, _keep_out (hard constraints); hard; 4 multibody
    assert len(SCENES) == 5 + 13 + 4


@pytest.mark.parametrize("path", SCENES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_builtin_scene_problem_satisfies_the_contract(path, rng):
    problem = build_problem(_short(path))
    if isinstance(problem, ConstrainedProblem):
        # a scene with hard constraints: what the solver sees is the outer loop's inner problem,
        # the augmented Lagrangian of the constraints added to the costs (zero multipliers here)
        problem = problem.augmented([np.zeros((p.nodes.size, p.bound.rows)) for p in problem.placed],
                                    [10.0] * len(problem.placed))
    assert isinstance(problem, OptimalControlProblem)
    H, m, nx = problem.horizon, problem.nu, problem.nx
    assert H == H_SHORT and m >= 1 and nx % 2 == 0 and problem.dt > 0.0
    nv = nx // 2

    U = _controls(problem, rng)
    traj = problem.trajectory(U)
    assert isinstance(traj, Trajectory)
    assert traj.q.shape[0] == H + 1 and traj.v.shape == (H + 1, nv) and traj.u.shape == (H, m)
    assert np.array_equal(traj.u, U)
    J = problem.trajectory_cost(traj)
    assert isinstance(J, float) and np.isfinite(J) and J >= 0.0

    for order in (1, 2):
        lin = problem.linearise(traj, order)
        assert isinstance(lin, Linearisation) and lin.order == order
        shapes = dict(Phi=(H, nx, nx), B=(H, nx, m), l_x=(H, nx), l_u=(H, m), l_xx=(H, nx, nx),
                      l_ux=(H, m, nx), l_uu=(H, m, m), lf_x=(nx,), lf_xx=(nx, nx))
        if order == 2 and lin.second_order is not None:
            # factored second order (compiled multibody): no tensors; the contraction has the
            # Q-function's shape (its values: tests/test_core_contracted.py)
            assert lin.Theta is None and lin.Gamma is None and lin.Xi is None
            S = lin.second_order.contract(H - 1, np.ones(nx))
            assert S.shape == (nx + m, nx + m) and np.all(np.isfinite(S))
        elif order == 2:
            shapes.update(Theta=(H, nx, nx, nx), Gamma=(H, nx, nx, m), Xi=(H, nx, m, m))
        else:
            assert lin.Theta is None and lin.Gamma is None and lin.Xi is None
        for name, shape in shapes.items():
            a = getattr(lin, name)
            assert a.shape == shape, (name, a.shape, shape)
            assert np.all(np.isfinite(a)), name

    # The policy law u = u_bar - step k - K difference(x, x_bar): with K = 0 and k = (u_bar - U2)
    # / step it is the open loop U2, so it must reproduce trajectory(U2) exactly; with gains, the
    # applied controls follow the law at the first node (zeta_0 = 0: x_0 is shared).
    U2 = _controls(problem, rng)
    K0 = np.zeros((H, m, nx))
    step = 0.5
    closed = problem.rollout_policy(traj, (U - U2) / step, K0, step)
    open_ = problem.trajectory(U2)
    assert np.allclose(closed.u, U2, rtol=0, atol=1e-15)
    assert np.allclose(closed.q, open_.q, rtol=0, atol=1e-13) and np.allclose(closed.v, open_.v, rtol=0, atol=1e-13)
    K = rng.normal(size=(H, m, nx))
    k = rng.normal(size=(H, m))
    fb = problem.rollout_policy(traj, k, K, 1.0)
    assert np.allclose(fb.u[0], _clip(problem, U - k)[0], rtol=0, atol=1e-15)  # clamped into the limits
    # ... and the same policy about the nominal itself with zero gains gives back the nominal
    same = problem.rollout_policy(traj, np.zeros((H, m)), K, 1.0)
    assert np.allclose(same.u, U, rtol=0, atol=1e-12) and np.allclose(same.v, traj.v, rtol=0, atol=1e-12)
    kbad = np.zeros((H, m))
    kbad[0, 0] = np.nan
    assert problem.rollout_policy(traj, kbad, K0, 1.0) is None

    with pytest.raises(InputError, match="^initial_controls"):
        problem.check_controls(np.zeros((H + 1, m)))
    assert np.array_equal(problem.check_controls(U), U)

    d = problem.describe()
    assert d["kind"] in ("satellite", "multibody") and d["dt"] == problem.dt and isinstance(d["integrator"], str)
    assert np.shape(d["target_rotation"]) == (3, 3) and np.shape(d["target_angular_velocity"]) == (3,)
    if d["kind"] == "multibody":
        assert {"urdf", "urdf_xml", "root", "nq", "nv"} <= set(d) and d["nv"] == nv
        assert traj.q.shape == (H + 1, d["nq"])
    else:
        assert traj.q.shape == (H + 1, 3, 3)
    json.dumps({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()})


class _OnlyTheContract:
    """Exposes the members of OptimalControlProblem and nothing else."""

    def __init__(self, problem) -> None:
        self._p = problem
        self.nx, self.nu, self.horizon, self.dt = problem.nx, problem.nu, problem.horizon, problem.dt

    def check_controls(self, controls, name="initial_controls"):
        return self._p.check_controls(controls, name)

    def trajectory(self, controls):
        return self._p.trajectory(controls)

    def trajectory_cost(self, traj):
        return self._p.trajectory_cost(traj)

    def linearise(self, traj, order):
        return self._p.linearise(traj, order)

    def rollout_policy(self, traj, k, K, step):
        return self._p.rollout_policy(traj, k, K, step)

    def describe(self):
        return self._p.describe()


@pytest.mark.parametrize("name", ["satellite_paper.toml", "hard/target_180deg_x.toml", "multibody/space_manipulator.toml"])
def test_the_solver_needs_only_the_contract(name):
    spec = load_scene(EXAMPLES / name)
    if not isinstance(spec, SceneSpec):
        spec = spec.with_overrides(horizon=40, dt=0.05)
    problem = build_problem(spec)
    proxy = _OnlyTheContract(problem)
    assert isinstance(proxy, OptimalControlProblem)
    opt = SolverOptions(verbose=False, record_controls=True)
    a, b = solve(problem, opt), solve(proxy, opt)
    for f in ("cost_history", "grad_norm_history", "reg_history", "step_history", "controls", "feedback"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert a.expansion_history == b.expansion_history and a.status == b.status
    assert np.array_equal(a.rotations, b.rotations) and np.array_equal(a.target_rotation, b.target_rotation)
    U = np.asarray(a.controls)
    Ja, ga = cost_gradient(problem, U)
    Jb, gb = cost_gradient(proxy, U)
    assert Ja == Jb and np.array_equal(ga, gb)


def test_satellite_and_multibody_describe_their_model_alike():
    """One Problem class: both kinds describe kind, dt, integrator, the URDF, root, nq, nv and the
    terminal targets, so the Result and the viewer read the same keys."""
    from geoddp.problem import paper_problem
    from geoddp.scene.builtin import quadrotor

    sat, mb = paper_problem().describe(), quadrotor(horizon=5).describe()
    common = {"kind", "dt", "integrator", "urdf", "root", "nq", "nv", "target_rotation", "target_angular_velocity"}
    assert common <= set(sat) and common <= set(mb)
    assert (sat["kind"], sat["root"], sat["nq"], sat["nv"]) == ("satellite", "spherical", 4, 3)
    assert Path(sat["urdf"]).name == "satellite.urdf"
    assert mb["kind"] == "multibody"
