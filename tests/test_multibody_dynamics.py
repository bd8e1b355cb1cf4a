"""Multibody dynamics on Q x R^nv: rollouts and expansions against Pinocchio and finite differences.

The test model (tests/data/test_all_joints.urdf) has revolute, continuous (SO(2)), prismatic and
floating (SE(3)) joints in its chain; the root is free-flyer (SE(3)), spherical (SO(3)) or fixed.
"""

import numpy as np
import pinocchio as pin
import pytest

from geoddp import lie
from geoddp.models.multibody import Multibody
from oracle_multibody import FD_STEP, OracleMultibody
from geoddp.validate import InputError
from urdfs import urdf

URDF = urdf("test_all_joints.urdf")  # test-only model (tests/data/)
ROOTS = ["free_flyer", "spherical", "fixed"]
INTEGRATORS = ["euler", "semi_implicit"]
# The paper's forward variational Euler (implicit; derivatives by implicit differentiation).
ALL_INTEGRATORS = INTEGRATORS + ["rk4", "variational"]
DT = 0.05


def _model(root="free_flyer", integrator="euler", oracle=False, **kw):
    """The compiled model, or with ``oracle`` the tests' Python one (tests/oracle_multibody.py)."""
    return (OracleMultibody if oracle else Multibody)(URDF, root=root, dt=kw.pop("dt", DT), integrator=integrator, **kw)


def _trajectory(mb, rng, H=4):
    q0 = pin.integrate(mb.pin_model, mb.neutral(), rng.normal(size=mb.nv))
    v0 = 0.5 * rng.normal(size=mb.nv)
    U = 0.5 * rng.normal(size=(H, mb.nu))
    Q, V = mb.rollout(q0, v0, U)
    return Q, V, U


def _one_step_map(mb, Q, V, U, k):
    """z = (zeta, du) -> zeta+ in (retract, local) coordinates about the nominal next state."""
    nx = mb.nx

    def f(z):
        qp, vp = mb.retract(Q[k], V[k], z[:nx])
        qn, vn = mb.step(qp, vp, U[k] + z[nx:])
        return mb.local(Q[k + 1], V[k + 1], qn, vn)

    return f


def _jacobian_fd(f, nz, h=1e-3):
    """Fourth-order central differences: truncation ~h^4, round-off ~1e-16/h."""
    cols = []
    for e in np.eye(nz):
        cols.append((-f(2 * h * e) + 8 * f(h * e) - 8 * f(-h * e) + f(-2 * h * e)) / (12 * h))
    return np.array(cols).T


def _full_hessian(e, k, n):
    nz = n + e.B.shape[2]
    T = np.zeros((n, nz, nz))
    T[:, :n, :n] = e.Theta[k]
    T[:, :n, n:] = e.Gamma[k]
    T[:, n:, :n] = np.swapaxes(e.Gamma[k], 1, 2)
    T[:, n:, n:] = e.Xi[k]
    return T


# ---------------------------------------------------------------------------- model and rollout
def test_test_model_has_every_supported_group():
    kinds = {r: [g.kind for g in _model(r).groups] for r in ROOTS}
    assert kinds["free_flyer"] == ["se3", "vector", "so2", "vector", "se3"]
    assert kinds["spherical"] == ["so3", "vector", "so2", "vector", "se3"]
    assert kinds["fixed"] == ["vector", "so2", "vector", "se3"]
    mb = _model()
    assert (mb.nq, mb.nv, mb.nx, mb.nu) == (18, 15, 30, 15)
    shorts = [mb.pin_model.joints[j].shortname() for j in range(1, mb.pin_model.njoints)]
    assert shorts == ["JointModelFreeFlyer", "JointModelRY", "JointModelRUBX", "JointModelPZ", "JointModelFreeFlyer"]


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("root", ROOTS)
def test_rollout_matches_a_plain_pinocchio_loop(root, integrator, rng):
    mb = _model(root, integrator)
    Q, V, U = _trajectory(mb, rng, H=30)
    model, data = pin.buildModelFromUrdf(str(URDF), *([] if root == "fixed" else
                                          [pin.JointModelFreeFlyer() if root == "free_flyer" else pin.JointModelSpherical()])), None
    data = model.createData()
    q, v = Q[0].copy(), V[0].copy()
    for k in range(U.shape[0]):
        a = pin.aba(model, data, q, v, U[k])  # identity actuation, default gravity
        v_next = v + DT * a
        q = pin.integrate(model, q, DT * (v_next if integrator == "semi_implicit" else v))
        v = v_next
        assert np.abs(q - Q[k + 1]).max() < 1e-12 and np.abs(v - V[k + 1]).max() < 1e-12


