"""Control limits (issue 15): validation, the feasible forward pass, and constrained solves.

Numbers asserted: KKT residuals and complementarity at the returned point, feasibility of every
iterate, monotone cost, agreement of the three expansions (1e-9 relative) and of scipy's L-BFGS-B
on the single-shooting cost with our exact gradient (1e-7 relative), bit-for-bit equality with
the unconstrained solver when the limits never bind.
"""
import json

import numpy as np
import pytest

from geoddp.scene import builtin as scenes
from geoddp.problem.limits import ControlLimits, active_set, projected_gradient
from geoddp.problem import Problem, paper_problem
from geoddp import Result
from geoddp.solver import SolverOptions, cost_gradient, solve
from geoddp.validate import InputError

EXPANSIONS = ("first", "second", "switch")
KKT_TOL = 1e-5  # max |projected gradient| at a returned point; J ~ 1e3 and ||dJ/dU|| ~ 5e2 at the
# start: 2e-8 relative. The solver stops on |dJ| <= tol = 1e-8 certified by the Newton decrement
# (the cost, not the gradient, is what it drives to 1e-8): first order ends at ~3e-6, second at ~1e-9.


def opts(**kw):
    return SolverOptions(verbose=False, record_controls=True, **kw)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize("limits, parameter, words", [
    ((1.0, -1.0), "limits.lower", "lower <= upper"),
    ((np.nan, 1.0), "limits.lower", "NaN"),
    ((-1.0, [1.0, np.nan, 1.0]), "limits.upper", "NaN"),
    (([-1.0, -1.0], 1.0), "limits.lower", "3 numbers"),
    ((-1.0, np.ones((7, 3))), "limits.upper", "array"),
    ((np.inf, np.inf), "limits.lower", "+inf"),
    ((-1.0, -np.inf), "limits.upper", "-inf"),
    (("a", 1.0), "limits.lower", "expected a number"),
    ((1.0, 2.0, 3.0), "limits", "pair"),
    ({"lo": 1.0}, "limits", "keys"),
])
def test_bad_limits_name_the_parameter(limits, parameter, words):
    with pytest.raises(InputError) as e:
        paper_problem(horizon=10, limits=limits)
    assert e.value.parameter == parameter
    assert words in str(e.value)


def test_limit_forms_broadcast_to_nodes():
    H = 10
    lo_nodes = -np.linspace(1, 2, H)[:, None] * np.ones(3)
    for lim, lo0, hi0 in [((-2.0, 3.0), [-2.0] * 3, [3.0] * 3),
                          (ControlLimits([-1, -np.inf, -3], [1, 2, np.inf]), [-1, -np.inf, -3], [1, 2, np.inf]),
                          ({"upper": 4.0}, [-np.inf] * 3, [4.0] * 3),
                          ((lo_nodes, None), lo_nodes[0], [np.inf] * 3)]:
        lo, hi = paper_problem(horizon=H, limits=lim).control_bounds()
        assert lo.shape == hi.shape == (H, 3)
        np.testing.assert_array_equal(lo[0], lo0)
        np.testing.assert_array_equal(hi[0], hi0)
    lo, _ = paper_problem(horizon=H, limits=(lo_nodes, None)).control_bounds()
    np.testing.assert_array_equal(lo, lo_nodes)
    assert paper_problem(horizon=H).control_bounds() is None


def test_initial_guess_outside_the_box_is_rejected_and_default_guess_projected():
    p = paper_problem(horizon=20, limits=([0.5, -1, -1], [1, 1, 1]))
    U = np.zeros((20, 3))
    with pytest.raises(InputError) as e:
        solve(p, opts(max_iter=1), initial_controls=U)
    assert e.value.parameter == "initial_controls" and "node 0, input 0" in str(e.value)
    r = solve(p, opts(max_iter=1))  # zeros, clipped into the box: u_1 starts on its lower bound 0.5
    np.testing.assert_array_equal(r.control_history[0][:, 0], 0.5)
    np.testing.assert_array_equal(r.control_history[0][:, 1:], 0.0)


