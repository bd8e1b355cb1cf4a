"""The box-constrained backward pass (issue 15): the box QP against an independent exhaustive
active-set solver, the value update with clamped inputs against finite differences of the node's
optimal cost, the gains' structure, and the routing of geoddp.solver.backward."""
import itertools

import numpy as np
import pytest

import pinocchio  # noqa: F401  (loads the libpinocchio geoddp._core links)
from geoddp import _core

RNG_SEEDS = range(40)


def exhaustive_box_qp(H, q, lo, hi):
    """min 1/2 x^T H x - q^T x over lo <= x <= hi by enumerating every face (free / lower / upper
    per input, 3^m faces): the minimiser of a strictly convex QP is the best feasible face
    minimiser. Independent of the projected Newton code (numpy solves, no iteration)."""
    m = len(q)
    best, best_x = np.inf, None
    for pattern in itertools.product((0, -1, 1), repeat=m):
        p = np.array(pattern)
        if np.any((p == -1) & ~np.isfinite(lo)) or np.any((p == 1) & ~np.isfinite(hi)):
            continue
        x = np.where(p == -1, lo, np.where(p == 1, hi, 0.0))
        f = p == 0
        if f.any():
            x[f] = np.linalg.solve(H[np.ix_(f, f)], q[f] - H[np.ix_(f, ~f)] @ x[~f])
        if np.any(x < lo - 1e-14 * (1 + np.abs(lo))) or np.any(x > hi + 1e-14 * (1 + np.abs(hi))):
            continue
        val = 0.5 * x @ H @ x - q @ x
        if val < best:
            best, best_x = val, x
    return best_x


def random_box(rng, m):
    lo = rng.normal(size=m) - rng.uniform(0.0, 1.0, m)
    hi = lo + rng.uniform(0.0, 2.0, m)
    lo[rng.uniform(size=m) < 0.15] = -np.inf
    hi[rng.uniform(size=m) < 0.15] = np.inf
    return lo, hi


@pytest.mark.parametrize("seed", RNG_SEEDS)
def test_box_qp_matches_exhaustive_active_set_search(seed):
    rng = np.random.default_rng(seed)
    m = 1 + seed % 4
    A = rng.normal(size=(m, m))
    H = A @ A.T + 0.05 * np.eye(m)
    q = 3.0 * rng.normal(size=m)
    lo, hi = random_box(rng, m)
    if seed % 5 == 0:  # an input fixed by lower == upper
        hi[0] = lo[0] = 0.3
    x0 = rng.normal(size=m)  # any warm start
    x, clamped, it = _core.testing.box_qp(H, q, lo, hi, x0)
    assert it >= 0
    ref = exhaustive_box_qp(H, q, lo, hi)
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10 * (1 + np.abs(ref).max()))
    assert np.all(x >= lo) and np.all(x <= hi)
    # the reported faces: clamped inputs sit on their bound with the gradient pushing outward
    g = H @ x - q
    assert np.all(x[clamped == -1] == lo[clamped == -1]) and np.all(g[clamped == -1] >= 0)
    assert np.all(x[clamped == 1] == hi[clamped == 1]) and np.all(g[clamped == 1] <= 0)
    free = clamped == 0
    np.testing.assert_allclose(g[free], 0.0, atol=1e-10 * (1 + np.abs(q).max()))


def test_box_qp_inside_box_is_the_newton_point_and_reports_indefinite():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(4, 4))
    H = A @ A.T + np.eye(4)
    q = rng.normal(size=4)
    x, cl, _ = _core.testing.box_qp(H, q, np.full(4, -1e6), np.full(4, 1e6), np.zeros(4))
    np.testing.assert_allclose(x, np.linalg.solve(H, q), rtol=1e-12)
    assert not cl.any()
    # indefinite H on a free set: failure is reported, not a wrong answer
    _, _, it = _core.testing.box_qp(np.diag([1.0, -1.0]), np.ones(2), np.full(2, -1.0), np.full(2, 1.0), np.zeros(2))
    assert it == -1