def test_gravity_switch_and_free_fall():
    """With v = 0 and no input, the whole tree falls freely: only the base accelerates, by g."""
    on, off = _model(gravity=True), _model(gravity=False)
    assert np.allclose(on.pin_model.gravity.linear, [0, 0, -9.81]) and np.all(off.pin_model.gravity.vector == 0)
    q = pin.integrate(on.pin_model, on.neutral(), np.r_[0.3, -0.2, 0.1, 0.4, -0.5, 0.6, np.zeros(on.nv - 6)])
    R = pin.Quaternion(q[3:7]).normalized().toRotationMatrix()
    _, v_next = on.step(q, np.zeros(on.nv), np.zeros(on.nu))
    expected = np.zeros(on.nv)
    expected[:3] = DT * R.T @ np.array([0, 0, -9.81])  # body-frame linear acceleration
    assert np.abs(v_next - expected).max() < 1e-12
    _, v_off = off.step(q, np.zeros(off.nv), np.zeros(off.nu))
    assert np.all(v_off == 0.0)


def test_retract_and_local_are_inverse(rng):
    mb = _model()
    Q, V, _ = _trajectory(mb, rng, H=1)
    zeta = 0.3 * rng.normal(size=mb.nx)
    q, v = mb.retract(Q[0], V[0], zeta)
    assert np.abs(mb.local(Q[0], V[0], q, v) - zeta).max() < 1e-12
    assert np.abs(mb.local(Q[0], V[0], q, v)[: mb.nv] - pin.difference(mb.pin_model, Q[0], q)).max() < 1e-12


def test_local_is_exact_for_tiny_so2_angles(rng):
    """pin.difference (4.1) returns 0 for some SO(2) angles below ~1e-8; local must not."""
    mb = _model("fixed")
    spin = next(g for g in mb.groups if g.kind == "so2")
    worst, pin_zeros = 0.0, 0
    for _ in range(300):
        q = pin.integrate(mb.pin_model, mb.neutral(), rng.normal(size=mb.nv))
        zeta = np.zeros(mb.nx)
        zeta[spin.idx_v] = 10 ** rng.uniform(-12, -7)
        qp, _ = mb.retract(q, np.zeros(mb.nv), zeta)
        worst = max(worst, abs(mb.local(q, np.zeros(mb.nv), qp, np.zeros(mb.nv))[spin.idx_v] - zeta[spin.idx_v]))
        pin_zeros += pin.difference(mb.pin_model, q, qp)[spin.idx_v] == 0.0
    assert worst < 1e-15, worst  # round-off of the (cos, sin) coordinates only
    assert pin_zeros > 0  # the Pinocchio behaviour this works around is still there


