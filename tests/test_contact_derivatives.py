"""Derivatives of the contact and impulse nodes (geoddp.models.contact, geoddp.problem.legged).

On ANYmal's walk and trot (example-robot-data) at random states and controls: the analytic
Jacobians of the node map zeta+ = difference(x_bar+, f(x_bar (+) zeta, u_bar + du)) (Pinocchio's
RNEA and frame derivatives through the KKT system), of the contact forces and of the node cost
against central differences; the exact second-order terms (the KKT system differentiated twice,
the costs' curvature) against the differences of those Jacobians (tests/oracle_legged.py, all
entries, 1e-7 relative), the forces' and accelerations' second derivatives likewise, and by the
one-step prediction test: the error of the second-order expansion falls 8x per halving of the step,
the first-order one's 4x.
"""
import numpy as np
import pinocchio as pin
import pytest

from oracle_legged import fd_second_order_node

from geoddp.problem.contract import Trajectory
from geoddp.scene.legged import anymal_gait, load_anymal


@pytest.fixture(scope="module")
def gaits():
    robot = load_anymal()
    return {g: anymal_gait(g, robot) for g in ("walk", "trot")}


@pytest.fixture(scope="module")
def walk(gaits):
    return gaits["walk"]


def nodes_of(problem):
    """One single-support contact node with a swing foot and CoM target, one four-foot node, one impulse."""
    kinds = [n.kind for n in problem.nodes]
    swing = next(k for k, n in enumerate(problem.nodes) if n.kind == "contact" and n.swing)
    return [swing, 0, kinds.index("impulse")]


def nominal(problem, k, rng):
    """A one-node trajectory slice at a random state: (q, v) near the posture, u random, the next
    state its image."""
    m = problem.model
    q = pin.integrate(m, problem.q0, 0.05 * rng.standard_normal(m.nv))
    v = 0.3 * rng.standard_normal(m.nv)
    u = np.zeros(problem.nu) if problem.impulse_rows[k] else problem.dyn.quasi_static(q, problem.nodes[k].feet) \
        + 2.0 * rng.standard_normal(problem.nu)
    ev = problem.node(k, q, v, u)[0]
    Q, V, U = np.zeros((problem.horizon + 1, m.nq)), np.zeros((problem.horizon + 1, m.nv)), np.zeros((problem.horizon, problem.nu))
    Q[:], V[:] = problem.q0, 0.0
    Q[k], V[k], U[k], Q[k + 1], V[k + 1] = q, v, u, ev.q_next, ev.v_next
    return Trajectory(Q, V, U)


def node_value(problem, k, traj, z):
    """(zeta+ (nx,), forces, cost) of node k at z = (zeta, du) around the nominal."""
    m, nv = problem.model, problem.model.nv
    q = pin.integrate(m, traj.q[k], z[:nv])
    v = traj.v[k] + z[nv:2 * nv]
    u = traj.u[k] + z[2 * nv:]
    ev, cost, *_ = problem.node(k, q, v, u)
    zeta = np.concatenate([pin.difference(m, traj.q[k + 1], ev.q_next), ev.v_next - traj.v[k + 1]])
    return zeta, ev.forces, cost


@pytest.mark.parametrize("which", [0, 1, 2])
def test_first_derivatives_against_differences(walk, which):
    rng = np.random.default_rng(3 + which)
    k = nodes_of(walk)[which]
    traj = nominal(walk, k, rng)
    ev, _, g, _ = walk.node(k, traj.q[k], traj.v[k], traj.u[k], derivatives=True)
    nz = walk.nx + walk.nu
    h = 1e-6
    Fd, Ld, gd = np.zeros((walk.nx, nz)), np.zeros((len(ev.forces), nz)), np.zeros(nz)
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = h
        zp, fp, cp = node_value(walk, k, traj, e)
        zm, fm, cm = node_value(walk, k, traj, -e)
        Fd[:, j], Ld[:, j], gd[j] = (zp - zm) / (2 * h), (fp - fm) / (2 * h), (cp - cm) / (2 * h)
    if walk.impulse_rows[k]:
        assert np.all(ev.Fz[:, walk.nx:] == 0.0) and np.all(Fd[:, walk.nx:] == 0.0)
    for name, a, b in (("Fz", ev.Fz, Fd), ("forces", ev.Lz, Ld), ("cost gradient", g, gd)):
        err = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1.0)
        assert err < 1e-6, (name, err)