# ------------------------------------------------------------------ the feasible forward pass
def _random_policy(rng, p, scale):
    H, m, nx = p.horizon, p.nu, p.nx
    nominal = p.trajectory(np.clip(rng.normal(size=(H, m)), *p.control_bounds()))
    return nominal, scale * rng.normal(size=(H, m)), scale * rng.normal(size=(H, m, nx))


@pytest.mark.parametrize("which", ["satellite", "multibody_compiled", "multibody_python"])
def test_forward_pass_clamps_after_the_feedback_law(which, monkeypatch):
    """Rule: u_k = clip(u_bar_k - gamma k_k - K_k zeta_k, lower_k, upper_k), zeta_k from the
    clamped rollout itself; the stored controls are the applied ones (the states equal an open-
    loop rollout of them) and lie in the box."""
    rng = np.random.default_rng(1)
    if which == "satellite":
        p = paper_problem(horizon=40, limits=(-1.0, [0.5, 1.0, 2.0]))
    else:
        if which == "multibody_python":
            from oracle_multibody import use_oracle

            use_oracle(monkeypatch)
        q = scenes.quadrotor(integrator="semi_implicit", horizon=30)
        assert q.model.backend == ("python" if which == "multibody_python" else "compiled")
        p = Problem(q.model, q.q0, q.v0, q.horizon, q.running, q.terminal, limits=(0.0, 4.0))
    lo, hi = p.control_bounds()
    nominal, k, K = _random_policy(rng, p, 3.0)
    out = p.rollout_policy(nominal, k, K, 0.7)
    assert out is not None
    assert np.all(out.u >= lo) and np.all(out.u <= hi)
    assert np.any(out.u == lo) and np.any(out.u == hi)  # the clamp acted
    q_ol, v_ol = p.rollout(out.u)
    np.testing.assert_array_equal(out.v, v_ol)
    # the law, node by node, from the clamped states
    unc = Problem(p.model, p.q0, p.v0, p.horizon, p.running, p.terminal)
    for j in (0, 5, p.horizon - 1):
        zeta = _difference(p, nominal, out, j)
        u = nominal.u[j] - 0.7 * k[j] - K[j] @ zeta
        np.testing.assert_allclose(out.u[j], np.clip(u, lo[j], hi[j]), rtol=1e-12, atol=1e-12)
    # no limits: the same call without the clamp leaves the box
    free = unc.rollout_policy(nominal, k, K, 0.7)
    assert free is None or np.any(free.u > hi) or np.any(free.u < lo)


def _difference(p, nominal, traj, j):
    import pinocchio as pin

    if p.nx == 6 and nominal.q.ndim == 3:
        return np.concatenate([pin.log3(nominal.q[j].T @ traj.q[j]), traj.v[j] - nominal.v[j]])
    return np.concatenate([pin.difference(p.model.pin_model, nominal.q[j], traj.q[j]), traj.v[j] - nominal.v[j]])


def test_forward_pass_keeps_nan_and_reports_non_finite():
    p = paper_problem(horizon=10, limits=(-1.0, 1.0))
    nominal = p.trajectory(np.zeros((10, 3)))
    k = np.zeros((10, 3))
    k[3] = np.nan
    assert p.rollout_policy(nominal, k, np.zeros((10, 3, 6)), 1.0) is None


# ------------------------------------------------------------------ the paper's satellite (Table I)
@pytest.fixture(scope="module")
def unconstrained():
    return solve(paper_problem(), opts())


@pytest.fixture(scope="module")
def table1():
    """{(limit, expansion): Result} for |u_i| <= 5 and <= 3 N m."""
    return {(lim, e): solve(paper_problem(limits=(-lim, lim)), opts(expansion=e)) for lim in (5.0, 3.0) for e in EXPANSIONS}


def check_kkt(problem, r, tol=KKT_TOL):
    """KKT of min J(U) over the box, recomputed from the exact gradient (not the solver's record)."""
    lo, hi = problem.control_bounds()
    U = r.controls
    assert np.all(U >= lo) and np.all(U <= hi)
    _, g = cost_gradient(Problem(problem.model, problem.q0, problem.v0, problem.horizon, problem.running,
                                 problem.terminal), U)
    pg = projected_gradient(U, g, lo, hi)
    assert np.abs(pg).max() <= tol
    assert r.extra["optimality"]["kkt_residual"] == pytest.approx(np.abs(pg).max(), rel=1e-6, abs=1e-12)
    act = active_set(U, lo, hi)
    np.testing.assert_array_equal(act, r.active_set)
    # on a bound only where the gradient points outward (a descent direction would leave the box)
    assert np.all(g[act == -1] >= -tol) and np.all(g[act == 1] <= tol)
    return g, act