# ---------------------------------------------------------------------------- first order
@pytest.mark.parametrize("integrator", INTEGRATORS + ["variational"])
@pytest.mark.parametrize("root", ROOTS)
def test_phi_b_against_finite_differences(root, integrator, rng):
    mb = _model(root, integrator)
    Q, V, U = _trajectory(mb, rng)
    e = mb.expansion(Q, V, U, order=1)
    # The implicit step of this stiff test model (light links at up to 13 rad/s, dt = 0.05) has
    # fifth derivatives ~1e7: its differences need h = 1e-4, whose round-off is ~1e-8.
    h, tol = (1e-4, 5e-8) if integrator == "variational" else (1e-3, 1e-9)
    worst = 0.0
    for k in range(U.shape[0]):
        J = _jacobian_fd(_one_step_map(mb, Q, V, U, k), mb.nx + mb.nu, h=h)
        worst = max(worst, np.abs(J[:, : mb.nx] - e.Phi[k]).max(), np.abs(J[:, mb.nx :] - e.B[k]).max())
    assert worst < tol, worst


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("root", ROOTS)
def test_phi_b_against_pinocchio_derivatives(root, integrator, rng):
    """Rows of Phi, B rebuilt directly from computeABADerivatives and dIntegrate."""
    mb = _model(root, integrator)
    Q, V, U = _trajectory(mb, rng)
    e = mb.expansion(Q, V, U, order=1)
    model, data, nv = mb.pin_model, mb.pin_model.createData(), mb.nv
    for k in range(U.shape[0]):
        pin.computeABADerivatives(model, data, Q[k], V[k], U[k])
        Minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        Fq, Fv, Fu = DT * data.ddq_dq, np.eye(nv) + DT * data.ddq_dv, DT * Minv
        w = V[k + 1] if integrator == "semi_implicit" else V[k]
        Aq = pin.dIntegrate(model, Q[k], DT * w, pin.ARG0)
        Jv = pin.dIntegrate(model, Q[k], DT * w, pin.ARG1)
        if integrator == "euler":
            top = np.hstack([Aq, DT * Jv, np.zeros((nv, nv))])
        else:
            top = np.hstack([Aq + DT * Jv @ Fq, DT * Jv @ Fv, DT * Jv @ Fu])
        ref = np.vstack([top, np.hstack([Fq, Fv, Fu])])
        got = np.hstack([e.Phi[k], e.B[k]])
        assert np.abs(got - ref).max() < 1e-12
    # dIntegrate is the per-group Ad_exp(-omega), Jr(omega) of geoddp.lie.product.
    omega = rng.normal(size=nv)
    A, Jr = lie.block_Ad_Jr(mb.groups, nv, omega)
    assert np.abs(A - pin.dIntegrate(model, Q[0], omega, pin.ARG0)).max() < 1e-12
    assert np.abs(Jr - pin.dIntegrate(model, Q[0], omega, pin.ARG1)).max() < 1e-12


# ---------------------------------------------------------------------------- second order
@pytest.mark.parametrize("integrator", ALL_INTEGRATORS)
@pytest.mark.parametrize("root", ROOTS)
def test_second_order_error_falls_8x_per_halving(root, integrator, rng):
    """One-step prediction error over random nominals and directions: ~8x per halving of the
    perturbation with the second-order terms, ~4x with the first-order ones only."""
    mb = _model(root, integrator)
    n = mb.nx
    r1, r2 = [], []
    for _ in range(5):
        Q, V, U = _trajectory(mb, rng, H=3)
        e = mb.expansion(Q, V, U, order=2)
        k = 1
        f = _one_step_map(mb, Q, V, U, k)
        G = np.hstack([e.Phi[k], e.B[k]])
        T = _full_hessian(e, k, n)
        d = rng.normal(size=n + mb.nu)
        d /= np.linalg.norm(d)
        e1, e2 = [], []
        for eps in (2e-2, 1e-2, 5e-3, 2.5e-3):
            z = eps * d
            lin = G @ z
            e1.append(np.linalg.norm(f(z) - lin))
            e2.append(np.linalg.norm(f(z) - lin - 0.5 * np.einsum("iab,a,b->i", T, z, z)))
        r1.append([e1[i] / e1[i + 1] for i in range(3)])
        r2.append([e2[i] / e2[i + 1] for i in range(3)])
    r1, r2 = np.array(r1), np.array(r2)
    assert np.all((r2 > 7.0) & (r2 < 9.0)), r2
    assert np.all((r1 > 3.5) & (r1 < 4.5)), r1