def chart_jacobians(problem, k, traj, z):
    """(acceleration or v+ Jacobian, world-force Jacobian) of node k at z = (zeta, du), in the chart
    of the nominal (the q columns through dIntegrate), so that their differences are Hessians."""
    m, nv = problem.model, problem.model.nv
    q = pin.integrate(m, traj.q[k], z[:nv])
    node = problem.nodes[k]
    if node.kind == "impulse":
        ev = problem.dyn.impulse(q, traj.v[k] + z[nv:2 * nv], node.feet, True)
    else:
        ev = problem.dyn.contact(q, traj.v[k] + z[nv:2 * nv], traj.u[k] + z[2 * nv:], node.feet, True)
    Rq = pin.dIntegrate(m, traj.q[k], z[:nv], pin.ArgumentPosition.ARG1)
    A, L = ev.Az.copy(), ev.Lz.copy()
    A[:, :nv], L[:, :nv] = A[:, :nv] @ Rq, L[:, :nv] @ Rq
    return A, L


@pytest.mark.parametrize("gait", ["walk", "trot"])
@pytest.mark.parametrize("which", [0, 1, 2])
def test_kkt_second_derivatives_against_differences(gaits, gait, which):
    """The accelerations' (v+'s at an impulse) and the world forces' exact second derivatives
    against central differences of their analytic Jacobians, every entry (1e-7 of the largest)."""
    problem = gaits[gait]
    rng = np.random.default_rng(21 + which)
    k = nodes_of(problem)[which]
    traj = nominal(problem, k, rng)
    q, v, u, node = traj.q[k], traj.v[k], traj.u[k], problem.nodes[k]
    if node.kind == "impulse":
        Y2, L2 = problem.dyn.impulse_second(q, v, node.feet, problem.dyn.impulse(q, v, node.feet, True))
    else:
        Y2, L2 = problem.dyn.contact_second(q, v, u, node.feet, problem.dyn.contact(q, v, u, node.feet, True))
    nz = problem.nx + problem.nu
    h = 1e-5
    DY, DL = np.zeros_like(Y2), np.zeros_like(L2)
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = h
        (Yp, Lp), (Ym, Lm) = chart_jacobians(problem, k, traj, e), chart_jacobians(problem, k, traj, -e)
        DY[:, :, j], DL[:, :, j] = (Yp - Ym) / (2 * h), (Lp - Lm) / (2 * h)
    for name, a, b in (("accelerations", Y2, DY), ("forces", L2, DL)):
        b = 0.5 * (b + b.transpose(0, 2, 1))
        err = np.max(np.abs(a - b)) / np.max(np.abs(b))
        assert err < 1e-7, (name, err)
        assert np.max(np.abs(a - a.transpose(0, 2, 1))) <= 1e-9 * np.max(np.abs(a))


def test_kkt_second_derivatives_with_a_position_gain():
    """The Baumgarte position term (Kp = 30 1/s^2, zero in Crocoddyl's gaits) in the exact second
    derivatives, against differences as above."""
    problem = anymal_gait("walk", load_anymal())
    problem.dyn.gains = (30.0, 50.0)
    k = nodes_of(problem)[0]
    traj = nominal(problem, k, np.random.default_rng(5))
    q, v, u, node = traj.q[k], traj.v[k], traj.u[k], problem.nodes[k]
    Y2, _ = problem.dyn.contact_second(q, v, u, node.feet, problem.dyn.contact(q, v, u, node.feet, True))
    nz, h = problem.nx + problem.nu, 1e-5
    DY = np.zeros_like(Y2)
    for j in range(nz):
        e = np.zeros(nz)
        e[j] = h
        DY[:, :, j] = (chart_jacobians(problem, k, traj, e)[0] - chart_jacobians(problem, k, traj, -e)[0]) / (2 * h)
    DY = 0.5 * (DY + DY.transpose(0, 2, 1))
    assert np.max(np.abs(Y2 - DY)) / np.max(np.abs(DY)) < 1e-7


@pytest.mark.parametrize("gait", ["walk", "trot"])
@pytest.mark.parametrize("which", [0, 1, 2, 3])
def test_second_order_terms_against_the_differences(gaits, gait, which):
    """The node's exact T and cost Hessian against tests/oracle_legged.py's differences of the
    whole node map's analytic Jacobian and cost gradient, every entry (which = 3: the terminal
    node's Hessian)."""
    problem = gaits[gait]
    rng = np.random.default_rng(31 + which)
    k = nodes_of(problem)[which] if which < 3 else problem.horizon
    traj = nominal(problem, min(k, problem.horizon - 1), rng)
    T, Hc = problem.second_order_node(k, traj)
    Tf, Hf = fd_second_order_node(problem, k, traj)
    if k < problem.horizon:
        err = np.max(np.abs(T - Tf)) / np.max(np.abs(Tf))
        assert err < 1e-7, err
    err = np.max(np.abs(Hc - Hf)) / np.max(np.abs(Hf))
    assert err < 1e-7, err