@pytest.mark.parametrize("lim, saturating", [(5.0, [False, False, True]), (3.0, [True, True, True])])
@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_table1_with_torque_limits(table1, unconstrained, lim, saturating, expansion):
    r = table1[(lim, expansion)]
    p = paper_problem(limits=(-lim, lim))
    assert r.converged, r.message
    g, act = check_kkt(p, r)
    np.testing.assert_array_equal((act != 0).any(axis=0), saturating)
    # strict complementarity on the saturated nodes except where a saturated arc begins or ends
    # (the stated degenerate case: the multiplier goes to zero continuously there)
    mult = np.abs(g[act != 0])
    assert np.median(mult) > 1e-3
    # every iterate inside the box, J never rises
    assert np.all(np.abs(r.control_history) <= lim)
    assert np.all(np.diff(r.cost_history) <= 0.0)
    assert r.cost > unconstrained.cost
    # the unconstrained peaks (about 3.0, 2.8, 8.9 N m): at 5 only axis 3's is cut; at 3 axis 2
    # saturates too although its unconstrained peak is below 3 (the axes couple through the
    # gyroscopic term and the shared attitude error)
    peaks = np.abs(unconstrained.controls).max(axis=0)
    np.testing.assert_allclose(peaks, [3.02, 2.82, 8.92], atol=0.01)


@pytest.mark.parametrize("lim", [5.0, 3.0])
def test_expansions_reach_the_same_constrained_optimum(table1, lim):
    J = [table1[(lim, e)].cost for e in EXPANSIONS]
    np.testing.assert_allclose(J, J[1], rtol=1e-9)
    U = [table1[(lim, e)].controls for e in EXPANSIONS]
    for u in U:
        np.testing.assert_allclose(u, U[1], atol=1e-4)
        np.testing.assert_array_equal(active_set(u, -lim, lim), active_set(U[1], -lim, lim))


@pytest.mark.parametrize("lim", [5.0, 3.0])
def test_lbfgsb_on_the_single_shooting_cost_agrees(table1, lim):
    """An independent optimiser: scipy's L-BFGS-B on J(U) over the box, with the exact gradient of
    Lemma lemm:psi (geoddp.solver.cost_gradient), from zero controls."""
    from scipy.optimize import minimize

    p = paper_problem()  # the same cost, no limits inside (L-BFGS-B handles the box)
    H, m = p.horizon, p.nu

    def fun(x):
        J, g = cost_gradient(p, x.reshape(H, m))
        return J, g.ravel()

    res = minimize(fun, np.zeros(H * m), jac=True, method="L-BFGS-B", bounds=[(-lim, lim)] * (H * m),
                   options=dict(maxiter=20000, maxfun=40000, ftol=1e-16, gtol=1e-9, maxcor=30))
    J_ddp = table1[(lim, "switch")].cost
    assert res.fun == pytest.approx(J_ddp, rel=1e-7)
    assert res.fun >= J_ddp * (1 - 1e-12)  # ours is not worse


def _count_box_passes(monkeypatch) -> list:
    """Replace the solver's compiled module by one that counts its box passes (dense and
    contracted); returns the list that grows by one per call."""
    import geoddp.solver.backward as bw

    real, calls = bw._core, []

    class Core:
        def __getattr__(self, name):
            fn = getattr(real, name)
            if not name.startswith("backward_pass_box"):
                return fn

            def counted(*a):
                calls.append(name)
                return fn(*a)
            return counted

    monkeypatch.setattr(bw, "_core", Core())
    return calls


