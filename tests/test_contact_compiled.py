"""The compiled legged backend (geoddp._core.ContactKernel, cpp/dynamics/contact.hpp) against the
Python node models it twins (geoddp.models.contact.ContactDynamics, geoddp.problem.legged.ContactProblem).

On ANYmal's walk and trot (example-robot-data) at random states and controls around the
quasi-static start: every node (contact nodes with and without swing feet and CoM targets, impulse
nodes, the terminal node) evaluated by both, next state, forces, cost, gradient and Gauss-Newton
Hessian, Fz and Lz, to 1e-12 relative to each array's largest entry (1 when that is smaller); the
friction-cone barrier active at some of them. Along whole trajectories: the kernel's rollout,
node costs, first-order expansion and node-parallel evaluation; the problem's own (``backend``
"compiled", the default, against "python", the reference): open-loop and closed-loop rollouts,
node and trajectory costs, the first- and second-order expansions, and whole first-order and
switch solves.
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models.contact_compiled import build_kernel
from geoddp.problem.contract import Trajectory
from geoddp.scene.legged import anymal_gait, load_anymal
from geoddp.solver import SolverOptions, solve

TOL = 1e-12


@pytest.fixture(scope="module")
def gaits():
    robot = load_anymal()
    return {g: anymal_gait(g, robot) for g in ("walk", "trot")}


def python_twin(problem):
    """The same problem object forced to the Python node models (restored by the caller)."""
    problem.backend = "python"
    return problem


def close(a, b, tol=TOL):
    """|a - b| <= tol max(1, max |b|), entrywise; the worst relative error for the message."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, (a.shape, b.shape)
    scale = max(1.0, float(np.max(np.abs(b)))) if b.size else 1.0
    err = float(np.max(np.abs(a - b))) / scale if b.size else 0.0
    return err <= tol, err


def random_point(problem, k, rng):
    """(q, v, u) near the posture, velocities random, controls quasi-static plus noise (zero at
    impulse nodes and the terminal node)."""
    m = problem.model
    q = pin.integrate(m, problem.q0, 0.05 * rng.standard_normal(m.nv))
    v = 0.3 * rng.standard_normal(m.nv)
    if k == problem.horizon or problem.impulse_rows[k]:
        u = np.zeros(problem.nu)
    else:
        u = problem.dyn.quasi_static(q, problem.nodes[k].feet) + 5.0 * rng.standard_normal(problem.nu)
    return q, v, u


def node_indices(problem):
    """Every impulse node, the terminal node, and contact nodes of each kind (four feet, swing
    feet with a CoM target, the first after each impulse)."""
    H = problem.horizon
    ks = {0, 1, H}
    for k, n in enumerate(problem.nodes):
        if n.kind == "impulse":
            ks.update({k, min(k + 1, H)})
        elif n.swing:
            ks.add(k)
    return sorted(ks)[:24]


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_nodes_agree(gaits, gait):
    problem = gaits[gait]
    kernel = build_kernel(problem)
    rng = np.random.default_rng(11 if gait == "walk" else 12)
    worst, cone_active = {}, 0
    for k in node_indices(problem):
        for _ in range(2):
            q, v, u = random_point(problem, k, rng)
            for derivatives in (False, True):
                ev, cost, g, Hs = problem.node(k, q, v, u, derivatives=derivatives)
                out = kernel.node(k, q, v, u, derivatives)
                pairs = [("cost", out["cost"], cost)]
                if ev is not None:
                    pairs += [("q_next", out["q_next"], ev.q_next), ("v_next", out["v_next"], ev.v_next),
                              ("forces", out["forces"], ev.forces)]
                if derivatives:
                    pairs += [("g", out["g"], g), ("Hs", out["Hs"], Hs)]
                    if ev is not None:
                        pairs += [("Fz", out["Fz"], ev.Fz), ("Lz", out["Lz"], ev.Lz),
                                  ("Az", out["Az"], ev.Az)]
                for name, a, b in pairs:
                    ok, err = close(a, b)
                    worst[name] = max(worst.get(name, 0.0), err)
                    assert ok, (gait, k, name, derivatives, err)
                if ev is not None and len(ev.forces):
                    A, lb, ub = problem.cone
                    r = ev.forces.reshape(-1, 3) @ A.T
                    cone_active += int(np.any((r < lb) | (r > ub)))
    assert cone_active > 0  # the barrier's derivatives were compared where they are nonzero
    assert max(worst.values()) <= TOL, worst


