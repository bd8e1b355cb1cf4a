"""Constraint derivatives against differences along the group: every kind's Jacobian against
central differences of its value along x exp(s e_i) (first order), and its contracted Hessian
sum_i w_i Hess c_i against differences of w^T J (the symmetric part: the (0)-Hessian), at random
states, near the identity and at a rotation angle of pi - 1e-6; on the satellite's TSO(3) backend
and on multibody models (a free-floating arm, a fixed-base arm). Then the augmented Lagrangian's
additions to l_x, l_xx against differences of its merit, and Pinocchio's kinematic Hessian as
geoddp reads it against differences of the frame Jacobian."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from geoddp.constraints import (ConstrainedProblem, FrameHalfspace, FramePlacementConstraint, FrameSphereKeepOut,
                                JointLimits, PointingKeepOut, StateConstraint)
from geoddp.constraints.augmented import merit
from geoddp.constraints.kinematics import frame_kinematic_hessian
from geoddp.problem.contract import Trajectory
from geoddp.data import urdf_path
from geoddp.models.multibody import Multibody
from geoddp.models.satellite import Satellite, satellite_model
from geoddp.problem import paper_problem

D = np.array([0.849, 0.482, 0.215])
NEAR = ("random", "identity", "pi")


def _sat() -> Satellite:
    return Satellite(inertia=np.diag([10.0, 11.1, 13.0]), actuation=np.eye(3), dt=0.01)


def _arm() -> Multibody:
    return Multibody(urdf_path("space_manipulator.urdf"), root="free_flyer", dt=0.02, gravity=False)


def _fixed_arm() -> Multibody:
    return Multibody.from_model(pin.buildSampleModelManipulator(), dt=0.01)


def _axis_angle(rng, near: str) -> np.ndarray:
    x = rng.normal(size=3)
    x /= np.linalg.norm(x)
    return x * {"random": rng.uniform(0.3, 2.8), "identity": 1e-7, "pi": np.pi - 1e-6}[near]


def _rotation(rng, near: str) -> np.ndarray:
    return pin.exp3(_axis_angle(rng, near))


def _states(model, rng, near: str, N: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """N states: rotations near the identity / pi (the satellite, or the free flyer's root)."""
    if isinstance(model, Satellite):
        return np.array([_rotation(rng, near) for _ in range(N)]), rng.normal(size=(N, 3))
    pm = model.pin_model
    # drawn from the test's own generator (pin.randomConfiguration draws from Pinocchio's global
    # one, which other tests advance: the states then depend on the order the tests run in)
    Q = np.array([pin.integrate(pm, pin.neutral(pm), rng.uniform(-1.0, 1.0, pm.nv)) for _ in range(N)])
    if pm.joints[1].shortname() == "JointModelFreeFlyer":
        for q in Q:
            q[3:7] = pin.Quaternion(_rotation(rng, near)).coeffs()
    return Q, rng.normal(size=(N, pm.nv))


def _check(bound, model, q, v, rng, h: float | list[float], tol_J: float = 1e-7, tol_H: float = 1e-6) -> None:
    """Central differences along model.retract: J against the value's, sym(d(w^T J)) against Hw;
    ``h``: the step, or one step per node."""
    N, nx = v.shape[0], bound.nx
    w = rng.normal(size=(N, bound.rows))
    c, J, Hw = bound.derivatives(q, v, w)
    assert c.shape == (N, bound.rows) and J.shape == (N, bound.rows, nx) and Hw.shape == (N, nx, nx)
    assert np.all(np.isfinite(c)) and np.all(np.isfinite(J)) and np.all(np.isfinite(Hw))
    np.testing.assert_array_equal(bound.value(q, v), c)
    np.testing.assert_allclose(Hw, np.swapaxes(Hw, 1, 2), rtol=0, atol=1e-12 * max(1.0, np.abs(Hw).max()))
    steps = np.broadcast_to(np.asarray(h, dtype=float), (N,))
    for n in range(N):
        h = steps[n]
        M = np.zeros((nx, nx))
        dc = np.zeros((bound.rows, nx))
        for i in range(nx):
            z = np.zeros(nx)
            z[i] = h
            qp, vp = model.retract(q[n], v[n], z)
            qm, vm = model.retract(q[n], v[n], -z)
            cp, Jp, _ = bound.derivatives(qp[None], vp[None], None)
            cm, Jm, _ = bound.derivatives(qm[None], vm[None], None)
            dc[:, i] = (cp[0] - cm[0]) / (2 * h)
            M[i] = (w[n] @ Jp[0] - w[n] @ Jm[0]) / (2 * h)
        scale_J = max(1.0, np.abs(J[n]).max())
        assert np.abs(dc - J[n]).max() <= tol_J * scale_J, (n, np.abs(dc - J[n]).max())
        scale_H = max(1.0, np.abs(Hw[n]).max())
        assert np.abs(0.5 * (M + M.T) - Hw[n]).max() <= tol_H * scale_H, (n, np.abs(0.5 * (M + M.T) - Hw[n]).max())


# ------------------------------------------------------------------ the satellite (TSO(3) backend)


@pytest.mark.parametrize("near", NEAR)
def test_pointing_on_tso3(near, rng):
    sat = _sat()
    q, v = _states(sat, rng, near)
    _check(PointingKeepOut([1.0, 0.2, -0.1], D, 20.0).bind(sat), sat, q, v, rng, h=1e-6)
    # the boresight itself near the direction and near its opposite (cos(angle) near 1 and -1)
    for R in (np.eye(3), pin.exp3(np.array([0.0, 0.0, np.pi - 1e-6]))):
        d = R @ np.array([1.0, 0.0, 0.0])
        _check(PointingKeepOut([1.0, 0.0, 0.0], d, 30.0).bind(sat), sat, q @ R if near == "identity" else q, v, rng,
               h=1e-6)


@pytest.mark.parametrize("near", NEAR)
def test_state_equality_on_tso3_near_the_identity_and_pi(near, rng):
    """difference(R_ref, R) = log(R_ref^T R) with R_ref^T R itself near the identity / pi."""
    sat = _sat()
    R_ref = _rotation(rng, "random")
    R = np.array([R_ref @ _rotation(rng, near) for _ in range(3)])
    v = rng.normal(size=(3, 3))
    c = StateConstraint(q=pin.Quaternion(R_ref).coeffs(), v=[0.1, -0.2, 0.3])
    # at pi - 1e-6 a step of 1e-6 would cross the cut locus of log: 1e-7 there
    _check(c.bind(sat), sat, R, v, rng, h=1e-7 if near == "pi" else 1e-6, tol_J=1e-7, tol_H=2e-6)


@pytest.mark.parametrize("near", NEAR)
def test_frame_constraints_on_the_satellite(near, rng):
    """Frame kinds on the satellite's body (q = the quaternion of R through Pinocchio)."""
    sat = _sat()
    q, v = _states(sat, rng, near)
    body = "bus"
    M_ref = pin.SE3(_rotation(rng, "random"), np.zeros(3))
    for c in (FrameSphereKeepOut(body, [0.3, -0.1, 0.2], 0.5), FrameHalfspace(body, [0.0, 1.0, 1.0], -0.3),
              FramePlacementConstraint(body, M_ref), JointLimits(velocity={"root_joint": [-0.5, 0.7]})):
        _check(c.bind(sat), sat, q, v, rng, h=1e-5)


def test_pointing_closed_form_equals_the_frame_path(rng):
    """The TSO(3) closed forms and the Pinocchio frame path are the same constraint: values,
    Jacobians and contracted Hessians of the satellite's body on both models agree."""
    sat = _sat()
    general = satellite_model(inertia=np.diag([10.0, 11.1, 13.0]), actuation=np.eye(3), dt=0.01, integrator="rk4")
    assert isinstance(general, Multibody)
    R, v = _states(sat, rng, "random", N=5)
    Q = np.array([pin.Quaternion(r).coeffs() for r in R])
    w = rng.normal(size=(5, 1))
    a = PointingKeepOut([0.3, 1.0, 0.2], D, 25.0, frame="bus").bind(sat).derivatives(R, v, w)
    b = PointingKeepOut([0.3, 1.0, 0.2], D, 25.0, frame="bus").bind(general).derivatives(Q, v, w)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-13)


