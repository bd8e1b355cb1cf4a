"""Issue 5, hard cases: every scene in examples/hard/ with each expansion (first, second, switch).

For each solve: it converges within 300 iterations to a small gradient, or stops with an honest
non-converged status; J never rises between accepted iterates; the result holds no NaN/inf; every
rotation of the horizon is orthonormal to 1e-12; two runs are bit-identical. The exactly-180-deg
scene starts at a saddle (zero gradient, indefinite reduced Hessian) that the solver must escape.
The H = 30000 case is checked by rollout only (a solve would take too long for CI).
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from geoddp import solve_scene
from geoddp.solver import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_MAX_ITER,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_SADDLE,
    STATUS_STALLED,
)
from geoddp.scene import build_problem, load_scene
from geoddp.solver import SolverOptions, solve

HARD = Path(__file__).resolve().parent.parent / "examples" / "hard"
SCENES = sorted(p.name for p in HARD.glob("*.toml"))
EXPANSIONS = ("first", "second", "switch")
MAX_ITER = 300
ORTHO_TOL = 1e-12


@functools.lru_cache(maxsize=None)
def _solves(scene: str, expansion: str):
    """Two independent solves of the same scene (for the bit-identity check); cached per session."""
    run = lambda: solve_scene(HARD / scene, verbose=False, expansion=expansion, max_iter=MAX_ITER)  # noqa: E731
    return run(), run()


def _orthonormality_error(R: np.ndarray) -> float:
    """max_k ||R_k^T R_k - I||_max, plus |det R_k - 1| (a reflection would pass the first test)."""
    RtR = np.einsum("kji,kjl->kil", R, R)
    return max(float(np.max(np.abs(RtR - np.eye(3)))), float(np.max(np.abs(np.linalg.det(R) - 1.0))))


def test_the_hard_scene_set_is_complete():
    assert len(SCENES) == 13, SCENES
    assert "target_180deg_x.toml" in SCENES and "long_horizon_H3000.toml" in SCENES


@pytest.mark.parametrize("expansion", EXPANSIONS)
@pytest.mark.parametrize("scene", SCENES)
def test_hard_scene(scene, expansion):
    r, r2 = _solves(scene, expansion)

    # Converged to a small gradient, or an honest stop.
    assert r.iterations <= MAX_ITER
    g = r.grad_norm_history
    if r.converged:
        assert r.status in (STATUS_CONVERGED_COST, STATUS_CONVERGED_GRAD)
        # "small": 1e-6 of the largest gradient met on the way (the scenes' costs span 1e-4 .. 1e4,
        # so an absolute threshold would mean nothing), or below the absolute 1e-6.
        assert g[-1] <= max(1e-6, 1e-6 * g.max()), (r.status, r.message, g[-1], g.max())
    else:
        assert r.status in (STATUS_MAX_ITER, STATUS_MAX_REG, STATUS_NO_DESCENT, STATUS_SADDLE, STATUS_STALLED), r.status
        assert r.message and "converged" not in r.status

    # Monotone cost, consistent histories.
    assert len(r.cost_history) == r.iterations + 1 == len(g)
    assert np.all(np.diff(r.cost_history) <= 0.0), "cost rose between accepted iterates"
    assert r.cost == r.cost_history[-1]

    # No NaN or inf anywhere.
    for name, val in vars(r).items():
        if isinstance(val, np.ndarray):
            assert np.all(np.isfinite(val)), name
    assert np.isfinite(r.cost) and np.isfinite(r.attitude_error_deg) and np.isfinite(r.angular_velocity_error)

    # Orthonormal rotations over the whole horizon.
    assert r.rotations.shape == (r.horizon + 1, 3, 3)
    assert _orthonormality_error(r.rotations) <= ORTHO_TOL

    # Deterministic: a second run is bit-identical.
    assert np.array_equal(r.controls, r2.controls)
    assert np.array_equal(r.cost_history, r2.cost_history)
    assert (r.cost_history == r2.cost_history).all() and (r.controls == r2.controls).all()
    assert r.status == r2.status and r.iterations == r2.iterations


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_180deg_saddle_is_escaped_to_a_genuine_minimum(expansion):
    """Exactly 180 deg about x with the chordal cost: U = 0 is stationary but not a minimum.

    tr(S_R (I - R_d^T R)) has zero gradient at R = I when R_d = Rot_x(pi) (R_d^T is symmetric), and
    it is *maximal* along rotations about x, so the zero-control start is a saddle of J(U).
    """
    r, _ = _solves("target_180deg_x.toml", expansion)
    J_saddle = r.cost_history[0]
    assert r.grad_norm_history[0] == 0.0  # the start really is stationary
    escapes = r.extra.get("saddle_escapes")
    assert escapes, r.message
    assert escapes[0]["iteration"] == 0 and escapes[0]["eigenvalue"] < 0.0
    assert escapes[0]["cost_after"] < escapes[0]["cost_before"] == J_saddle
    # Ends at a minimum that passes the final exact second-order check, well below the saddle.
    assert r.converged, (r.status, r.message)
    assert r.status != STATUS_SADDLE
    assert r.cost < 0.1 * J_saddle
    assert r.grad_norm <= 1e-6 * r.grad_norm_history.max()
    assert r.attitude_error_deg < 10.0  # it actually turned (by about 180 deg) toward the target
    assert "saddle" in r.message


def test_180deg_saddle_on_the_general_model():
    """The same saddle with the variational step, which runs on the general one-body model
    (FrameRotationChordal on the body frame, the compiled core): escaped along negative curvature
    to the TSO(3) optimum. The optimal motion turns about x only, where Jr(dt y) e_x = e_x and the
    forward variational Euler step is explicit Euler's, so the two optima agree to round-off
    (measured: J* 1961.146756296005 against 1961.146756296004)."""
    spec = load_scene(HARD / "target_180deg_x.toml")
    problem = build_problem(spec.with_overrides(integrator="variational"))
    assert type(problem.model).__name__ == "Multibody" and problem.model.integrator == "variational"
    r = solve(problem, SolverOptions(verbose=False))
    euler, _ = _solves("target_180deg_x.toml", "switch")
    assert r.grad_norm_history[0] == 0.0 and r.extra.get("saddle_escapes")
    assert r.converged and r.status != STATUS_SADDLE
    assert r.cost == pytest.approx(euler.cost, rel=1e-12)


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_history_has_one_entry_per_accepted_step_escapes_included(expansion):
    """The recorder appends once per accepted step, the escape step included: per-step histories
    have ``iterations`` entries, per-iterate ones ``iterations + 1``, and the escape is recorded
    as a second-order step of length |alpha| that lowers J by what the escape info says."""
    r = solve_scene(HARD / "target_180deg_x.toml", verbose=False, expansion=expansion, record_controls=True)
    n = r.iterations
    assert len(r.reg_history) == len(r.step_history) == len(r.expansion_history) == n
    assert len(r.cost_history) == len(r.grad_norm_history) == len(r.time_history) == n + 1
    assert r.control_history.shape == (n + 1, r.horizon, r.controls.shape[1])
    assert np.array_equal(r.control_history[-1], r.controls)
    (esc,) = r.extra["saddle_escapes"]
    i = esc["iteration"]
    assert r.expansion_history[i] == "second" and r.step_history[i] == abs(esc["alpha"])
    assert r.cost_history[i] == esc["cost_before"] and r.cost_history[i + 1] == esc["cost_after"]
    assert np.all(np.diff(r.cost_history) <= 0.0)


def test_saddle_not_reported_converged_when_the_escape_has_no_budget():
    """With max_iter = 1 the escape step is the only iteration: the solve must not claim convergence."""
    r = solve_scene(HARD / "target_180deg_x.toml", verbose=False, max_iter=1)
    assert not r.converged
    assert r.status == STATUS_MAX_ITER
    assert r.iterations == 1 and r.cost < r.cost_history[0]


def test_long_horizon_H30000_rollout_stays_orthonormal():
    """H = 30000 (tf = 300 s at dt = 0.01 s): roll out a torque sequence that keeps the body tumbling."""
    spec = load_scene(HARD / "long_horizon_H3000.toml").with_overrides(tf=300.0)
    problem = build_problem(spec)
    assert problem.horizon == 30000
    t = np.arange(problem.horizon) * spec.dt
    U = np.stack([2.0 * np.sin(0.3 * t), 1.5 * np.cos(0.17 * t + 1.0), np.sin(0.05 * t) + 0.2], axis=1)
    R, Om = problem.rollout(U)
    assert R.shape == (30001, 3, 3) and Om.shape == (30001, 3)
    assert np.all(np.isfinite(R)) and np.all(np.isfinite(Om))
    assert np.max(np.linalg.norm(Om, axis=1)) > 1.0  # it really tumbles (many full turns)
    assert _orthonormality_error(R) <= ORTHO_TOL


def test_negative_curvature_matches_the_true_cost_at_the_saddle():
    """The escape direction's predicted curvature (eigenvalue of the numpy-mirrored Q_uu) agrees
    with the true J along the escape curve: J(alpha) - J(0) ~ alpha^2 / 2 * eigenvalue."""
    from geoddp import kernels
    from geoddp.solver.backward import Workspace, backward, node_quu

    from oracle_satellite import with_backend

    problem = with_backend(build_problem(load_scene(HARD / "target_180deg_x.toml")), "analytic")
    H, m = problem.horizon, problem.nu
    U = np.zeros((H, m))
    R, Om = problem.rollout(U)
    J0 = problem.cost(R, Om, U)
    ws = Workspace(H, m, problem.nx)
    lin = problem.linearise(problem.trajectory(U), 2)
    node, _, _ = backward(lin, ws, 0.0)
    assert node >= 0
    w, V = np.linalg.eigh(node_quu(lin, node))
    assert w[0] < 0.0
    for k in (node + 1, H - 1):  # the kernel factorised every later node: the mirror must agree
        assert np.linalg.eigvalsh(node_quu(lin, k))[0] > 0.0
    K = ws.K.copy()
    K[: node + 1] = 0.0
    kff = np.zeros((H, m))
    model = problem.model
    Rn, Omn, Un = np.empty_like(R), np.empty_like(Om), np.empty_like(U)
    for alpha in (1e-2, 3e-3):
        kff[node] = -alpha * V[:, 0]
        kernels.satellite_rollout(problem.R0, problem.Omega0, R, Om, U, kff, K, 1.0, True, model.inertia,
                                  model.inertia_inv, model.actuation, model.dt, model.semi_implicit, Rn, Omn, Un)
        dJ = problem.cost(Rn, Omn, Un) - J0
        assert dJ < 0.0
        assert abs(dJ - 0.5 * alpha**2 * w[0]) <= 1e-2 * abs(0.5 * alpha**2 * w[0]), (alpha, dJ, w[0])


def test_extreme_weights_all_expansions_reach_the_same_optimum():
    """S_u = 1e-8: a regularised step is a tiny gradient step whose small |dJ| must not stop the
    solve (regression: 'second' once stopped 0.7 % above the optimum)."""
    from geoddp import solve_scene

    costs = [solve_scene(HARD / "extreme_weights.toml", verbose=False, expansion=e, max_iter=300).cost
             for e in ("first", "second", "switch")]
    assert max(costs) - min(costs) <= 1e-6 * min(costs), costs