def _hessian_fd(f, nz, h=2e-4):
    """Central second differences of f: truncation ~h^2, round-off ~1e-16/h^2 (both ~1e-8)."""
    f0 = f(np.zeros(nz))
    E = h * np.eye(nz)
    out = np.empty(f0.shape + (nz, nz))
    for i in range(nz):
        out[:, i, i] = (f(E[i]) - 2 * f0 + f(-E[i])) / (h * h)
        for j in range(i):
            v = (f(E[i] + E[j]) - f(E[i] - E[j]) - f(E[j] - E[i]) + f(-E[i] - E[j])) / (4 * h * h)
            out[:, i, j] = out[:, j, i] = v
    return out


@pytest.mark.parametrize("integrator", INTEGRATORS + ["variational"])
@pytest.mark.parametrize("root", ROOTS)
def test_second_order_terms_against_finite_difference_hessians(root, integrator, rng):
    """Theta, Gamma, Xi against the Hessian of the one-step map in (retract, local) coordinates:
    every entry, including the reconstruction's dJr and bracket terms (O(dt^2), O(dt))."""
    mb = _model(root, integrator)
    Q, V, U = _trajectory(mb, rng, H=2)
    e = mb.expansion(Q, V, U, order=2)
    k = 1
    ref = _hessian_fd(_one_step_map(mb, Q, V, U, k), mb.nx + mb.nu)
    err = np.abs(_full_hessian(e, k, mb.nx) - ref).max()
    assert err < 2e-6 * max(1.0, np.abs(ref).max()), err


def test_second_order_terms_are_symmetric(rng):
    mb = _model("free_flyer", "semi_implicit")
    Q, V, U = _trajectory(mb, rng)
    e = mb.expansion(Q, V, U, order=2)
    assert np.abs(e.Theta - np.swapaxes(e.Theta, 2, 3)).max() < 1e-14
    assert np.abs(e.Xi - np.swapaxes(e.Xi, 2, 3)).max() < 1e-14
    assert e.Theta.shape == (4, 30, 30, 30) and e.Gamma.shape == (4, 30, 30, 15) and e.Xi.shape == (4, 30, 15, 15)


def test_velocity_hessian_step_is_accurate(rng):
    """F2 at the default step against a Richardson extrapolation of two larger steps (where
    round-off is negligible and the h^2 truncation cancels, leaving O(h^4))."""
    mb = _model("free_flyer", "euler", oracle=True)
    Q, V, U = _trajectory(mb, rng, H=2)
    _, F2 = mb.velocity_derivatives(Q[:2], V[:2], U, order=2)
    _, Fa = mb.velocity_derivatives(Q[:2], V[:2], U, order=2, fd_step=2e-3)
    _, Fb = mb.velocity_derivatives(Q[:2], V[:2], U, order=2, fd_step=1e-3)
    rich = (4.0 * Fb - Fa) / 3.0
    scale = np.abs(rich).max()
    err = np.abs(F2 - rich).max() / scale
    assert err < 1e-8, err
    assert np.abs(Fb - rich).max() / scale > 10 * err  # the test can tell steps apart
    assert FD_STEP == 1e-5


def _velocity_hessian_all_directions(mb, Q, V, U, h=FD_STEP):
    """The former F2: central differences of the analytic ABA Jacobian along every direction
    of z = (dq, dv, du) (q through integrate), symmetrised. Structure-blind reference."""
    model, data, Hm, nv, dt = mb.pin_model, mb.pin_model.createData(), mb.actuation, mb.nv, mb.dt
    nz = 2 * nv + mb.nu

    def jac(q, v, tau):
        pin.computeABADerivatives(model, data, q, v, tau)
        Minv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        return np.hstack([dt * data.ddq_dq, np.eye(nv) + dt * data.ddq_dv, dt * Minv @ Hm])

    F2 = np.empty((len(U), nv, nz, nz))
    for k in range(len(U)):
        q, v, tau = Q[k], V[k], Hm @ U[k]
        D = np.empty((nv, nz, nz))
        for j, e in enumerate(h * np.eye(nz)):
            plus = jac(pin.integrate(model, q, e[:nv]), v + e[nv:2 * nv], tau + Hm @ e[2 * nv:])
            minus = jac(pin.integrate(model, q, -e[:nv]), v - e[nv:2 * nv], tau - Hm @ e[2 * nv:])
            D[:, :, j] = (plus - minus) / (2 * h)
        F2[k] = 0.5 * (D + np.swapaxes(D, 1, 2))
    return F2