def test_inactive_limits_give_the_unconstrained_solution_bit_for_bit(monkeypatch):
    """Limits that neither an iterate nor a full Newton step of the unconstrained solve reaches
    (its first full step overshoots to ~50 N m, so the bounds sit at -100 / +100.5, with unbounded
    holes): the box pass never runs (counted) and every number is the unconstrained one."""
    r0 = solve(paper_problem(), opts())
    calls = _count_box_passes(monkeypatch)
    H = 300
    lo = np.full((H, 3), -100.0)
    lo[::7, 1] = -np.inf
    r1 = solve(paper_problem(limits=(lo, 100.5)), opts())
    assert not calls
    assert r1.cost == r0.cost
    np.testing.assert_array_equal(r1.controls, r0.controls)
    np.testing.assert_array_equal(r1.control_history, r0.control_history)
    for key in ("cost_history", "grad_norm_history", "reg_history", "step_history"):
        np.testing.assert_array_equal(getattr(r1, key), getattr(r0, key))
    np.testing.assert_array_equal(r1.feedforward, r0.feedforward)
    np.testing.assert_array_equal(r1.feedback, r0.feedback)
    assert r1.expansion_history == r0.expansion_history and r1.status == r0.status
    assert not r1.active_set.any() and r1.extra["optimality"]["active_inputs"] == 0


# ------------------------------------------------------------------ hard cases
def test_unreachable_target_is_an_honest_optimum(unconstrained):
    p = paper_problem(limits=(-0.2, 0.2))
    r = solve(p, opts())
    assert r.converged, r.message
    check_kkt(p, r)
    assert r.cost > 10 * unconstrained.cost
    assert r.attitude_error_deg > 20.0  # the target is out of reach in 3 s with 0.2 N m
    assert (r.active_set != 0).mean() > 0.8
    assert np.all(np.diff(r.cost_history) <= 0.0)


def test_limit_active_from_the_first_iterate():
    # u_1 >= 1 N m: the default guess (zeros clipped into the box) starts on the bound
    p = paper_problem(limits=([1.0, -5, -5], 5.0))
    r = solve(p, opts())
    assert r.converged, r.message
    assert np.all(r.control_history[0][:, 0] == 1.0)
    g, act = check_kkt(p, r)
    assert (act[:, 0] == -1).any()
    assert np.all(r.control_history[:, :, 0] >= 1.0)


def test_underactuated_body_with_limits():
    H2 = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])  # no torque about the body z axis
    p = paper_problem(actuation=H2, limits=(-3.0, 3.0))
    r = solve(p, opts(max_iter=400))
    assert r.converged, r.message
    check_kkt(p, r)
    assert r.controls.shape == (300, 2)
    assert np.all(np.diff(r.cost_history) <= 0.0)


def test_lower_equal_to_upper_fixes_the_input():
    p = paper_problem(limits=([-5.0, 0.5, -5.0], [5.0, 0.5, 5.0]))
    r = solve(p, opts())
    assert r.converged, r.message
    np.testing.assert_array_equal(r.control_history[:, :, 1], 0.5)
    g, act = check_kkt(p, r)
    assert np.all(act[:, 1] != 0)
    # the other inputs optimise with u_2 fixed: an independent check against fixing it by hand
    # is the KKT test above (their gradient components vanish where free)
    free = act == 0
    assert np.abs(g[free]).max() <= KKT_TOL


# ------------------------------------------------------------------ multibody: quadrotor thrust limits
@pytest.fixture(scope="module")
def quadrotor_limits():
    q = scenes.quadrotor(integrator="semi_implicit")
    p = Problem(q.model, q.q0, q.v0, q.horizon, q.running, q.terminal, limits=(0.0, 4.0))
    return p, {e: solve(p, opts(expansion=e)) for e in ("second", "switch")}


def test_quadrotor_thrust_limits(quadrotor_limits):
    p, rs = quadrotor_limits
    for r in rs.values():
        assert r.converged, r.message
        check_kkt(p, r, tol=1e-5)
        # T_max binds on every rotor for tens of nodes (0 N does not: the optimum never cuts a rotor)
        assert np.all((r.active_set == 1).sum(axis=0) >= 5) and (r.active_set == 1).sum() > 100
        assert np.all(r.control_history >= 0.0) and np.all(r.control_history <= 4.0)
        assert np.all(np.diff(r.cost_history) <= 0.0)
    assert rs["second"].cost == pytest.approx(rs["switch"].cost, rel=1e-9)