def node_data(rng, n=6, m=3, second=True):
    """One node (H = 1) of a random problem: its Q blocks and the arrays of the pass."""
    d = dict(
        Phi=rng.normal(size=(1, n, n)) * 0.5 + np.eye(n), B=rng.normal(size=(1, n, m)),
        lx=rng.normal(size=(1, n)), lu=rng.normal(size=(1, m)),
        lxx=np.eye(n)[None] * 0.5, lux=0.1 * rng.normal(size=(1, m, n)), luu=np.eye(m)[None] * 0.5,
        Vx=3.0 * rng.normal(size=n), Vxx=None,
    )
    A = rng.normal(size=(n, n))
    d["Vxx"] = A @ A.T + np.eye(n)
    sym = lambda X: 0.5 * (X + np.swapaxes(X, -1, -2))  # noqa: E731
    d["Theta"] = sym(0.1 * rng.normal(size=(1, n, n, n))) if second else np.zeros((0, n, n, n))
    d["Gamma"] = 0.1 * rng.normal(size=(1, n, n, m)) if second else np.zeros((0, n, n, m))
    d["Xi"] = sym(0.05 * rng.normal(size=(1, n, m, m))) if second else np.zeros((0, n, m, m))
    return d


def q_blocks(d, second):
    """Q_x, Q_u, Q_xx, Q_ux, Q_uu of the node in numpy (paper eq. Qfunctions, Remark rem:theta)."""
    P, B, Vx, Vxx = d["Phi"][0], d["B"][0], d["Vx"], d["Vxx"]
    Qx = d["lx"][0] + P.T @ Vx
    Qu = d["lu"][0] + B.T @ Vx
    Qxx = d["lxx"][0] + P.T @ Vxx @ P
    Qux = d["lux"][0] + B.T @ Vxx @ P
    Quu = d["luu"][0] + B.T @ Vxx @ B
    if second:
        Qxx = Qxx + np.einsum("i,iab->ab", Vx, d["Theta"][0])
        Qux = Qux + np.einsum("i,iac->ca", Vx, d["Gamma"][0])
        Quu = Quu + np.einsum("i,iab->ab", Vx, d["Xi"][0])
    return Qx, Qu, Qxx, Qux, Quu


def run_box(d, second, reg, u_bar, lo, hi):
    n, m = d["Phi"].shape[1], d["B"].shape[2]
    k, K, eig, act = np.zeros((1, m)), np.zeros((1, m, n)), np.zeros(1), np.zeros((1, m), np.int8)
    Vx0, Vxx0 = np.zeros(n), np.zeros((n, n))
    out = _core.backward_pass_box(d["Phi"], d["B"], d["lx"], d["lu"], d["lxx"], d["lux"], d["luu"], d["Vx"],
                                  d["Vxx"], d["Theta"], d["Gamma"], d["Xi"], second, reg, u_bar[None], lo[None],
                                  hi[None], k, K, eig, act, Vx0, Vxx0)
    return out, k[0], K[0], act[0], Vx0, Vxx0


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("second", [False, True])
def test_value_update_with_clamped_inputs_matches_finite_differences(seed, second):
    """V(zeta) = min over the box of the node's Q model: its gradient and Hessian at 0 by central
    differences (the minimiser by the exhaustive solver) against the pass's Vx, Vxx (full form).
    Crocoddyl's box update Vx = Q_x - K^T Q_u misses -Q_ux,c^T k_c and fails the same test."""
    rng = np.random.default_rng(100 + seed)
    d = node_data(rng, second=second)
    Qx, Qu, Qxx, Qux, Quu = q_blocks(d, second)
    if np.linalg.eigvalsh(Quu).min() <= 0.05:
        Quu_shift = 0.05 - np.linalg.eigvalsh(Quu).min() + 0.5
        d["luu"] = d["luu"] + Quu_shift * np.eye(Quu.shape[0])
        Qx, Qu, Qxx, Qux, Quu = q_blocks(d, second)
    m = Qu.shape[0]
    u_bar = rng.normal(size=m)
    k_free = np.linalg.solve(Quu, Qu)  # unconstrained step: u = u_bar - k
    # a box that clamps at least one input but not all: shrink around u_bar
    half = np.abs(k_free) * np.array([0.3, 3.0, 0.5])[:m]
    lo, hi = u_bar - half, u_bar + half
    out, k, K, act, Vx0, Vxx0 = run_box(d, second, 0.0, u_bar, lo, hi)
    assert out[0] == -1
    assert act.any() and not act.all()
    np.testing.assert_array_equal(K[act != 0], 0.0)  # clamped rows are zero

    def node_cost(dz):
        # min over du in [lo - u_bar, hi - u_bar] of Q(dz, du) = Qx dz + Qu du + 1/2 [dz du] Q [dz du]
        du = exhaustive_box_qp(Quu, -(Qu + Qux @ dz), lo - u_bar, hi - u_bar)
        return Qx @ dz + Qu @ du + 0.5 * dz @ Qxx @ dz + du @ Qux @ dz + 0.5 * du @ Quu @ du

    n, h = Qx.shape[0], 1e-4
    E = np.eye(n)
    g_fd = np.array([(node_cost(h * E[i]) - node_cost(-h * E[i])) / (2 * h) for i in range(n)])
    H_fd = np.array([[(node_cost(h * (E[i] + E[j])) - node_cost(h * (E[i] - E[j])) - node_cost(h * (E[j] - E[i]))
                       + node_cost(-h * (E[i] + E[j]))) / (4 * h * h) for j in range(n)] for i in range(n)])
    scale = 1 + np.abs(g_fd).max()
    np.testing.assert_allclose(Vx0, g_fd, rtol=0, atol=2e-9 * scale)
    np.testing.assert_allclose(Vxx0, H_fd, rtol=0, atol=1e-5 * (1 + np.abs(H_fd).max()))
    # the short update (reuse of the unconstrained formula) is measurably wrong here
    short = Qx - K.T @ Qu
    assert np.abs(short - g_fd).max() > 1e-3 * scale
    # the node's optimal cost at zeta = 0 is the model decrease -(d1 - d2/2)
    assert node_cost(np.zeros(n)) == pytest.approx(-(out[1] - 0.5 * out[2]), rel=1e-10, abs=1e-12)