@pytest.mark.parametrize("gravity", [True, False])
@pytest.mark.parametrize("root", ROOTS)
def test_structured_velocity_hessian_equals_differences_along_every_direction(root, gravity, rng):
    """The structured F2 (zero u-u and v-u blocks, RNEA v-v block, differences along q only,
    none along invariant root directions) against differences along all nz directions."""
    mb = _model(root, "euler", gravity=gravity, oracle=True)
    Q, V, U = _trajectory(mb, rng, H=2)
    _, F2 = mb.velocity_derivatives(Q[:2], V[:2], U, order=2)
    ref = _velocity_hessian_all_directions(mb, Q, V, U)
    assert np.abs(F2 - ref).max() < 1e-8 * np.abs(ref).max()
    nv = mb.nv
    assert np.array_equal(F2, np.swapaxes(F2, 2, 3))
    assert not np.any(F2[:, :, nv:, 2 * nv:])  # affine in tau, slope Minv(q) free of v
    expected = {"free_flyer": [0, 1, 2] + ([] if gravity else [3, 4, 5]),
                "spherical": [] if gravity else [0, 1, 2], "fixed": []}[root]
    assert mb._invariant_q_dirs().tolist() == expected
    # along the skipped directions the differences see round-off only
    assert np.abs(ref[:, :, :, expected]).max(initial=0.0) < 1e-8 * np.abs(ref).max()


# ---------------------------------------------------------------------------- integrator order
def _rkmk4_reference(mb, q0, v0, u, tf, steps):
    """Runge-Kutta-Munthe-Kaas, classical RK4 tableau on (theta, v) with q = q_n exp(theta),
    theta' = Jr(theta)^-1 v (dexpinv, exact): fourth order on the Lie group."""
    model, data = mb.pin_model, mb.pin_model.createData()
    tau = mb.actuation @ u
    h = tf / steps
    q, v = q0.copy(), v0.copy()

    def rhs(theta, vel):
        qs = pin.integrate(model, q, theta)
        Jr = pin.dIntegrate(model, q, theta, pin.ARG1)
        return np.linalg.solve(Jr, vel), pin.aba(model, data, qs, vel, tau)

    for _ in range(steps):
        th0 = np.zeros(mb.nv)
        k1 = rhs(th0, v)
        k2 = rhs(0.5 * h * k1[0], v + 0.5 * h * k1[1])
        k3 = rhs(0.5 * h * k2[0], v + 0.5 * h * k2[1])
        k4 = rhs(h * k3[0], v + h * k3[1])
        theta = h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        q = pin.integrate(model, q, theta)
    return q, v


def _ambient_rhs(mb, tau):
    """The continuous dynamics in Pinocchio's configuration coordinates, written per joint group
    (independent of integrate/dIntegrate): SE(3) p' = R v_lin, quaternions q' = 1/2 q (x) (w, 0),
    SO(2) (c, s)' = w (-s, c), vector joints q' = v; v' = aba."""
    model, data = mb.pin_model, mb.pin_model.createData()
    nq = model.nq

    def quat_rate(xyzw, w):
        qv, qw = xyzw[:3], xyzw[3]
        return 0.5 * np.concatenate([qw * w + np.cross(qv, w), [-qv @ w]])

    def rhs(_t, y):
        q, v = pin.normalize(model, y[:nq]), y[nq:]
        qd = np.empty(nq)
        for g in mb.groups:
            iq, vv = g.idx_q, v[g.slice]
            if g.kind == "se3":
                R = pin.Quaternion(q[iq + 3 : iq + 7]).toRotationMatrix()
                qd[iq : iq + 3] = R @ vv[:3]
                qd[iq + 3 : iq + 7] = quat_rate(q[iq + 3 : iq + 7], vv[3:])
            elif g.kind == "so3":
                qd[iq : iq + 4] = quat_rate(q[iq : iq + 4], vv)
            elif g.kind == "so2":
                qd[iq : iq + 2] = vv[0] * np.array([-q[iq + 1], q[iq]])
            else:
                qd[iq : iq + g.nv] = vv
        return np.concatenate([qd, pin.aba(model, data, q, v, tau)])

    return rhs