# ------------------------------------------------------------------ output
def test_result_json_carries_limits_and_active_set(table1, tmp_path):
    r = table1[(5.0, "switch")]
    lo, hi = r.limits
    assert lo.shape == (300, 3) and np.all(hi == 5.0)
    d = json.loads(json.dumps(r.to_dict()))
    assert d["limits"]["upper"][0] == [5.0, 5.0, 5.0]
    assert d["optimality"]["kkt_residual"] <= KKT_TOL
    back = Result.read_json(r.write_json(tmp_path / "r.json"))
    np.testing.assert_array_equal(back.limits[0], lo)
    np.testing.assert_array_equal(back.active_set, r.active_set)
    # unbounded sides survive strict JSON (null <-> inf)
    p = paper_problem(horizon=20, limits=([-1, -np.inf, -1], [np.inf, 1, 1]))
    r2 = solve(p, opts(max_iter=2))
    back = Result.read_json(r2.write_json(tmp_path / "r2.json"))
    np.testing.assert_array_equal(back.limits[0], r2.limits[0])
    np.testing.assert_array_equal(back.limits[1], r2.limits[1])
    assert "NaN" not in (tmp_path / "r2.json").read_text() and "Infinity" not in (tmp_path / "r2.json").read_text()
    # a result without limits: null
    assert solve(paper_problem(horizon=20), opts(max_iter=1)).to_dict()["limits"] is None


def test_controls_figure_draws_bounds_and_shades_saturation(table1, tmp_path):
    from geoddp.viz.figures import plot_trajectory

    r = table1[(5.0, "switch")]
    figs = plot_trajectory(r, tmp_path)
    data = figs.data["controls"].arrays
    np.testing.assert_array_equal(data["upper"], 5.0)
    sat = data["saturated"]
    assert sat and {j for j, _, _ in sat} == {2}  # only axis 3 saturates
    # the shaded intervals cover exactly the saturated nodes
    t = r.times
    covered = np.zeros(300, bool)
    for _, a, b in sat:
        covered[(t[:-1] >= a) & (t[:-1] < b)] = True
    np.testing.assert_array_equal(covered, r.active_set[:, 2] != 0)


# ------------------------------------------------------------------ URDF effort limits
def test_effort_limits_from_the_urdf():
    from geoddp.problem.limits import effort_limits

    p = scenes.space_manipulator()  # three arm joints with effort="50" on a free-flying base
    lo, hi = effort_limits(p.model.pin_model.effortLimit, p.model.actuation)
    np.testing.assert_array_equal(hi, [50.0, 50.0, 50.0])
    np.testing.assert_array_equal(lo, -hi)
    # no effort given (a free flyer's DBL_MAX, or 0): unbounded
    lo, hi = effort_limits(np.array([1.79e308, 0.0, 7.5]), np.eye(3))
    np.testing.assert_array_equal(hi, [np.inf, np.inf, 7.5])
    # thrusters are not joint motors
    q = scenes.quadrotor()
    with pytest.raises(InputError) as e:
        effort_limits(q.model.pin_model.effortLimit, q.model.actuation)
    assert e.value.parameter == "[limits].effort_limits" and "input 0" in str(e.value)


def test_inactive_limits_bit_for_bit_on_a_multibody_model(monkeypatch):
    """The same on the quadrotor (compiled multibody rollout with its clamp, C++ passes): thrust
    bounds of +-1e5 N that no iterate or full step reaches (the first full Newton step from hover
    asks for more than 1000 N; the line search cuts it)."""
    q = scenes.quadrotor(integrator="semi_implicit")
    U0 = scenes.hover_controls(q)
    r0 = solve(q, opts(), initial_controls=U0)
    calls = _count_box_passes(monkeypatch)
    r1 = solve(q.with_limits((-1e5, 1e5)), opts(), initial_controls=U0)
    assert not calls
    assert r1.cost == r0.cost and r1.iterations == r0.iterations
    np.testing.assert_array_equal(r1.control_history, r0.control_history)
    for key in ("cost_history", "grad_norm_history", "reg_history", "step_history"):
        np.testing.assert_array_equal(getattr(r1, key), getattr(r0, key))