def test_feedforward_respects_the_box_and_free_rows_are_the_face_newton_gains():
    rng = np.random.default_rng(5)
    d = node_data(rng, second=False)
    Qx, Qu, Qxx, Qux, Quu = q_blocks(d, False)
    u_bar = np.zeros(3)
    lo, hi = np.array([-0.01, -np.inf, -0.02]), np.array([0.01, np.inf, 0.02])
    reg = 0.3
    out, k, K, act, _, _ = run_box(d, False, reg, u_bar, lo, hi)
    assert out[0] == -1
    u = u_bar - k
    assert np.all(u >= lo) and np.all(u <= hi)
    ref = exhaustive_box_qp(Quu + reg * np.eye(3), Qu, u_bar - hi, u_bar - lo)
    np.testing.assert_allclose(k, ref, atol=1e-12)
    f = act == 0
    Hr = Quu + reg * np.eye(3)
    np.testing.assert_allclose(K[f], np.linalg.solve(Hr[np.ix_(f, f)], Qux[f]), rtol=1e-12, atol=1e-14)
    # u at the lower bound <=> k at its upper bound u_bar - lo
    np.testing.assert_array_equal(act == -1, u == lo)
    np.testing.assert_array_equal(act == 1, u == hi)


def test_box_pass_fails_where_quu_plus_reg_is_indefinite():
    rng = np.random.default_rng(3)
    d = node_data(rng, second=False)
    d["luu"] = -50.0 * np.eye(3)[None]
    out = run_box(d, False, 0.0, np.zeros(3), -np.ones(3), np.ones(3))[0]
    assert out[0] == 0  # the regularisation rule: the caller raises reg and restarts
    out = run_box(d, False, 1e4, np.zeros(3), -np.ones(3), np.ones(3))[0]
    assert out[0] == -1