def _dop853_reference(mb, q0, v0, u, tf):
    from scipy.integrate import solve_ivp

    sol = solve_ivp(_ambient_rhs(mb, mb.actuation @ u), (0.0, tf), np.concatenate([q0, v0]),
                    method="DOP853", rtol=1e-13, atol=1e-13)
    return pin.normalize(mb.pin_model, sol.y[: mb.nq, -1]), sol.y[mb.nq :, -1]


def _order_problem(integrator="euler"):
    """A free-flyer start state and constant input (gravity on), tf = 0.5 s."""
    mb = _model("free_flyer", integrator)
    rng = np.random.default_rng(7)
    q0 = pin.integrate(mb.pin_model, mb.neutral(), 0.5 * rng.normal(size=mb.nv))
    return mb, q0, 0.5 * rng.normal(size=mb.nv), 0.5 * rng.normal(size=mb.nu), 0.5


_REFERENCE = {}


def _reference():
    """DOP853 solution of the ODE in configuration coordinates (computed once)."""
    if not _REFERENCE:
        mb, q0, v0, u, tf = _order_problem()
        _REFERENCE["x"] = _dop853_reference(mb, q0, v0, u, tf)
    return _REFERENCE["x"]


def _terminal_errors(integrator, dts):
    _, q0, v0, u, tf = _order_problem(integrator)
    q_ref, v_ref = _reference()
    errs = []
    for dt in dts:
        mb = _model("free_flyer", integrator, dt=dt)
        H = int(round(tf / dt))
        Q, V = mb.rollout(q0, v0, np.tile(u, (H, 1)))
        errs.append(np.linalg.norm(mb.local(q_ref, v_ref, Q[-1], V[-1])))
    return np.array(errs)


def test_references_agree():
    """The RKMK4 written here and DOP853 in configuration coordinates agree to < 1e-10 (measured 2e-12), far below
    the smallest integrator error measured against them."""
    mb, q0, v0, u, tf = _order_problem()
    qa, va = _rkmk4_reference(mb, q0, v0, u, tf, 1600)
    qb, vb = _reference()
    assert np.linalg.norm(mb.local(qa, va, qb, vb)) < 1e-10


@pytest.mark.parametrize("integrator", INTEGRATORS + ["variational"])
def test_euler_schemes_are_first_order(integrator):
    dts = np.array([0.01, 0.005, 0.0025, 0.00125])
    errs = _terminal_errors(integrator, dts)
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 0.9 < slope < 1.1, (slope, errs)


# ---------------------------------------------------------------------------- RKMK4
def test_rk4_step_is_the_rkmk4_written_here(rng):
    mb = _model("spherical", "rk4")
    Q, V, U = _trajectory(mb, rng, H=3)
    for k in range(3):
        q, v = _rkmk4_reference(mb, Q[k], V[k], U[k], DT, 1)
        assert np.abs(mb.local(Q[k + 1], V[k + 1], q, v)).max() < 1e-13


def test_rk4_is_fourth_order():
    dts = np.array([0.05, 0.025, 0.0125, 0.00625])
    errs = _terminal_errors("rk4", dts)
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 3.8 < slope < 4.2, (slope, errs)