@pytest.mark.parametrize("gait", ["walk", "trot"])
@pytest.mark.parametrize("which", [0, 1, 2])
def test_second_order_terms(gaits, gait, which):
    """T against a directional difference of the analytic Jacobian (1e-7), and the halving test."""
    walk = gaits[gait]
    rng = np.random.default_rng(11 + which)
    k = nodes_of(walk)[which]
    traj = nominal(walk, k, rng)
    T, Hc = walk.second_order_node(k, traj)
    nz = walk.nx + walk.nu
    d = rng.standard_normal(nz)
    if walk.impulse_rows[k]:
        d[walk.nx:] = 0.0
    h = 1e-6
    Gp, gp = walk._node_map(k, traj, h * d)
    Gm, gm = walk._node_map(k, traj, -h * d)
    dG = (Gp - Gm) / (2 * h)
    err = np.max(np.abs(np.einsum("ijk,k->ij", T, d) - dG)) / np.max(np.abs(dG))
    assert err < 1e-7, err
    err = np.max(np.abs(Hc @ d - (gp - gm) / (2 * h))) / np.max(np.abs(Hc @ d))
    assert err < 1e-7, err
    # one-step prediction: errors of the first- and second-order expansions along d
    G0, g0 = walk._node_map(k, traj, np.zeros(nz))
    _, _, c0 = node_value(walk, k, traj, np.zeros(nz))
    steps = [5e-3 / 2**i for i in range(3)]
    e1, e2, ec = [], [], []
    for s in steps:
        zeta, _, c = node_value(walk, k, traj, s * d)
        lin = G0 @ (s * d)
        quad = lin + 0.5 * s * s * np.einsum("ijk,j,k->i", T, d, d)
        e1.append(np.linalg.norm(zeta - lin))
        e2.append(np.linalg.norm(zeta - quad))
        ec.append(abs(c - (c0 + s * g0 @ d + 0.5 * s * s * d @ Hc @ d)))
    r1 = np.array(e1[:-1]) / np.array(e1[1:])
    r2 = np.array(e2[:-1]) / np.array(e2[1:])
    rc = np.array(ec[:-1]) / np.array(ec[1:])
    assert np.all(np.abs(r1 - 4) < 0.5), r1
    assert np.all(np.abs(r2 - 8) < 1.0), r2
    assert np.all(np.abs(rc - 8) < 1.0), rc


def test_second_order_model_predicts_the_trajectory_cost():
    """The whole trot from its quasi-static start: J(U + s dU) against J + s J' + s^2/2 J'' with J',
    J'' propagated through the linearisation (zeta to second order: Phi, B, Theta, Gamma, Xi; costs
    to second order): the error falls 8x per halving of s (4x without J'')."""
    problem = anymal_gait("trot", load_anymal())
    U = problem.quasi_static_controls()
    traj = problem.trajectory(U)
    lin = problem.linearise(traj, 2)
    Theta, Gamma, Xi = lin.tensors()  # factored in the compiled kernel: formed here
    nx, nu = problem.nx, problem.nu
    dU = np.random.default_rng(0).standard_normal((problem.horizon, nu))
    dU[problem.impulse_rows] = 0.0
    d1, d2, J1, J2 = np.zeros(nx), np.zeros(nx), 0.0, 0.0
    for k in range(problem.horizon):
        z1, z2 = np.concatenate([d1, dU[k]]), np.concatenate([d2, np.zeros(nu)])
        g = np.concatenate([lin.l_x[k], lin.l_u[k]])
        Hl = np.block([[lin.l_xx[k], lin.l_ux[k].T], [lin.l_ux[k], lin.l_uu[k]]])
        J1 += g @ z1
        J2 += g @ z2 + z1 @ Hl @ z1
        T = np.zeros((nx, nx + nu, nx + nu))
        T[:, :nx, :nx], T[:, :nx, nx:], T[:, nx:, :nx] = Theta[k], Gamma[k], Gamma[k].transpose(0, 2, 1)
        T[:, nx:, nx:] = Xi[k]
        d1, d2 = lin.Phi[k] @ d1 + lin.B[k] @ dU[k], lin.Phi[k] @ d2 + np.einsum("ijk,j,k->i", T, z1, z1)
    J1 += lin.lf_x @ d1
    J2 += lin.lf_x @ d2 + d1 @ lin.lf_xx @ d1
    J0 = problem.trajectory_cost(traj)
    e1, e2 = [], []
    for s in [2.5e-3 / 2**i for i in range(4)]:
        J = problem.trajectory_cost(problem.trajectory(U + s * dU))
        e1.append(abs(J - J0 - s * J1))
        e2.append(abs(J - J0 - s * J1 - 0.5 * s * s * J2))
    r1, r2 = np.array(e1[:-1]) / np.array(e1[1:]), np.array(e2[:-1]) / np.array(e2[1:])
    assert np.all(np.abs(r1 - 4) < 0.2), r1
    assert np.all(np.abs(r2 - 8) < 0.4), r2
