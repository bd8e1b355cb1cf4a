"""Rigid point contacts and impulses on a floating-base multibody: the node dynamics of legged robots.

Two node models over Pinocchio, as Crocoddyl's (same arithmetic, same next state to round-off):

* **Contact node** (Crocoddyl's ``DifferentialActionModelContactFwdDynamics`` with 3D point contacts
  expressed ``LOCAL_WORLD_ALIGNED``, under ``IntegratedActionModelEuler``): the feet in contact have
  zero classical acceleration up to Baumgarte stabilisation,
  ``J_c a + a_0 = 0``, ``a_0 = oRf (alpha_f + Kp oRf^T p_f + Kd v_f)`` (alpha_f the frame's
  classical linear acceleration at a = 0, v_f its linear velocity, both in the foot frame; the
  position term's reference is the origin, as in Crocoddyl's gaits, where Kp = 0), and the
  accelerations and contact forces solve the KKT system ``M a = tau - b + J_c^T lambda`` (Pinocchio's
  ``forwardDynamics``), ``tau = S u`` (S: the floating base unactuated). Then semi-implicit Euler:
  ``v+ = v + dt a``, ``q+ = integrate(q, dt v+)``.
* **Impulse node** (Crocoddyl's ``ActionModelImpulseFwdDynamics``, a node with no controls): at
  touch-down the velocity jumps to the one that stops the new feet, ``M (v+ - v) = J_c^T Lambda``,
  ``J_c v+ = 0`` (Pinocchio's ``impulseDynamics``, restitution 0); ``q+ = q``.

Perturbations are geoddp's (right/local: ``q = integrate(q_bar, dq)``, ``v = v_bar + dv``), so the
Jacobians are those of Pinocchio's analytic derivatives: ``computeRNEADerivatives`` with the contact
forces as external forces and ``getFrameAccelerationDerivatives`` / ``getFrameVelocityDerivatives``
for the constraint rows, put through the KKT matrix (implicit differentiation); forces are handled
in the foot frame (where they move with the body) and rotated to the world at the end.

Second order (for the ``second`` and ``switch`` expansions), exact (:meth:`ContactDynamics.contact_second`,
:meth:`ContactDynamics.impulse_second`): the KKT system differentiated twice. With w = (q, v, y),
y = (a, lambda) (contact; v+ and Lambda at an impulse) and the equations written as
``E1 = rnea(q, v, a) - sum_f J_w,f(q)^T lambda_f - S u = 0`` (world forces, J_w the feet's
world-aligned linear Jacobians) and, per foot, the Baumgarte condition rotated to the world,
``E2 = p''(q, v, a + Kd v) + Kp p(q) = 0`` (p the foot point's world position; the same solution
as the foot frame's condition, so the same derivatives), the second derivatives y'' solve
``E_y y'' = -E_ww[X, X]``, X = dw/dz = (I, I, y'), with the first-order y' the analytic one above.
E_ww comes from Pinocchio's second-order RNEA derivatives (``ComputeRNEASecondOrderDerivatives``,
the compiled core's ``rnea_second_order``) of three exact identities, no differences anywhere:

* the robot's own RNEA at (q, v, a) (an impulse: without gravity at (q, 0, v+ - v), M(q) (v+ - v));
* per foot, the RNEA of the robot with every inertia zero and a unit point mass at the foot is
  ``J_w^T p''(q, v, a)`` (the point's Newton equation), whose free-flyer translational rows are
  ``oR_b^T p''``: p'' = oR_b tau[0:3], and its q-q, q-v, q-a, v-v second derivatives follow by the
  product rule with oR_b(q exp(eta)) = oR_b exp(eta_rot); P_qa = dJ_w/dq gives the q-lambda block;
* per foot, that model's RNEA at v = a = 0 under the gravity -lambda_f is ``J_w^T lambda_f``: the
  q-q block of the forces' term.

All chart Hessians are symmetric (Pinocchio's q-q blocks, derivatives of right-trivialised
Jacobians, symmetrised: the difference is antisymmetric). The semi-implicit Euler step's chart terms
are added by :func:`geoddp.models.integrators.expand` (:mod:`geoddp.problem.legged`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..kernels import core as _core
from ..validate import InputError

LOCAL = pin.ReferenceFrame.LOCAL


def skew(w: np.ndarray) -> np.ndarray:
    x, y, z = w.tolist()  # Python floats: a fraction of the cost of indexing the array
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


# skew(e_i), i = 0..2: d/d eta_(3+i) of oR_b exp(eta_rot) = oR_b skew(e_i) (the free flyer's
# rotational tangent directions 3..5; the other directions leave oR_b unchanged)
_GENERATORS = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
                        [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
                        [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])


# the Levi-Civita symbol: skew(w)[a, b] = -sum_c EPS[a, b, c] w_c
_EPS = np.zeros((3, 3, 3))
_EPS[0, 1, 2] = _EPS[1, 2, 0] = _EPS[2, 0, 1] = 1.0
_EPS[0, 2, 1] = _EPS[2, 1, 0] = _EPS[1, 0, 2] = -1.0


def skew_stack(W: np.ndarray) -> np.ndarray:
    """(n, 3, 3): skew(w) of each row of W (n, 3)."""
    return -np.einsum("abc,nc->nab", _EPS, W)


def _symmetric_from_upper(M: np.ndarray) -> np.ndarray:
    """A copy of the square M with its strict lower triangle replaced by the upper one's mirror
    (Pinocchio fills the upper triangle of the mass matrix)."""
    S = np.array(M)
    lower = _LOWER.get(S.shape[0])
    if lower is None:
        lower = _LOWER[S.shape[0]] = np.tril_indices(S.shape[0], -1)
    S[lower] = S.T[lower]
    return S


_LOWER: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def friction_cone(mu: float, facets: int = 4, min_force: float = 0.0, max_force: float = np.inf
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crocoddyl's linearised friction cone (outer approximation, flat ground, normal +z):
    (A (facets + 1, 3), lb, ub) with lb <= A f <= ub meaning f inside the cone, f_z in
    [min_force, max_force] (N)."""
    if facets % 2 or facets < 2:
        raise InputError("facets", f"expected an even number >= 2, got {facets!r}")
    A = np.zeros((facets + 1, 3))
    lb, ub = np.full(facets + 1, -np.inf), np.zeros(facets + 1)
    theta = 2.0 * np.pi / facets
    mu_n = np.array([0.0, 0.0, -mu])
    row = 0
    for i in range(facets // 2):
        t = np.array([np.cos(theta * i), np.sin(theta * i), 0.0])
        A[row], A[row + 1] = mu_n + t, mu_n - t
        row += 2
    A[facets] = [0.0, 0.0, 1.0]
    lb[facets], ub[facets] = min_force, max_force
    return A, lb, ub


@dataclass
class NodeEval:
    """One node evaluated: next state, accelerations / velocity jump, contact forces in the world
    frame (3 per foot, N at a contact node, N s at an impulse node) and, when asked, the Jacobians
    in z = (dq, dv, du) (nv + nv + m columns): Fz (2 nv, nz) of (q+, v+) in the tangent at (q+, v+),
    Lz (3 nc, nz) of the world forces."""

    q_next: np.ndarray
    v_next: np.ndarray
    forces: np.ndarray
    Fz: np.ndarray | None = None
    Lz: np.ndarray | None = None
    acc: np.ndarray | None = None  # contact node: the accelerations a (nv,)
    Az: np.ndarray | None = None  # Jacobian (nv, nz) of a (contact node) or of v+ (impulse node)


@dataclass
class ContactDynamics:
    """Contact and impulse node dynamics of a floating-base ``pin.Model``.

    Attributes:
        model: the robot (free-flyer root; joints after it actuated one to one).
        dt: time step of the contact nodes, s.
        gains: Baumgarte gains (Kp 1/s^2, Kd 1/s) of every point contact (Crocoddyl's (0, 50) in
            its quadruped gaits).
        impulse_damping: Pinocchio's inv_damping of the impulse KKT solve (Crocoddyl's 1e-12).
    """

    model: pin.Model
    dt: float
    gains: tuple[float, float] = (0.0, 50.0)
    impulse_damping: float = 1e-12
    data: pin.Data = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.model, pin.Model) or self.model.njoints < 2 or \
                self.model.joints[1].shortname() != "JointModelFreeFlyer":
            raise InputError("model", "expected a pinocchio.Model with a free-flyer root joint")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise InputError("dt", f"expected a positive time step (s), got {self.dt!r}")
        self.gains = (float(self.gains[0]), float(self.gains[1]))
        self.data = self.model.createData()
        nv = self.model.nv
        self.S = np.zeros((nv, nv - 6))
        self.S[6:] = np.eye(nv - 6)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    @property
    def nu(self) -> int:
        return int(self.model.nv) - 6

    # ------------------------------------------------------------------ contact node
    def _contact_terms(self, feet: tuple[int, ...]):
        """After computeAllTerms: per foot (local Jacobian (6, nv), oRf, local velocity, a0_local)."""
        m, d = self.model, self.data
        Kp, Kd = self.gains
        out = []
        for f in feet:
            J = pin.getFrameJacobian(m, d, f, LOCAL)
            R = d.oMf[f].rotation
            vf = pin.getFrameVelocity(m, d, f, LOCAL)
            a0 = pin.getFrameClassicalAcceleration(m, d, f, LOCAL).linear.copy()
            dp_local = None
            if Kp != 0.0:
                dp_local = R.T @ d.oMf[f].translation
                a0 += Kp * dp_local
            if Kd != 0.0:
                a0 += Kd * vf.linear
            out.append((J, R.copy(), vf, a0, dp_local))
        return out

    def contact(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, feet: tuple[int, ...],
                derivatives: bool = False) -> NodeEval:
        """Contact node at (q, v, u) with ``feet`` (frame ids) on the ground."""
        m, d, dt, nv = self.model, self.data, self.dt, self.nv
        pin.computeAllTerms(m, d, q, v)
        pin.updateFramePlacements(m, d)
        terms = self._contact_terms(feet)
        tau = self.S @ u
        if feet:
            Jc = np.vstack([R @ J[:3] for J, R, *_ in terms])
            a0 = np.concatenate([R @ a0 for _, R, _, a0, _ in terms])
            a = pin.forwardDynamics(m, d, tau, Jc, a0, 0.0).copy()
            lam = d.lambda_c.copy()
        else:
            a = pin.aba(m, d, q, v, tau).copy()
            lam = np.zeros(0)
        v_next = v + a * dt
        w = v * dt + a * (dt * dt)  # Crocoddyl's dx (= dt v+)
        q_next = pin.integrate(m, q, w)
        ev = NodeEval(q_next, v_next, lam, acc=a)
        if not derivatives:
            return ev
        nf, nu = len(feet), self.nu
        nc = 3 * nf
        Js = np.array([t[0] for t in terms]).reshape(nf, 6, nv)  # LOCAL Jacobians, stacked over the feet
        Rs = np.array([t[1] for t in terms]).reshape(nf, 3, 3)
        lam_local = np.einsum("fba,fb->fa", Rs, lam.reshape(nf, 3))  # oRf^T lambda_f
        fext = [pin.Force.Zero() for _ in range(m.njoints)]
        for f, ll in zip(feet, lam_local):
            fr = m.frames[f]
            fext[fr.parentJoint] += fr.placement.act(pin.Force(ll, np.zeros(3)))
        dtau_dq, dtau_dv, M = pin.computeRNEADerivatives(m, d, q, v, a, fext)
        M = _symmetric_from_upper(M)
        nz = 2 * nv + nu
        K = np.zeros((nv + nc, nv + nc))
        K[:nv, :nv] = M
        rhs = np.zeros((nv + nc, nz))
        rhs[:nv, :nv], rhs[:nv, nv:2 * nv], rhs[:nv, 2 * nv:] = dtau_dq, dtau_dv, -self.S
        if feet:
            Kp, Kd = self.gains
            pin.computeForwardKinematicsDerivatives(m, d, q, v, a)
            V_dq, A_dq, A_dv = np.empty((nf, 6, nv)), np.empty((nf, 6, nv)), np.empty((nf, 6, nv))
            for i, f in enumerate(feet):
                V_dq[i], A_dq[i], A_dv[i], _ = pin.getFrameAccelerationDerivatives(m, d, f, LOCAL)
            Wx = skew_stack(np.array([t[2].angular for t in terms]))
            Vx = skew_stack(np.array([t[2].linear for t in terms]))
            h_q = A_dq[:, :3] + Wx @ V_dq[:, :3] - Vx @ V_dq[:, 3:]
            h_v = A_dv[:, :3] + Wx @ Js[:, :3] - Vx @ Js[:, 3:]
            if Kp != 0.0:
                h_q = h_q + Kp * (skew_stack(np.array([t[4] for t in terms])) @ Js[:, 3:] + Js[:, :3])
            if Kd != 0.0:
                h_q = h_q + Kd * V_dq[:, :3]
                h_v = h_v + Kd * Js[:, :3]
            Jlin = Js[:, :3].reshape(nc, nv)
            K[:nv, nv:] = -Jlin.T
            K[nv:, :nv] = Jlin
            rhs[nv:, :nv], rhs[nv:, nv:2 * nv] = h_q.reshape(nc, nv), h_v.reshape(nc, nv)
        sol = -(np.linalg.inv(K) @ rhs)  # LAPACK's solve is slower on these small systems
        da, dlam = sol[:nv], sol[nv:]
        Lz = (Rs @ dlam.reshape(nf, 3, nz)).reshape(nc, nz)
        Lz[:, :nv] -= (Rs @ skew_stack(lam_local) @ Js[:, 3:]).reshape(nc, nv)
        dvn = dt * da
        dvn[:, nv:2 * nv] += np.eye(nv)
        Dq = pin.dIntegrate(m, q, w, pin.ArgumentPosition.ARG0)
        Dw = pin.dIntegrate(m, q, w, pin.ArgumentPosition.ARG1)
        Fz = np.empty((2 * nv, nz))
        Fz[:nv] = dt * (Dw @ dvn)
        Fz[:nv, :nv] += Dq
        Fz[nv:] = dvn
        ev.Fz, ev.Lz, ev.Az = Fz, Lz, da
        return ev

    # ------------------------------------------------------------------ impulse node
    def impulse(self, q: np.ndarray, v: np.ndarray, feet: tuple[int, ...], derivatives: bool = False) -> NodeEval:
        """Impulse node at (q, v): ``feet`` touch down (v jumps, q stays). Jacobian columns as a
        contact node's with m = nu (the control columns zero)."""
        m, d, nv = self.model, self.data, self.nv
        pin.computeAllTerms(m, d, q, v)
        pin.updateFramePlacements(m, d)
        Js = [pin.getFrameJacobian(m, d, f, LOCAL) for f in feet]
        Rs = [d.oMf[f].rotation.copy() for f in feet]
        Jc = np.vstack([R @ J[:3] for J, R in zip(Js, Rs)])
        pin.impulseDynamics(m, d, v, Jc, 0.0, self.impulse_damping)  # M from computeAllTerms, as Crocoddyl
        v_next, imp = d.dq_after.copy(), d.impulse_c.copy()
        ev = NodeEval(q.copy(), v_next, imp)
        if not derivatives:
            return ev
        nc, nu = 3 * len(feet), self.nu
        nz = 2 * nv + nu
        imp_local = [R.T @ imp[3 * i:3 * i + 3] for i, R in enumerate(Rs)]
        fext = [pin.Force.Zero() for _ in range(m.njoints)]
        for f, ll in zip(feet, imp_local):
            fr = m.frames[f]
            fext[fr.parentJoint] += fr.placement.act(pin.Force(ll, np.zeros(3)))
        # F1 = M(q) (v+ - v) - J(q)^T Lambda = rnea(q, 0, v+ - v, fext) - g(q)
        dtau_dq, _, M = pin.computeRNEADerivatives(m, d, q, np.zeros(nv), v_next - v, fext)
        dtau_dq = dtau_dq.copy()
        M = _symmetric_from_upper(M)
        dg_dq = pin.computeGeneralizedGravityDerivatives(m, d, q)
        K = np.zeros((nv + nc, nv + nc))
        K[:nv, :nv] = M
        rhs = np.zeros((nv + nc, nz))
        rhs[:nv, :nv] = dtau_dq - dg_dq
        rhs[:nv, nv:2 * nv] = -M
        pin.computeForwardKinematicsDerivatives(m, d, q, v_next, np.zeros(nv))
        for i, (f, J) in enumerate(zip(feet, Js)):
            v_dq, _ = pin.getFrameVelocityDerivatives(m, d, f, LOCAL)
            r = slice(nv + 3 * i, nv + 3 * i + 3)
            K[:nv, r] = -J[:3].T
            K[r, :nv] = J[:3]
            rhs[r, :nv] = v_dq[:3]
        sol = -(np.linalg.inv(K) @ rhs)  # LAPACK's solve is slower on these small systems
        dvn, dimp = sol[:nv], sol[nv:]
        Lz = np.empty((nc, nz))
        for i, (J, R) in enumerate(zip(Js, Rs)):
            rows = slice(3 * i, 3 * i + 3)
            Lz[rows] = R @ dimp[rows]
            Lz[rows, :nv] -= R @ skew(imp_local[i]) @ J[3:]
        Fz = np.zeros((2 * nv, nz))
        Fz[:nv, :nv] = np.eye(nv)
        Fz[nv:] = dvn
        ev.Fz, ev.Lz, ev.Az = Fz, Lz, dvn
        return ev

    # ------------------------------------------------------------------ exact second order
    def _aux_models(self):
        """Models built once for the second order: the robot without gravity (the impulse's M(q) w
        as an RNEA) and, per foot frame, a massless copy of the robot carrying a unit point mass at
        the frame's origin and no gravity (its RNEA is J_w^T p'', see :meth:`_point_terms`)."""
        if getattr(self, "_aux", None) is None:
            m0 = pin.Model(self.model)
            m0.gravity = pin.Motion.Zero()
            self._aux = {"zero_gravity": (m0, m0.createData()), "feet": {}}
        return self._aux

    def _foot_model(self, f: int):
        aux = self._aux_models()
        if aux["feet"].get(f) is None:
            mf = pin.Model(self.model)
            for j in range(mf.njoints):
                mf.inertias[j] = pin.Inertia.Zero()
            fr = mf.frames[f]
            mf.inertias[fr.parentJoint] = pin.Inertia(1.0, fr.placement.translation.copy(), np.zeros((3, 3)))
            mf.gravity = pin.Motion.Zero()
            aux["feet"][f] = (mf, mf.createData())
        return aux["feet"][f]

    def _point_terms(self, feet: tuple[int, ...], q: np.ndarray, v: np.ndarray, a: np.ndarray):
        """Derivatives of the world accelerations p''(q, v, a) of the origins of the frames
        ``feet`` (q in the right chart), stacked over the feet (3 rows each): (P_a = J_w (3 nf, nv),
        P_qq, P_qv, P_qa, P_vv (3 nf, nv, nv), indexed [c, first, second], P_qq the symmetric chart
        Hessian).

        Exact, from an identity: the RNEA of the robot with every inertia zero and a unit point mass
        at the frame's origin is tau = J_w(q)^T p''(q, v, a) (the point's Newton equation; no
        gravity), and the free flyer's translational columns of J_w are the base rotation oR_b,
        so p'' = oR_b w with w = tau[0:3]. Pinocchio's first- and second-order RNEA derivatives
        of that model give w's, oR_b(q exp(eta)) = oR_b exp(eta_rot) gives the rest (product rule).
        """
        nv, nf = self.nv, len(feet)
        W = np.empty((nf, 3))
        Wq, Wv, Wa = np.empty((nf, 3, nv)), np.empty((nf, 3, nv)), np.empty((nf, 3, nv))
        P_qq, P_qv, P_qa, P_vv = (np.empty((nf, 3, nv, nv)) for _ in range(4))
        for i, f in enumerate(feet):
            mf, df = self._foot_model(f)
            W[i] = pin.rnea(mf, df, q, v, a)[:3]
            dq, dv, M = pin.computeRNEADerivatives(mf, df, q, v, a)
            Wq[i], Wv[i], Wa[i] = dq[:3], dv[:3], _symmetric_from_upper(M)[:3]
            qq, vv, qv, aq = _core.rnea_second_order(mf, q, v, a, False)
            P_qq[i], P_qv[i], P_qa[i], P_vv[i] = qq[:3], qv[:3], aq[:3].transpose(0, 2, 1), vv[:3]
        R = pin.XYZQUATToSE3(q[:7]).rotation  # the base rotation (RNEA does not fill oMi)
        # E_i = skew(e_(i-3)) on the free flyer's rotational directions i = 3..5, zero elsewhere:
        # the product rule's terms touch those rows (and columns) only
        G = _GENERATORS
        P_qq += P_qq.transpose(0, 1, 3, 2)
        P_qq *= 0.5
        Gw_q = np.einsum("iab,fbj->faij", G, Wq)  # (nf, 3, 3, nv): [f, a, i - 3, j]
        P_qq[:, :, 3:6, :] += Gw_q
        P_qq[:, :, :, 3:6] += Gw_q.transpose(0, 1, 3, 2)
        GG = np.einsum("iab,jbc,fc->faij", G, G, W)
        P_qq[:, :, 3:6, 3:6] += 0.5 * (GG + GG.transpose(0, 1, 3, 2))
        P_qv[:, :, 3:6, :] += np.einsum("iab,fbk->faik", G, Wv)
        P_qa[:, :, 3:6, :] += np.einsum("iab,fbk->faik", G, Wa)

        def rot(T):  # oR_b applied to each foot's 3 rows
            return (R @ T.reshape(nf, 3, nv * nv)).reshape(3 * nf, nv, nv)

        return (R @ Wa).reshape(3 * nf, nv), rot(P_qq), rot(P_qv), rot(P_qa), rot(P_vv)

    def _force_terms(self, H: np.ndarray, q: np.ndarray, feet, forces: np.ndarray, Q: slice) -> None:
        """Subtract from the RNEA rows of H (E_ss) the q-q second derivatives of sum_f J_w,f(q)^T lambda_f
        (world forces held), from the foot's point-mass model under the gravity -lambda_f (its RNEA
        at v = a = 0 is J_w^T lambda_f). (The q-lambda block, -dJ_w/dq, is the callers': P_qa.)"""
        nv = self.nv
        zero = np.zeros(nv)
        total = None
        for i, f in enumerate(feet):
            mf, _ = self._foot_model(f)
            mf.gravity = pin.Motion(-forces[3 * i:3 * i + 3], np.zeros(3))
            try:
                gqq = _core.rnea_second_order(mf, q, zero, zero, False)[0]
            finally:
                mf.gravity = pin.Motion.Zero()
            total = gqq if total is None else total + gqq
        if total is not None:
            H[:nv, Q, Q] -= 0.5 * (total + total.transpose(0, 2, 1))

    def _kkt_second(self, Hss: np.ndarray, Hsy: np.ndarray, Y1: np.ndarray, M: np.ndarray, Jw: np.ndarray
                    ) -> np.ndarray:
        """y'' (ny, nz, nz) of the KKT unknowns y = (a or v+, lambda) from E(w) = 0, w = (s, y),
        s = (q, v): E_y y'' = -E_ww[X, X], X = dw/dz = [[I, 0], [Y1]] (s is z's first 2 nv
        entries; Y1 = dy/dz (ny, nz)), E_y = [[M, -J_w^T], [J_w, 0]]. E is affine in y (E_yy = 0),
        so E_ww[X, X] = E_ss + E_sy Y1 + its transpose, without forming X: the blocks
        Hss = E_ss (ny, 2 nv, 2 nv) and Hsy = E_sy (ny, 2 nv, ny) are all it reads."""
        nv, nc, nz = self.nv, Jw.shape[0], Y1.shape[1]
        ny, ns = Hss.shape[0], 2 * nv
        # the rows in s of the symmetric E_ww[X, X] (its u-u block is zero: X's u columns are y's)
        rhs = (Hsy.reshape(ny * ns, ny) @ Y1).reshape(ny, ns, nz)  # E_sy Y1
        CT = rhs[:, :, :ns].transpose(0, 2, 1).copy()
        rhs[:, :, :ns] += Hss
        rhs[:, :, :ns] += CT
        K = np.zeros((nv + nc, nv + nc))
        K[:nv, :nv], K[:nv, nv:], K[nv:, :nv] = M, -Jw.T, Jw
        # one inverse of the small KKT matrix, then one product over the right-hand sides
        # (LAPACK's solve is several times slower on this many columns)
        Kinv = np.linalg.inv(K)
        Kinv *= -1.0
        Ys = (Kinv @ rhs.reshape(ny, ns * nz)).reshape(ny, ns, nz)
        Y = np.empty((ny, nz, nz))
        Y[:, :ns] = Ys
        Y[:, ns:, :ns] = Ys[:, :, ns:].transpose(0, 2, 1)
        Y[:, ns:, ns:] = 0.0
        return Y

    def contact_second(self, q: np.ndarray, v: np.ndarray, u: np.ndarray, feet: tuple[int, ...], ev: NodeEval
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Exact second derivatives (symmetric chart Hessians in z = (dq, dv, du)) of a contact
        node's accelerations a (nv, nz, nz) and world forces lambda (3 nc, nz, nz), from ``ev`` (the
        node evaluated with derivatives), by differentiating the KKT system twice:
        E1 = rnea(q, v, a) - sum_f J_w,f^T lambda_f - S u = 0 and, per foot, the Baumgarte condition
        in the world frame E2 = p''(q, v, a + Kd v) + Kp p(q) = 0 (the foot frame's condition
        rotated, the same solution)."""
        nv, nc = self.nv, 3 * len(feet)
        Kp, Kd = self.gains
        Q, V = slice(0, nv), slice(nv, 2 * nv)
        ny = nv + nc
        # E_ww's blocks in (s, s) and (s, y), s = (q, v), y = (a, lambda) (E_yy = 0; E_ys is E_sy's transpose)
        Hss, Hsy = np.zeros((ny, 2 * nv, 2 * nv)), np.zeros((ny, 2 * nv, ny))
        qq, vv, qv, aq = _core.rnea_second_order(self.model, q, v, ev.acc, False)
        Hss[:nv, Q, Q] = 0.5 * (qq + qq.transpose(0, 2, 1))
        Hss[:nv, Q, V], Hss[:nv, V, Q], Hss[:nv, V, V] = qv, qv.transpose(0, 2, 1), vv
        Hsy[:nv, Q, :nv] = aq.transpose(0, 2, 1)
        self._force_terms(Hss, q, feet, ev.forces, Q)
        Jw, P_qq, P_qv, P_qa, P_vv = self._point_terms(feet, q, v, ev.acc + Kd * v)
        r = slice(nv, ny)
        Hss[r, Q, Q] = P_qq + Kp * 0.5 * (P_qa + P_qa.transpose(0, 2, 1))
        Hss[r, Q, V] = P_qv + Kd * P_qa
        Hss[r, V, Q] = Hss[r, Q, V].transpose(0, 2, 1)
        Hss[r, V, V] = P_vv
        Hsy[r, Q, :nv] = P_qa
        Hsy[:nv, Q, nv:] = -P_qa.transpose(2, 1, 0)
        return self._kkt_second_split(Hss, Hsy, ev, q, Jw)

    def impulse_second(self, q: np.ndarray, v: np.ndarray, feet: tuple[int, ...], ev: NodeEval
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Exact second derivatives of an impulse node's v+ (nv, nz, nz) and world impulses
        (3 nc, nz, nz), from its KKT system differentiated twice: E1 = M(q) (v+ - v) -
        sum_f J_w,f^T Lambda_f = 0 (M(q) w: the RNEA without gravity at (q, 0, w)) and, per foot,
        E2 = J_w(q) v+ = p''(q, 0, v+) = 0."""
        nv, nc = self.nv, 3 * len(feet)
        Q, V = slice(0, nv), slice(nv, 2 * nv)
        ny = nv + nc
        Hss, Hsy = np.zeros((ny, 2 * nv, 2 * nv)), np.zeros((ny, 2 * nv, ny))
        m0, _ = self._aux_models()["zero_gravity"]
        zero = np.zeros(nv)
        qq, _, _, aq = _core.rnea_second_order(m0, q, zero, ev.v_next - v, False)
        Hss[:nv, Q, Q] = 0.5 * (qq + qq.transpose(0, 2, 1))
        Hsy[:nv, Q, :nv] = aq.transpose(0, 2, 1)
        Hss[:nv, V, Q], Hss[:nv, Q, V] = -aq, -aq.transpose(0, 2, 1)
        self._force_terms(Hss, q, feet, ev.forces, Q)
        Jw, P_qq, _, P_qa, _ = self._point_terms(feet, q, zero, ev.v_next)
        r = slice(nv, ny)
        Hss[r, Q, Q] = P_qq
        Hsy[r, Q, :nv] = P_qa
        Hsy[:nv, Q, nv:] = -P_qa.transpose(2, 1, 0)
        return self._kkt_second_split(Hss, Hsy, ev, q, Jw)

    def _kkt_second_split(self, Hss: np.ndarray, Hsy: np.ndarray, ev: NodeEval, q: np.ndarray, Jw: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
        """The KKT system's second derivatives from its blocks (Hss, Hsy) at q (M(q) by CRBA,
        symmetrised), split into the (nv, nz, nz) accelerations or velocity jump and the
        (3 nc, nz, nz) forces."""
        M = pin.crba(self.model, self.data, q)
        M = _symmetric_from_upper(M)
        Y = self._kkt_second(Hss, Hsy, np.vstack([ev.Az, ev.Lz]), M, Jw)
        return Y[:self.nv], Y[self.nv:]

    # ------------------------------------------------------------------ quasi-static controls
    def quasi_static(self, q: np.ndarray, feet: tuple[int, ...]) -> np.ndarray:
        """Crocoddyl's ``quasiStatic`` of a contact node: the (nu,) controls that, with the contact
        forces, hold q at rest (least squares of smallest norm of [S, J_c^T] (u, lambda) = g(q))."""
        m, d, nv = self.model, self.data, self.nv
        pin.computeAllTerms(m, d, q, np.zeros(nv))
        pin.updateFramePlacements(m, d)
        g = pin.rnea(m, d, q, np.zeros(nv), np.zeros(nv))
        cols = [self.S] + [(d.oMf[f].rotation @ pin.getFrameJacobian(m, d, f, LOCAL)[:3]).T for f in feet]
        sol = np.linalg.pinv(np.hstack(cols)) @ g
        return sol[:self.nu].copy()