# ------------------------------------------------------------------ multibody models


@pytest.mark.parametrize("near", NEAR)
def test_frame_constraints_on_a_free_floating_arm(near, rng):
    arm = _arm()
    q, v = _states(arm, rng, near)
    for c in (PointingKeepOut([1.0, 0.0, 0.0], [0.0, 0.3, 1.0], 40.0, frame="ee"),
              FrameHalfspace("forearm", [0.0, 0.0, 1.0], 0.2),
              FrameSphereKeepOut("ee", [0.4, 0.1, 0.2], 0.3)):
        _check(c.bind(arm), arm, q, v, rng, h=1e-6)


@pytest.mark.parametrize("near", NEAR)
def test_terminal_equalities_on_a_free_floating_arm(near, rng):
    """frame_placement: log6(M_ref^-1 oMf) with the relative rotation near the identity / pi;
    state: difference(q_ref, q) with the free flyer's relative rotation near the identity / pi."""
    arm = _arm()
    pm = arm.pin_model
    q, v = _states(arm, rng, "random")
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q[0])
    oMf = data.oMf[pm.getFrameId("ee")]
    twist = np.concatenate([rng.normal(size=3) * 0.3, _axis_angle(rng, near)])
    M_ref = oMf * pin.exp6(twist).inverse()  # M_ref^-1 oMf = exp6(twist) at node 0
    # Node 0's relative rotation is near the identity / pi, nodes 1 and 2 random. Near pi, log6's
    # round-off grows as 1/(h (pi - angle)): node 0 "pi" (pi - 1e-6) needs h = 1e-7 (its Taylor
    # error at 1e-4, 1e-5 is O(h^2/(pi - angle)^3)), the random nodes h = 1e-5 (at 3.07 rad, the
    # error at h = 1e-4..1e-7 measured 4e-9, 1e-8, 7e-8, 6e-7: round-off).
    _check(FramePlacementConstraint("ee", M_ref).bind(arm), arm, q, v, rng,
           h=[1e-7 if near == "pi" else 1e-5, 1e-5, 1e-5], tol_H=2e-6)
    q_ref = q[0].copy()
    q_ref[3:7] = pin.Quaternion(pin.Quaternion(q[0][3:7]).toRotationMatrix() @ _rotation(rng, near).T).coeffs()
    _check(StateConstraint(q=q_ref, v=np.ones(pm.nv)).bind(arm), arm, q, v, rng,
           h=[1e-7 if near == "pi" else 1e-6, 1e-6, 1e-6], tol_H=2e-6)