# control noise (N m) of the whole-trajectory tests: the walk's open loop is unstable and amplifies it,
# and the round-off with it (at 0.1 some seeds' states part by 1e-10 after 108 steps, as they would
# between two BLAS builds, and some rollouts diverge); the trot's much less
NOISE = {"walk": 0.01, "trot": 1.0}


def perturbed_controls(problem, rng, scale):
    U = problem.quasi_static_controls()
    U += scale * rng.standard_normal(U.shape)
    U[problem.impulse_rows] = 0.0
    return U


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_kernel_trajectory_agrees(gaits, gait):
    """The kernel's rollout, node costs and first-order expansion against the Python problem's."""
    problem = gaits[gait]
    kernel = build_kernel(problem)
    rng = np.random.default_rng(41 if gait == "walk" else 42)
    U = perturbed_controls(problem, rng, NOISE[gait])
    traj = problem.trajectory(U)
    Q, V, costs = kernel.rollout(U)
    assert close(Q, traj.q, 1e-11)[0] and close(V, traj.v, 1e-11)[0]  # 108 steps: the round-off compounds a little
    costs_p = problem.node_costs(traj)
    assert np.allclose(kernel.costs(traj.q, traj.v, traj.u, 1), costs_p, rtol=TOL, atol=0.0)
    assert float(kernel.costs(traj.q, traj.v, traj.u, 2).sum()) == pytest.approx(problem.trajectory_cost(traj), rel=TOL)
    lin = problem.linearise(traj, 1)
    out = dict(zip(("Phi", "B", "l_x", "l_u", "l_xx", "l_ux", "l_uu", "lf_x", "lf_xx", "costs"),
                   kernel.linearise(traj.q, traj.v, traj.u, 2)))
    assert np.allclose(out["costs"], costs_p, rtol=TOL, atol=0.0)
    for name in ("Phi", "B", "l_x", "l_u", "l_xx", "l_ux", "l_uu"):
        for k in range(problem.horizon):
            ok, err = close(out[name][k], getattr(lin, name)[k])
            assert ok, (gait, name, k, err)
    for name in ("lf_x", "lf_xx"):
        ok, err = close(out[name], getattr(lin, name))
        assert ok, (gait, name, err)


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_trajectory_agrees(gaits, gait):
    problem = gaits[gait]
    rng = np.random.default_rng(21 if gait == "walk" else 22)
    U = perturbed_controls(problem, rng, NOISE[gait])
    traj_c = problem.trajectory(U)
    costs_c = problem.node_costs(traj_c)
    Jc = problem.trajectory_cost(traj_c)
    lin_c = problem.linearise(traj_c, 1)
    try:
        python_twin(problem)
        traj_p = problem.trajectory(U)
        for a, b in ((traj_c.q, traj_p.q), (traj_c.v, traj_p.v), (traj_c.u, traj_p.u)):
            assert close(a, b, 1e-11)[0], close(a, b)[1]  # 108 steps: the round-off compounds a little
        # along the same trajectory: node costs, trajectory cost, the first-order expansion
        costs_p = problem.node_costs(traj_c)
        Jp = problem.trajectory_cost(traj_c)
        lin_p = problem.linearise(traj_c, 1)
    finally:
        problem.backend = "compiled"
    assert np.allclose(costs_c, costs_p, rtol=TOL, atol=0.0), np.max(np.abs(costs_c / costs_p - 1))
    assert Jc == pytest.approx(Jp, rel=TOL)
    for name in ("Phi", "B", "l_x", "l_u", "l_xx", "l_ux", "l_uu", "lf_x", "lf_xx"):
        a, b = getattr(lin_c, name), getattr(lin_p, name)
        per_node = a.ndim > 1 and name not in ("lf_xx",)
        for k in range(a.shape[0]) if per_node else [None]:
            ak, bk = (a[k], b[k]) if k is not None else (a, b)
            ok, err = close(ak, bk)
            assert ok, (gait, name, k, err)
    assert lin_c.order == lin_p.order == 1 and lin_c.gauss_newton and lin_p.gauss_newton


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_closed_loop_rollout_agrees(gaits, gait):
    problem = gaits[gait]
    rng = np.random.default_rng(31 if gait == "walk" else 32)
    nominal = problem.trajectory(perturbed_controls(problem, rng, NOISE[gait]))
    H, nu, nx = problem.horizon, problem.nu, problem.nx
    k = NOISE[gait] * rng.standard_normal((H, nu))
    K = 0.1 * rng.standard_normal((H, nu, nx))
    trial_c = problem.rollout_policy(nominal, k, K, 0.5)
    Jc = problem.trajectory_cost(trial_c)
    try:
        python_twin(problem)
        trial_p = problem.rollout_policy(nominal, k, K, 0.5)
        Jp = problem.trajectory_cost(trial_p)
    finally:
        problem.backend = "compiled"
    for a, b in ((trial_c.q, trial_p.q), (trial_c.v, trial_p.v), (trial_c.u, trial_p.u)):
        assert close(a, b, 1e-11)[0], close(a, b)[1]
    assert np.all(trial_c.u[problem.impulse_rows] == 0.0)
    assert Jc == pytest.approx(Jp, rel=1e-11)


