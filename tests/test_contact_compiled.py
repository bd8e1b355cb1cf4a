"""The compiled legged backend (geoddp._core.ContactKernel, cpp/dynamics/contact.hpp) against the
Python node models it twins (geoddp.models.contact.ContactDynamics, geoddp.problem.legged.ContactProblem).

On ANYmal's walk and trot (example-robot-data) at random states and controls around the
quasi-static start: every node (contact nodes with and without swing feet and CoM targets, impulse
nodes, the terminal node) evaluated by both, next state, forces, cost, gradient and Gauss-Newton
Hessian, Fz and Lz, to 1e-12 relative to each array's largest entry (1 when that is smaller); the
friction-cone barrier active at some of them.
"""
import numpy as np
import pinocchio as pin
import pytest

from geoddp.models.contact_compiled import build_kernel
from geoddp.scene.legged import anymal_gait, load_anymal

TOL = 1e-12


@pytest.fixture(scope="module")
def gaits():
    robot = load_anymal()
    return {g: anymal_gait(g, robot) for g in ("walk", "trot")}


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
                        pairs += [("Fz", out["Fz"], ev.Fz), ("Lz", out["Lz"], ev.Lz)]
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