def test_joint_limits_rows_and_derivatives(rng):
    arm = _fixed_arm()
    pm = arm.pin_model
    q, v = _states(arm, rng, "random")
    c = JointLimits(joints={"elbow_joint": [-0.5, 1.0]}, position="urdf", velocity={"wrist1_joint": [-2.0, 2.0]})
    b = c.bind(arm)
    # the URDF's 6 joints (two rows each; elbow at the tighter of the two bounds), then the velocity
    assert b.rows == 6 * 2 + 2 and b.labels[:2] == ("shoulder1_joint upper", "shoulder1_joint lower")
    cv = b.value(q, v)
    i = pm.joints[pm.getJointId("elbow_joint")].idx_q
    np.testing.assert_array_equal(cv[:, b.labels.index("elbow_joint upper")], q[:, i] - 1.0)
    np.testing.assert_array_equal(cv[:, b.labels.index("elbow_joint lower")], -0.5 - q[:, i])
    j = pm.joints[pm.getJointId("wrist1_joint")].idx_v
    np.testing.assert_array_equal(cv[:, -2], v[:, j] - 2.0)
    _check(b, arm, q, v, rng, h=1e-6)


def test_the_kinematic_hessian_as_read_is_the_derivative_of_the_jacobian(rng):
    """geoddp reads Pinocchio 4.1's binding of getFrameKinematicHessian in the tensor's column-major
    order; here H[:, :, k] against central differences of the LOCAL frame Jacobian along q exp(s e_k)
    (a binding that changed the layout fails this test)."""
    for model in (_arm(), _fixed_arm()):
        pm = model.pin_model
        data = pm.createData()
        fid = pm.nframes - 1
        q = pin.integrate(pm, pin.neutral(pm), rng.uniform(-1.0, 1.0, pm.nv))  # the test's generator

        def jac(qq):
            pin.computeJointJacobians(pm, data, qq)
            return pin.getFrameJacobian(pm, data, fid, pin.LOCAL).copy()

        pin.computeJointJacobians(pm, data, q)
        pin.computeJointKinematicHessians(pm, data)
        H = frame_kinematic_hessian(pm, data, fid)
        h = 1e-6
        for k in range(pm.nv):
            e = np.zeros(pm.nv)
            e[k] = h
            dJ = (jac(pin.integrate(pm, q, e)) - jac(pin.integrate(pm, q, -e))) / (2 * h)
            np.testing.assert_allclose(H[:, :, k], dJ, rtol=0, atol=1e-8)