def test_diverging_rollout_returns_none(gaits):
    problem = gaits["trot"]
    nominal = problem.trajectory(problem.quasi_static_controls())
    H, nu, nx = problem.horizon, problem.nu, problem.nx
    k = np.full((H, nu), -1e300)
    assert problem.rollout_policy(nominal, k, np.zeros((H, nu, nx)), 1.0) is None
    assert problem.trajectory_cost(Trajectory(np.full_like(nominal.q, np.nan), nominal.v, nominal.u)) == np.inf


def test_cost_cache_follows_the_values(gaits):
    """The node costs a rollout computed are reused only for the very same arrays' values."""
    problem = gaits["trot"]
    traj = problem.trajectory(problem.quasi_static_controls())
    J = problem.trajectory_cost(traj)
    traj.v[5, 0] += 0.5  # changed in place: the remembered costs no longer apply
    J2 = problem.trajectory_cost(traj)
    assert J2 != J
    try:
        python_twin(problem)
        assert J2 == pytest.approx(problem.trajectory_cost(traj), rel=TOL)
    finally:
        problem.backend = "compiled"


def test_backend_is_checked(gaits):
    from geoddp.problem.legged import ContactProblem
    from geoddp.validate import InputError

    p = gaits["trot"]
    with pytest.raises(InputError, match="backend"):
        ContactProblem(p.dyn, p.nodes, p.terminal_node, p.q0, p.v0, (p.q_ref, p.v_ref), backend="fortran")


@pytest.mark.parametrize("expansion", ["first", "switch"])
def test_solve_is_the_same(gaits, expansion):
    """The trot solved with the compiled backend and with the Python node models: the same J* to
    1e-10 relative, both converged. The iterations may differ by one: the stopping test sits at a
    round-off-sensitive border, and the two second-order expansions agree to 1e-10, not bitwise
    (switch: compiled 9, Python 8). First order (compiled rollouts and expansion) also gives the
    same controls to round-off."""
    problem = gaits["trot"]
    res_c = solve(problem, SolverOptions(expansion=expansion))
    try:
        python_twin(problem)
        res_p = solve(problem, SolverOptions(expansion=expansion))
    finally:
        problem.backend = "compiled"
    assert abs(res_c.iterations - res_p.iterations) <= 1
    assert res_c.converged and res_p.converged
    assert res_c.cost == pytest.approx(res_p.cost, rel=1e-10)
    if expansion == "first":
        assert np.max(np.abs(res_c.controls - res_p.controls)) <= 1e-6 * np.max(np.abs(res_p.controls))


