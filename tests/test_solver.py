"""Algorithm 1 on the paper's problem: gradient, optimum, convergence rates."""
import numpy as np
import pytest
from scipy.optimize import minimize

from geoddp.problem import paper_problem
from geoddp.solver import STATUS_CONVERGED_COST, STATUS_CONVERGED_GRAD
from geoddp.solver import SolverOptions, cost_gradient, solve


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
@pytest.mark.parametrize("attitude_kind", ["chordal", "geodesic"])
def test_psi_gradient_against_finite_differences(rng, integrator, attitude_kind):
    p = paper_problem(integrator=integrator, attitude_kind=attitude_kind, horizon=40, running_S_R=3.0,
                      running_S_Omega=np.diag([1.0, 2.0, 3.0]))
    U = rng.normal(size=(40, 3))
    J, g = cost_gradient(p, U)
    h = 1e-4
    roundoff = 20 * np.finfo(float).eps * J / h  # central-difference round-off of J(U)
    for idx in [(0, 0), (7, 1), (20, 2), (39, 0), (39, 2)]:
        E = np.zeros_like(U)
        E[idx] = h
        fd = (p.total_cost(U + E) - p.total_cost(U - E)) / (2 * h)
        assert abs(fd - g[idx]) < 1e-7 * max(1.0, abs(fd)) + roundoff, (idx, fd, g[idx], roundoff)


def test_all_expansions_reach_the_same_optimum(paper_solves):
    costs = {k: r.cost for k, r in paper_solves.items()}
    ref = costs["switch"]
    for k, J in costs.items():
        assert abs(J - ref) <= 1e-9 * ref, costs
    for r in paper_solves.values():
        assert r.status in (STATUS_CONVERGED_COST, STATUS_CONVERGED_GRAD)
        assert np.all(np.diff(r.cost_history) <= 0.0), "cost rose between accepted iterates"


def test_independent_solver_agrees(paper, paper_solves):
    """scipy L-BFGS on the single-shooting cost with the psi gradient."""
    H, m = paper.horizon, paper.nu

    def fg(x):
        J, g = cost_gradient(paper, x.reshape(H, m))
        return J, g.ravel()

    res = minimize(fg, np.zeros(H * m), jac=True, method="L-BFGS-B",
                   options=dict(maxiter=5000, ftol=1e-15, gtol=1e-8, maxcor=30))
    J_star = paper_solves["switch"].cost
    assert abs(res.fun - J_star) <= 1e-6 * J_star
    assert res.fun >= J_star - 1e-9 * J_star  # DDP's optimum is not beaten


def test_default_options_reach_small_gradient(paper):
    for exp in ("second", "switch"):
        r = solve(paper, SolverOptions(expansion=exp, verbose=False))
        assert r.converged
        assert r.grad_norm <= 1e-9, (exp, r.grad_norm)
        assert r.attitude_error_deg < 5.0


def _ratios(seq):
    seq = np.asarray(seq)
    return seq[1:] / seq[:-1]


@pytest.mark.parametrize("exp", ["second", "switch"])
def test_second_order_converges_superlinearly(paper_solves, exp):
    r = paper_solves[exp]
    g = r.grad_norm_history
    # the last three gradient reductions above round-off (1e-9) shrink: superlinear
    idx = np.where(g > 1e-9)[0]
    tail = g[idx[-3]: idx[-1] + 2]
    q = _ratios(tail)
    assert len(q) >= 2
    assert np.all(np.diff(q) < 0), q  # the contraction factor itself goes to 0
    assert q[-1] < 1e-2, q
    assert r.grad_norm <= 1e-9