@pytest.mark.parametrize("root", ROOTS)
def test_rk4_phi_b_against_finite_differences(root, rng):
    mb = _model(root, "rk4")
    Q, V, U = _trajectory(mb, rng)
    e = mb.expansion(Q, V, U, order=1)
    worst = 0.0
    for k in range(U.shape[0]):
        J = _jacobian_fd(_one_step_map(mb, Q, V, U, k), mb.nx + mb.nu)
        worst = max(worst, np.abs(J - np.hstack([e.Phi[k], e.B[k]])).max())
    # FD noise: near-identity SE(3) logs carry ~1e-12 round-off, i.e. ~1e-9 in a 1e-3 difference
    assert worst < 1e-8, worst


def test_rk4_second_order_terms_against_finite_difference_hessians(rng):
    mb = _model("free_flyer", "rk4")
    Q, V, U = _trajectory(mb, rng, H=2)
    e = mb.expansion(Q, V, U, order=2)
    ref = _hessian_fd(_one_step_map(mb, Q, V, U, 1), mb.nx + mb.nu)
    err = np.abs(_full_hessian(e, 1, mb.nx) - ref).max()
    assert err < 2e-6 * max(1.0, np.abs(ref).max()), err


@pytest.mark.parametrize(
    "kw, param",
    [
        ({"root": "floating"}, "root"),
        ({"integrator": "rk45"}, "integrator"),
        ({"dt": 0.0}, "dt"),
        ({"dt": float("nan")}, "dt"),
        ({"gravity": "yes"}, "gravity"),
        ({"second_order": "paper"}, "second_order"),
        ({"actuation": np.eye(3)}, "actuation"),
        ({"actuation": np.zeros((15, 2))}, "actuation"),
        ({"actuation": np.full((15, 2), np.inf)}, "actuation"),
    ],
)
def test_invalid_inputs_name_the_parameter(kw, param):
    with pytest.raises(InputError) as info:
        Multibody(URDF, **{"dt": DT, **kw})
    assert info.value.parameter == param


def test_dt_is_required_and_states_and_controls_are_checked(rng):
    with pytest.raises(TypeError, match="dt"):
        Multibody(URDF)
    mb = _model()
    q0, v0 = mb.neutral(), np.zeros(mb.nv)
    U = np.zeros((3, mb.nu))
    bad_q = q0.copy()
    bad_q[3:7] = [0.5, 0.0, 0.0, 0.5]  # non-unit quaternion
    for args, param in [((bad_q, v0, U), "initial.q"), ((q0[:-1], v0, U), "initial.q"),
                        ((q0, v0[:-1], U), "initial.v"), ((q0, v0, U[:, :-1]), "controls"),
                        ((q0, v0, np.full_like(U, np.nan)), "controls")]:
        with pytest.raises(InputError) as info:
            mb.rollout(*args)
        assert info.value.parameter == param
    Q, V = mb.rollout(q0, v0, U)
    for args, kw, param in [((Q[:-1], V, U), {}, "Q"), ((Q, V[:, :-1], U), {}, "V"), ((Q, V, U), {"order": 3}, "order")]:
        with pytest.raises(InputError) as info:
            mb.expansion(*args, **kw)
        assert info.value.parameter == param


def test_invalid_urdf_is_refused(tmp_path):
    with pytest.raises(InputError, match="urdf"):
        Multibody(tmp_path / "missing.urdf", dt=DT)
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    with pytest.raises(InputError, match="urdf"):
        Multibody(bad, dt=DT)
    planar = tmp_path / "planar.urdf"
    planar.write_text(
        "<robot name='p'><link name='a'/><link name='b'><inertial><mass value='1'/>"
        "<inertia ixx='1' ixy='0' ixz='0' iyy='1' iyz='0' izz='1'/></inertial></link>"
        "<joint name='pl' type='planar'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/></joint></robot>"
    )
    with pytest.raises(InputError, match="pl.*not supported"):
        Multibody(planar, root="fixed", dt=DT)