def test_copies_rebuild_the_kernel(gaits):
    """deepcopy / pickle (a sweep's workers) leave the compiled kernel behind; the copy builds its own."""
    import copy
    import pickle

    problem = gaits["trot"]
    U = problem.quasi_static_controls()
    J = problem.trajectory_cost(problem.trajectory(U))
    for other in (copy.deepcopy(problem), pickle.loads(pickle.dumps(problem))):
        assert other._core is None
        assert other.trajectory_cost(other.trajectory(U)) == pytest.approx(J, rel=TOL)


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_evaluate_agrees(gaits, gait):
    """The kernel's node-parallel evaluation (the second order's input) against the Python nodes."""
    problem = gaits[gait]
    rng = np.random.default_rng(51 if gait == "walk" else 52)
    traj = problem.trajectory(perturbed_controls(problem, rng, NOISE[gait]))
    out = problem.kernel().evaluate(traj.q, traj.v, traj.u, 2)
    assert len(out) == problem.horizon + 1
    for k, o in enumerate(out):
        ev, cost, g, Hs = problem.node(k, traj.q[k], traj.v[k], traj.u[k] if k < problem.horizon else None, True)
        assert o["cost"] == pytest.approx(cost, rel=TOL, abs=1e-300)
        pairs = [("g", o["g"], g), ("Hs", o["Hs"], Hs)]
        if ev is not None:
            pairs += [(f, o[f], getattr(ev, f)) for f in ("q_next", "v_next", "forces", "Fz", "Lz", "Az")]
            assert (o["acc"] is None) == (ev.acc is None)
            if ev.acc is not None:  # the KKT solve's round-off, before dt scales it into v+ (1e-12 above)
                ok, err = close(o["acc"], ev.acc, 1e-11)
                assert ok, (gait, k, "acc", err)
        for name, a, b in pairs:
            ok, err = close(a, b)
            assert ok, (gait, k, name, err)


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_second_order_nodes_agree(gaits, gait):
    """The kernel's exact second order of single nodes (node_second: the KKT system differentiated
    twice, the exact cost Hessian) against the Python node models' (contact_second /
    impulse_second, _cost_hessian) at random points, the friction-cone barrier active at some."""
    problem = gaits[gait]
    kernel = build_kernel(problem)
    rng = np.random.default_rng(71 if gait == "walk" else 72)
    H, worst = problem.horizon, {"Y": 0.0, "Hs": 0.0}
    for k in node_indices(problem):
        q, v, u = random_point(problem, k, rng)
        Y, Hs = kernel.node_second(k, q, v, u)
        if k == H:
            Hp = problem._cost_hessian(k, q, v, u, None, None)
            assert Y.shape[0] == 0
        else:
            node = problem.nodes[k]
            if node.kind == "impulse":
                ev = problem.dyn.impulse(q, v, node.feet, derivatives=True)
                A2, L2 = problem.dyn.impulse_second(q, v, node.feet, ev)
            else:
                ev = problem.dyn.contact(q, v, u, node.feet, derivatives=True)
                A2, L2 = problem.dyn.contact_second(q, v, u, node.feet, ev)
            Hp = problem._cost_hessian(k, q, v, u, ev, L2)
            ok, err = close(Y, np.concatenate([A2, L2]), 1e-10)
            worst["Y"] = max(worst["Y"], err)
            assert ok, (gait, k, "Y", err)
            assert np.max(np.abs(A2)) > 1.0  # not a vacuous comparison
        ok, err = close(Hs, Hp, 1e-10)
        worst["Hs"] = max(worst["Hs"], err)
        assert ok, (gait, k, "Hs", err)


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_second_order_expansion_agrees(gaits, gait):
    """linearise(traj, 2) in the kernel (the default) against the all-Python one, node by node."""
    problem = gaits[gait]
    rng = np.random.default_rng(61 if gait == "walk" else 62)
    traj = problem.trajectory(perturbed_controls(problem, rng, NOISE[gait]))
    try:
        assert problem.compiled and problem.compiled_second_order
        lin_c = problem.linearise(traj, 2)
        python_twin(problem)
        lin_p = problem.linearise(traj, 2)
    finally:
        problem.backend = "compiled"
    # the kernel's second order is factored (contracted in the pass): formed here for the comparison
    assert lin_c.Theta is None and lin_c.second_order is not None and lin_p.second_order is None
    dense = dict(zip(("Theta", "Gamma", "Xi"), lin_c.tensors()))
    for name in ("Phi", "B", "Theta", "Gamma", "Xi", "l_x", "l_u", "l_xx", "l_ux", "l_uu"):
        a, b = dense[name] if name in dense else getattr(lin_c, name), getattr(lin_p, name)
        for k in range(problem.horizon):
            ok, err = close(a[k], b[k], 1e-10)
            assert ok, (gait, name, k, err)
    for name in ("lf_x", "lf_xx"):
        ok, err = close(getattr(lin_c, name), getattr(lin_p, name), 1e-10)
        assert ok, (gait, name, err)
    assert np.max(np.abs(lin_p.Theta)) > 1e-3  # the second-order terms are there to compare
    assert lin_c.order == lin_p.order == 2 and not lin_c.gauss_newton