def test_first_order_converges_linearly(paper_solves):
    r = paper_solves["first"]
    g = r.grad_norm_history
    # the linear phase: between the transient and the round-off floor of the line search
    phase = g[(g < 1e-1) & (g > 1e-6)]
    q = _ratios(phase)
    assert len(q) >= 3
    assert np.all((q > 0.01) & (q < 0.5)), q  # a steady contraction factor ...
    assert q.max() / q.min() < 5.0, q  # ... that does not go to zero


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
def test_all_backends_give_the_same_iterates(integrator):
    """The compiled fast path against the numpy reference (1e-12) and Pinocchio (1e-8)."""
    # the backend is a model choice, made when the problem is built
    from oracle_satellite import with_backend

    p = paper_problem(horizon=60, dt=0.05, integrator=integrator)
    c, a, b = (solve(with_backend(p, be), SolverOptions(verbose=False)) for be in ("compiled", "analytic", "pinocchio"))
    assert c.iterations == a.iterations == b.iterations
    assert np.allclose(c.cost_history, a.cost_history, rtol=1e-12, atol=0)
    assert np.abs(c.controls - a.controls).max() <= 1e-12 * np.abs(a.controls).max()
    assert np.allclose(a.cost_history, b.cost_history, rtol=1e-10, atol=0)
    assert np.abs(a.controls - b.controls).max() <= 1e-8 * np.abs(a.controls).max()


def test_result_is_finite_and_rotations_orthonormal(paper_solves):
    r = paper_solves["switch"]
    for arr in (r.rotations, r.angular_velocities, r.controls, r.feedback, r.feedforward):
        assert np.all(np.isfinite(arr))
    RtR = np.einsum("nji,njk->nik", r.rotations, r.rotations)
    assert np.abs(RtR - np.eye(3)).max() < 1e-12


def test_feedback_gains_predict_the_response_to_a_perturbation(paper, paper_solves):
    """K from the final backward pass is the optimal feedback: closing the loop from a perturbed
    start must cost less than replaying the open-loop controls."""
    import pinocchio as pin
    from geoddp import kernels

    r = paper_solves["switch"]
    R0 = paper.R0 @ pin.exp3(np.array([0.02, -0.01, 0.015]))
    m = paper.model
    H = paper.horizon
    Rc, Oc, Uc = np.empty((H + 1, 3, 3)), np.empty((H + 1, 3)), np.empty((H, 3))
    kernels.satellite_rollout(R0, paper.Omega0, r.rotations, r.angular_velocities, r.controls,
                              np.zeros((H, 3)), r.feedback, 0.0, True, m.inertia, m.inertia_inv,
                              m.actuation, m.dt, m.semi_implicit, Rc, Oc, Uc)
    Ro, Oo = m.rollout(R0, paper.Omega0, r.controls)
    closed, open_ = paper.cost(Rc, Oc, Uc), paper.cost(Ro, Oo, r.controls)
    assert closed < open_


def _random_problem(seed: int, integrator: str, backend: str = "compiled"):
    import pinocchio as pin

    from oracle_satellite import with_backend

    from geoddp.problem import satellite_problem

    rng = np.random.default_rng(seed)
    Q = pin.exp3(rng.normal(size=3))
    inertia = Q @ np.diag([6.0, 8.0, 11.0]) @ Q.T  # non-diagonal
    return with_backend(satellite_problem(inertia=inertia, actuation=rng.normal(size=(3, 2)) + np.eye(3)[:, :2], dt=0.02,
                             horizon=80, R_d=pin.exp3(rng.normal(size=3)), R0=pin.exp3(rng.normal(size=3)),
                             Omega0=rng.normal(size=3), S_u=np.diag([0.2, 0.5]), S_R=np.diag([50.0, 80.0, 60.0]),
                             S_Omega=20.0, attitude_kind="geodesic", integrator=integrator), backend)