def test_box_pass_equals_unconstrained_pass_with_infinite_bounds():
    """With -inf/inf bounds the box pass is the unconstrained recursion (to round-off: its value
    update is the full form), over many nodes, first and second order."""
    from geoddp import kernels

    rng = np.random.default_rng(11)
    H, n, m = 20, 6, 3
    for second in (False, True):
        ds = [node_data(rng, n, m, second) for _ in range(H)]
        cat = {key: np.concatenate([d[key] for d in ds]) for key in ("Phi", "B", "lx", "lu", "lxx", "lux", "luu")}
        cat["Phi"] *= 0.5
        for key in ("Theta", "Gamma", "Xi"):
            cat[key] = np.concatenate([d[key] for d in ds])
        Vx, Vxx = ds[0]["Vx"], ds[0]["Vxx"]
        e1, e2, act = np.zeros(H), np.zeros(H), np.zeros((H, m), np.int8)
        # at reg = 0 (with reg > 0 the full value update differs from the short one by design)
        k1, K1 = np.zeros((H, m)), np.zeros((H, m, n))
        k2, K2 = np.zeros((H, m)), np.zeros((H, m, n))
        f1 = kernels.backward_pass(cat["Phi"], cat["B"], cat["lx"], cat["lu"], cat["lxx"], cat["lux"],
                                   cat["luu"] + 20.0 * np.eye(m), Vx, Vxx, cat["Theta"], cat["Gamma"], cat["Xi"],
                                   second, 0.0, k1, K1, e1)
        f2 = _core.backward_pass_box(cat["Phi"], cat["B"], cat["lx"], cat["lu"], cat["lxx"], cat["lux"],
                                     cat["luu"] + 20.0 * np.eye(m), Vx, Vxx, cat["Theta"], cat["Gamma"], cat["Xi"],
                                     second, 0.0, np.zeros((H, m)), np.full((H, m), -np.inf),
                                     np.full((H, m), np.inf), k2, K2, e2, act, np.zeros(n), np.zeros((n, n)))
        assert f1[0] == f2[0] == -1
        np.testing.assert_allclose(k2, k1, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(K2, K1, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(f2[1:], f1[1:], rtol=1e-10)


def test_contracted_box_pass_equals_the_dense_one():
    """A compiled multibody model keeps its second order factored (contracted with V_x' in the
    pass): the box pass over the factors equals the box pass over the formed tensors
    (Linearisation.tensors()) on the quadrotor with thrust limits, at a point where bounds bind."""
    from geoddp.scene import builtin as scenes

    q = scenes.quadrotor(integrator="semi_implicit")
    p = q.with_limits((0.0, 4.0))
    from geoddp.solver import SolverOptions, solve

    # an iterate of the constrained solve (second order), where T_max binds
    U = solve(p, SolverOptions(verbose=False, max_iter=6, expansion="second"),
              initial_controls=np.clip(scenes.hover_controls(q), 0.0, 4.0)).controls
    traj = p.trajectory(U)
    lin = p.linearise(traj, 2)
    assert lin.second_order is not None and lin.Theta is None  # factored
    Theta, Gamma, Xi = lin.tensors()
    H, m, n = q.horizon, 4, q.nx
    lo, hi = p.control_bounds()
    def run(dense, reg, workers=1):
        k, K, e, act = np.zeros((H, m)), np.zeros((H, m, n)), np.zeros(H), np.zeros((H, m), np.int8)
        Vx0, Vxx0 = np.zeros(n), np.zeros((n, n))
        args = (lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx)
        if dense:
            f = _core.backward_pass_box(*args, Theta, Gamma, Xi, True, reg, U, lo, hi, k, K, e, act, Vx0, Vxx0)
        else:
            f = _core.backward_pass_box_contracted(*args, lin.second_order, reg, U, lo, hi, k, K, e, act, Vx0, Vxx0,
                                                   workers)
        return f, k, K, act, Vx0, Vxx0

    # the same failed node at small lambda (Q_uu indefinite there), the same gains where both factorise
    assert run(False, 0.0)[0][0] == run(True, 0.0)[0][0]
    reg = next(r for r in 10.0 ** np.arange(0, 9) if run(True, r)[0][0] < 0)
    # each node's contraction on the core's second worker (workers=2), or the faster of the two ways
    # (0): bitwise the one-worker pass, also where it fails (0.0) and on repeated calls (a race would
    # show as a difference)
    for r in (0.0, reg):
        one = run(False, r)
        for workers in (2, 2, 2, 0, 0, 0):
            two = run(False, r, workers=workers)
            assert two[0] == one[0] and all(np.array_equal(a, b) for a, b in zip(two[1:], one[1:]))
    for workers in (-1, 3):  # the same check as the unconstrained pass (bindings/checks.hpp)
        with pytest.raises(ValueError, match="workers: expected 0"):
            run(False, reg, workers=workers)
    outs = [run(False, reg)[:5], run(True, reg)[:5]]
    (f1, k1, K1, a1, v1), (f2, k2, K2, a2, v2) = outs
    assert f1[0] == f2[0] == -1
    assert a1.any()  # bounds bind
    np.testing.assert_array_equal(a1, a2)
    np.testing.assert_allclose(k1, k2, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(K1, K2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(v1, v2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(f1[1:], f2[1:], rtol=1e-9)