@pytest.mark.parametrize("gait", ["walk", "trot"])
def test_contracted_expansion_is_the_dense_one(gaits, gait):
    """The kernel's factored second order (linearise_contracted) against its dense one
    (linearise_second) along a perturbed trajectory: the same first-order arrays and exact cost
    Hessians, and at every node contract(k, Vx) = sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]]
    for random Vx, to 1e-12 relative; then the exact lambda = 0 backward pass on both gives the same
    gains and decrements (1e-9)."""
    from geoddp.solver.backward import Workspace, backward

    problem = gaits[gait]
    rng = np.random.default_rng(71 if gait == "walk" else 72)
    traj = problem.trajectory(perturbed_controls(problem, rng, NOISE[gait]))
    c64 = np.ascontiguousarray
    args = (c64(traj.q), c64(traj.v), c64(traj.u), 0)
    kernel = problem.kernel()
    Phi, B, Theta, Gamma, Xi, *rest_d = kernel.linearise_second(*args)
    Phi_c, B_c, *rest_c = kernel.linearise_contracted(*args)
    terms = rest_c.pop()
    for name, a, b in zip(("Phi", "B", "lx", "lu", "lxx", "lux", "luu", "lfx", "lfxx", "costs"),
                          [Phi_c, B_c, *rest_c], [Phi, B, *rest_d]):
        ok, err = close(a, b)
        assert ok, (gait, name, err)
    n, nu = problem.nx, problem.nu
    assert terms.N == problem.horizon and terms.nv == n // 2 and terms.m == nu
    worst = 0.0
    for k in range(problem.horizon):
        Vx = rng.standard_normal(n)
        S = terms.contract(k, Vx)
        G = np.zeros((n + nu, n + nu))
        G[:n, :n] = np.einsum("i,iab->ab", Vx, Theta[k])
        G[:n, n:] = np.einsum("i,iab->ab", Vx, Gamma[k])
        G[n:, :n] = G[:n, n:].T
        G[n:, n:] = np.einsum("i,iab->ab", Vx, Xi[k])
        ok, err = close(S, G)
        worst = max(worst, err)
        assert ok, (gait, k, err)
        assert np.array_equal(S, S.T)
    assert np.max(np.abs(Theta)) > 1e-3  # not a vacuous comparison
    lin_c = problem.linearise(traj, 2)
    lin_d = type(lin_c)(order=2, Phi=Phi, B=B, Theta=Theta, Gamma=Gamma, Xi=Xi, l_x=rest_d[0], l_u=rest_d[1],
                        l_xx=rest_d[2], l_ux=rest_d[3], l_uu=rest_d[4], lf_x=rest_d[5], lf_xx=rest_d[6],
                        gauss_newton=False)
    out = []
    for lin in (lin_c, lin_d):
        ws = Workspace(problem.horizon, nu, n)
        failed, d1, d2 = backward(lin, ws, 1e-6, traj.u)
        out.append((failed, d1, d2, ws.k.copy(), ws.K.copy()))
    (f_c, d1_c, d2_c, k_c, K_c), (f_d, d1_d, d2_d, k_d, K_d) = out
    assert f_c == f_d
    if f_c < 0:
        assert abs(d1_c - d1_d) <= 1e-9 * abs(d1_d) and abs(d2_c - d2_d) <= 1e-9 * abs(d2_d)
        for a, b in ((k_c, k_d), (K_c, K_d)):
            ok, err = close(a, b, 1e-9)
            assert ok, (gait, err)