@pytest.mark.parametrize("integrator", ["euler", "semi_implicit"])
def test_fast_path_equals_pinocchio_path_on_a_random_scene(integrator):
    """Issue 3: the compiled path against the Pinocchio-based path on a random scene.

    First order, both paths are analytic: J history and controls agree to 1e-12 relative. With the
    second-order terms, the Pinocchio path's velocity Hessians are central differences of its
    analytic first derivatives (the pip wheel has no second-order ABA derivatives), so agreement
    is at their accuracy, 1e-9; the numpy reference of the same closed forms agrees to 1e-12."""
    p, pp, pa = (_random_problem(7, integrator, be) for be in ("compiled", "pinocchio", "analytic"))
    for exp in ("first", "switch"):
        c = solve(p, SolverOptions(expansion=exp, verbose=False))
        pn = solve(pp, SolverOptions(expansion=exp, verbose=False))
        a = solve(pa, SolverOptions(expansion=exp, verbose=False))
        assert c.iterations == pn.iterations == a.iterations
        assert np.allclose(c.cost_history, a.cost_history, rtol=1e-12, atol=0)
        assert np.abs(c.controls - a.controls).max() <= 1e-12 * np.abs(a.controls).max()
        tol = 1e-12 if exp == "first" else 1e-9
        assert np.allclose(c.cost_history, pn.cost_history, rtol=tol, atol=0), exp
        assert np.abs(c.controls - pn.controls).max() <= tol * np.abs(pn.controls).max(), exp


def test_satellite_outside_the_euler_schemes_runs_the_general_one_body_model():
    """The backend is chosen by structure: rk4 is not a TSO(3) closed form, so the satellite runs
    as the general one-body model (satellite.urdf, spherical root, no gravity, its inertia) with
    the same attitude term on the body frame; its optimum is the semi-implicit one to O(dt)."""
    from geoddp.models.multibody import Multibody
    from geoddp.models.satellite import Satellite
    from geoddp.validate import InputError

    si = paper_problem(integrator="semi_implicit", attitude_kind="geodesic", horizon=60, dt=0.05)
    rk = paper_problem(integrator="rk4", attitude_kind="geodesic", horizon=60, dt=0.05)
    assert isinstance(si.model, Satellite) and isinstance(rk.model, Multibody)
    assert np.array_equal(rk.model.pin_model.inertias[1].inertia, si.model.inertia)
    a, b = solve(si, SolverOptions(verbose=False)), solve(rk, SolverOptions(verbose=False))
    assert abs(a.cost - b.cost) <= 2e-3 * a.cost  # measured 1.0e-3 (different integrators)
    assert np.abs(b.rotations[-1] - si.describe()["target_rotation"]).max() < 0.05
    assert np.abs(rk.describe()["target_rotation"] - si.describe()["target_rotation"]).max() == 0.0
    # the chordal term too (FrameRotationChordal on the body frame): its own optimum, within the
    # integrators' O(dt) of the semi-implicit one
    ch = paper_problem(integrator="rk4", attitude_kind="chordal", horizon=60, dt=0.05)
    sc = paper_problem(integrator="semi_implicit", attitude_kind="chordal", horizon=60, dt=0.05)
    assert isinstance(ch.model, Multibody) and isinstance(sc.model, Satellite)
    c, d = solve(ch, SolverOptions(verbose=False)), solve(sc, SolverOptions(verbose=False))
    assert c.converged and abs(c.cost - d.cost) <= 2e-3 * d.cost
    with pytest.raises(InputError, match="attitude_kind"):
        paper_problem(integrator="rk4", attitude_kind="quat", horizon=10)


def test_an_exact_model_indefinite_beyond_reg_max_hands_back_to_first_order(paper, paper_solves):
    """With reg_max = 1e-6 no lambda makes the paper problem's first exact Q_uu positive definite:
    second order does not stop there but takes first-order steps until one is full and
    unregularised, then finishes at second order, at the optimum of the default solve."""
    res = solve(paper, SolverOptions(expansion="second", verbose=False, reg_max=1e-6))
    assert res.status in (STATUS_CONVERGED_COST, STATUS_CONVERGED_GRAD), res.message
    assert list(res.expansion_history) == ["first", "first", "second", "second"]
    assert res.step_history[1] == 1.0 and res.reg_history[1] == 0.0  # the step that hands over again
    ref = paper_solves["second"].cost
    assert abs(res.cost - ref) <= 1e-9 * ref