# ------------------------------------------------------------------ the augmented Lagrangian terms


def _perturbed(traj: Trajectory, model, k: int, z: np.ndarray) -> Trajectory:
    q, v = traj.q.copy(), traj.v.copy()
    q[k], v[k] = model.retract(traj.q[k], traj.v[k], z)
    return Trajectory(q, v, traj.u)


@pytest.mark.parametrize("case", ["satellite", "arm"])
def test_augmented_lagrangian_terms_against_differences_of_the_merit(case, rng):
    """The inner problem's l_x, l_xx, lf_x, lf_xx minus the wrapped problem's are the gradient and
    (0)-Hessian of the PHR merit at each node: its gradient against differences of the merit along
    x_k exp(s e_i), its Hessian against differences of the added gradient (black box: the inner
    problem's linearise at a trajectory with node k moved)."""
    if case == "satellite":
        p = paper_problem(horizon=8)
        cons = [PointingKeepOut([1.0, 0.0, 0.0], [0.3, 1.0, 0.2], 80.0)]
        term = [StateConstraint(q=pin.Quaternion(pin.exp3(np.array([0.3, -0.2, 0.5]))).coeffs(), v=[0.0, 0.1, 0.0])]
    else:
        from geoddp.scene.builtin import space_manipulator

        p = space_manipulator(horizon=8)
        cons = [FrameSphereKeepOut("ee", [0.8, 0.1, 0.1], 0.5), JointLimits(joints={"elbow": [-0.2, 0.3]})]
        M = pin.SE3(pin.exp3(np.array([0.1, 0.2, -0.1])), np.array([0.6, 0.2, 0.3]))
        term = [FramePlacementConstraint("ee", M)]
    cp = ConstrainedProblem(p, cons, term)
    model = p.model
    traj = p.trajectory(rng.normal(scale=2.0, size=(p.horizon, p.nu)))
    mu = [3.0] * len(cp.placed)
    # multipliers: positive on some rows, zero on others; rows kept away from the kink lambda + mu c = 0
    lam = []
    for pl, c in zip(cp.placed, cp.values(traj)):
        l_ = np.where(rng.uniform(size=c.shape) < 0.5, rng.uniform(1.0, 2.0, size=c.shape), 0.0)
        l_[np.isin(pl.nodes, (1, p.horizon // 2, p.horizon)), 0] = 1.5  # the nodes checked below: terms act there
        if not pl.bound.equality:
            l_ = np.where(np.abs(l_ + 3.0 * c) < 0.05, l_ + 0.2, l_)
        lam.append(l_)
    al = cp.augmented(lam, mu)
    base, aug = p.linearise(traj, 2), al.linearise(traj, 2)
    H = p.horizon

    def added(lin_a, lin_b, k):
        if k < H:
            return lin_a.l_x[k] - lin_b.l_x[k], lin_a.l_xx[k] - lin_b.l_xx[k]
        return lin_a.lf_x - lin_b.lf_x, lin_a.lf_xx - lin_b.lf_xx

    def node_merit(t: Trajectory, k: int) -> float:
        total = 0.0
        for pl, l_, m in zip(cp.placed, lam, mu):
            rows = np.flatnonzero(pl.nodes == k)
            if rows.size:
                c = pl.bound.value(t.q[pl.nodes[rows]], t.v[pl.nodes[rows]])
                total += merit(c, l_[rows], m, pl.bound.equality)
        return total

    nx = p.nx
    for k in (1, H // 2, H):
        g, Hk = added(aug, base, k)
        assert np.abs(g).max() > 0  # the terms act at this node
        fd_g, fd_H = np.zeros(nx), np.zeros((nx, nx))
        for i in range(nx):
            z = np.zeros(nx)
            z[i] = 1e-6
            tp, tm = _perturbed(traj, model, k, z), _perturbed(traj, model, k, -z)
            fd_g[i] = (node_merit(tp, k) - node_merit(tm, k)) / 2e-6
            fd_H[i] = (added(al.linearise(tp, 2), p.linearise(tp, 2), k)[0]
                       - added(al.linearise(tm, 2), p.linearise(tm, 2), k)[0]) / 2e-6
        assert np.abs(fd_g - g).max() <= 1e-7 * max(1.0, np.abs(g).max()), (k, np.abs(fd_g - g).max())
        assert np.abs(0.5 * (fd_H + fd_H.T) - Hk).max() <= 1e-6 * max(1.0, np.abs(Hk).max()), k
    # the merit added to J is the sum of the nodes'
    J_al, J = al.trajectory_cost(traj), p.trajectory_cost(traj)
    assert J_al - J == pytest.approx(sum(node_merit(traj, k) for k in range(1, H + 1)), rel=1e-12, abs=1e-12)


def test_gauss_newton_first_order_keeps_only_the_penalty_curvature(rng):
    """A Gauss-Newton order-1 linearisation (multibody costs) gets mu J^T J on the active rows and
    no constraint curvature; the exact order 2 adds lhat Hess c on top."""
    from geoddp.scene.builtin import space_manipulator

    p = space_manipulator(horizon=5)
    cp = ConstrainedProblem(p, [FrameSphereKeepOut("ee", [0.8, 0.1, 0.1], 0.5)])
    traj = p.trajectory(rng.normal(size=(5, p.nu)))
    (pl,) = cp.placed
    lam = [np.full((5, 1), 20.0)]  # lambda + mu c > 0 at every node: every row active
    al = cp.augmented(lam, [4.0])
    l1, b1 = al.linearise(traj, 1), p.linearise(traj, 1)
    assert l1.gauss_newton and b1.gauss_newton
    q, v = pl.states(traj)
    c, J, Hw = pl.bound.derivatives(q, v, np.maximum(lam[0] + 4.0 * pl.bound.value(q, v), 0.0))
    on = (lam[0] + 4.0 * c > 0).astype(float)
    gn = 4.0 * np.einsum("nia,ni,nib->nab", J, on, J)
    np.testing.assert_allclose(l1.l_xx[1:] - b1.l_xx[1:], gn[:-1], rtol=1e-12, atol=1e-12)
    l2, b2 = al.linearise(traj, 2), p.linearise(traj, 2)
    np.testing.assert_allclose(l2.l_xx[1:] - b2.l_xx[1:], gn[:-1] + Hw[:-1], rtol=1e-12, atol=1e-12)
    assert np.abs(Hw).max() > 1e-3  # the curvature is there to drop


def test_weights_as_a_function_of_the_value_are_the_weights_at_the_value(rng):
    """derivatives(q, v, f) with f a function of c (what the augmented Lagrangian hands over, so a
    frame's kinematics run once) equals derivatives(q, v, f(c)), for every kind."""
    sat, arm = _sat(), _arm()
    pm = arm.pin_model
    cases = [(sat, PointingKeepOut([1.0, 0.2, 0.0], D, 20.0)), (sat, StateConstraint(q=[0.0, 0.0, 0.6, 0.8])),
             (arm, PointingKeepOut([1.0, 0.0, 0.0], [0.0, 0.3, 1.0], 40.0, frame="ee")),
             (arm, FrameSphereKeepOut("ee", [0.4, 0.1, 0.2], 0.3)), (arm, FrameHalfspace("ee", [1.0, 0.0, 0.0], 0.1)),
             (arm, FramePlacementConstraint("ee", pin.SE3(_rotation(rng, "random"), np.ones(3)))),
             (arm, StateConstraint(q=pin.neutral(pm), v=np.zeros(pm.nv))), (arm, JointLimits(joints={"elbow": [-1, 1]}))]
    for model, c in cases:
        b = c.bind(model)
        q, v = _states(model, rng, "random")
        f = lambda cc: np.maximum(2.0 + 3.0 * cc, 0.0)  # noqa: E731  (a multiplier estimate)
        c1, J1, H1 = b.derivatives(q, v, f)
        c2, J2, H2 = b.derivatives(q, v, f(b.value(q, v)))
        for x, y in ((c1, c2), (J1, J2), (H1, H2)):
            np.testing.assert_array_equal(x, y)
