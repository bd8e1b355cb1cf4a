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
CONTACT_KINDS = ("3d", "6d", "6d_local")


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


def wrench_cone(mu: float, box: tuple[float, float], facets: int = 4, inner: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crocoddyl's ``WrenchCone`` (flat ground, normal +z) of a rectangular sole ``box`` = (length,
    width) m centred on the foot frame: (A (facets + 13, 6), lb, ub), lb <= A (f, tau) <= ub
    meaning the wrench (force N, torque N m about the foot frame's origin, world-aligned axes)
    inside: the linearised friction cone (``inner``: its inner approximation, mu cos(pi / facets);
    Crocoddyl's default), f_z >= 0, the centre of pressure inside the sole (four rows), the yaw
    torque within the sole's friction bound (eight rows)."""
    if facets % 2 or facets < 2:
        raise InputError("facets", f"expected an even number >= 2, got {facets!r}")
    theta = 2.0 * np.pi / facets
    mu = mu * np.cos(0.5 * theta) if inner else mu
    A = np.zeros((facets + 13, 6))
    lb, ub = np.full(facets + 13, -np.inf), np.zeros(facets + 13)
    mu_n = np.array([0.0, 0.0, -mu])
    for i in range(facets // 2):
        t = np.array([np.cos(theta * i), np.sin(theta * i), 0.0])
        A[2 * i, :3], A[2 * i + 1, :3] = mu_n + t, mu_n - t
    A[facets, 2] = 1.0
    lb[facets], ub[facets] = 0.0, np.inf
    L, W = 0.5 * box[0], 0.5 * box[1]
    n = facets
    A[n + 1] = [0, 0, -W, 1, 0, 0]
    A[n + 2] = [0, 0, -W, -1, 0, 0]
    A[n + 3] = [0, 0, -L, 0, 1, 0]
    A[n + 4] = [0, 0, -L, 0, -1, 0]
    mu_lw = -mu * (L + W)
    for j, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        A[n + 5 + j] = [sx * W, sy * L, mu_lw, -sx * mu, -sy * mu, -1.0]
        A[n + 9 + j] = [sx * W, sy * L, mu_lw, sx * mu, sy * mu, 1.0]
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
        contact_kinds: {frame id or name: kind} of the feet that are not 3D point contacts:
            ``"6d"`` (a flat foot: the frame's whole spatial acceleration constrained, forces
            (force, torque) at the frame's origin in world-aligned axes, Crocoddyl's
            ``ContactModel6D`` / ``ImpulseModel6D`` with ``LOCAL_WORLD_ALIGNED``) or ``"6d_local"``
            (the same in the frame's own axes, ``LOCAL``); ``"3d"`` (the default of every frame):
            a point contact. The Baumgarte position term of a 6D contact is
            ``Kp log6(oMf)`` (the reference placement the identity, as in Crocoddyl's biped).
    """

    model: pin.Model
    dt: float
    gains: tuple[float, float] = (0.0, 50.0)
    impulse_damping: float = 1e-12
    contact_kinds: dict = field(default_factory=dict)
    data: pin.Data = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.model, pin.Model) or self.model.njoints < 2 or \
                self.model.joints[1].shortname() != "JointModelFreeFlyer":
            raise InputError("model", "expected a pinocchio.Model with a free-flyer root joint")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise InputError("dt", f"expected a positive time step (s), got {self.dt!r}")
        self.gains = (float(self.gains[0]), float(self.gains[1]))
        kinds = {}
        for key, kind in dict(self.contact_kinds).items():
            if isinstance(key, str):
                if not self.model.existFrame(key):
                    raise InputError("contact_kinds", f"frame {key!r} is not in the model")
                key = int(self.model.getFrameId(key))
            if not (isinstance(key, (int, np.integer)) and 0 <= int(key) < len(self.model.frames)):
                raise InputError("contact_kinds", f"expected frame ids or names as keys, got {key!r}")
            if kind not in CONTACT_KINDS:
                raise InputError("contact_kinds", f"expected a kind of {CONTACT_KINDS} for frame {key!r}, got {kind!r}")
            if kind != "3d":
                kinds[int(key)] = kind
        self.contact_kinds = kinds
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

    def kind(self, f: int) -> str:
        """The contact kind of frame ``f``: "3d", "6d" or "6d_local"."""
        return self.contact_kinds.get(f, "3d")

    def force_dims(self, feet: tuple[int, ...]) -> list[int]:
        """Entries of each foot's force in ``NodeEval.forces``: 3 (point) or 6 (force, torque)."""
        return [3 if self.kind(f) == "3d" else 6 for f in feet]

    def _flat(self, feet: tuple[int, ...]) -> bool:
        return any(f in self.contact_kinds for f in feet)

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
        if self._flat(feet):
            return self._contact_general(q, v, u, feet, derivatives)
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
        if self._flat(feet):
            return self._impulse_general(q, v, feet, derivatives)
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
        if self._flat(feet):
            return self._second_general(q, v, feet, ev, impulse=False)
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
        if self._flat(feet):
            return self._second_general(q, v, feet, ev, impulse=True)
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

    # ------------------------------------------------------------------ feet of any kind (6D flat feet)
    def _rows(self, f: int, R: np.ndarray, J: np.ndarray) -> np.ndarray:
        """Foot f's constraint rows as Crocoddyl stacks them, from its LOCAL Jacobian J (6, nv):
        R J_lin (3d, world-aligned), blockdiag(R, R) J (6d), J (6d_local)."""
        kind = self.kind(f)
        if kind == "3d":
            return R @ J[:3]
        if kind == "6d":
            return np.vstack([R @ J[:3], R @ J[3:]])
        return J

    def _drift(self, f: int, R: np.ndarray, vf: pin.Motion) -> np.ndarray:
        """Foot f's a0 in its constraint's axes (Crocoddyl's arithmetic): the classical linear
        acceleration (3d) or the spatial acceleration (6d) at a = 0 in the foot frame plus the
        Baumgarte terms, rotated to the world for 3d and 6d."""
        m, d = self.model, self.data
        Kp, Kd = self.gains
        kind = self.kind(f)
        if kind == "3d":
            a0 = pin.getFrameClassicalAcceleration(m, d, f, LOCAL).linear.copy()
            if Kp != 0.0:
                a0 += Kp * (R.T @ d.oMf[f].translation)
            if Kd != 0.0:
                a0 += Kd * vf.linear
            return R @ a0
        a0 = pin.getFrameAcceleration(m, d, f, LOCAL).vector.copy()
        if Kp != 0.0:
            a0 += Kp * pin.log6(d.oMf[f]).vector
        if Kd != 0.0:
            a0 += Kd * vf.vector
        if kind == "6d":
            return np.concatenate([R @ a0[:3], R @ a0[3:]])
        return a0

    def _local_forces(self, f: int, R: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(force, torque) of foot f in the foot frame from its reported force (3 or 6 entries)."""
        kind = self.kind(f)
        if kind == "3d":
            return R.T @ lam, np.zeros(3)
        if kind == "6d":
            return R.T @ lam[:3], R.T @ lam[3:]
        return lam[:3].copy(), lam[3:].copy()

    def _fext(self, feet: tuple[int, ...], local: list) -> list:
        fext = [pin.Force.Zero() for _ in range(self.model.njoints)]
        for f, (fl, tl) in zip(feet, local):
            fr = self.model.frames[f]
            fext[fr.parentJoint] += fr.placement.act(pin.Force(fl, tl))
        return fext

    def _reported_force_jacobian(self, f: int, R: np.ndarray, J: np.ndarray, local, dlam: np.ndarray) -> np.ndarray:
        """Jacobian of foot f's reported force (world-aligned for 3d and 6d) from the Jacobian
        ``dlam`` of its foot-frame force: R dlam minus the rotation's q-derivative R skew(f) J_ang."""
        kind, nv = self.kind(f), self.nv
        if kind == "6d_local":
            return dlam
        out = np.empty_like(dlam)
        for k in range(len(dlam) // 3):
            out[3 * k:3 * k + 3] = R @ dlam[3 * k:3 * k + 3]
            out[3 * k:3 * k + 3, :nv] -= R @ skew(local[k]) @ J[3:]
        return out

    def _kkt_first(self, feet, Js, Rs, lam, rows, M, rhs):
        """Solve the differentiated KKT system for (d a or d v+, d lambda) and return (its first
        block (nv, nz), the reported forces' Jacobian (nc, nz)); ``rows``: per foot (constraint rows
        in the foot frame, their rhs in q, their rhs in v or None)."""
        nv = self.nv
        dims = self.force_dims(feet)
        offs = np.cumsum([0] + dims)
        nc = int(offs[-1])
        K = np.zeros((nv + nc, nv + nc))
        K[:nv, :nv] = M
        for i, (Jl, h_q, h_v) in enumerate(rows):
            r = slice(nv + offs[i], nv + offs[i + 1])
            K[:nv, r], K[r, :nv] = -Jl.T, Jl
            rhs[r, :nv] = h_q
            if h_v is not None:
                rhs[r, nv:2 * nv] = h_v
        sol = -(np.linalg.inv(K) @ rhs)
        local = [self._local_forces(f, R, lam[offs[i]:offs[i + 1]]) for i, (f, R) in enumerate(zip(feet, Rs))]
        Lz = np.vstack([self._reported_force_jacobian(f, Rs[i], Js[i], local[i], sol[nv + offs[i]:nv + offs[i + 1]])
                        for i, f in enumerate(feet)])
        return sol[:nv], Lz

    def _contact_general(self, q, v, u, feet, derivatives):
        """:meth:`contact` with feet of any kind (3d points and 6d flat feet)."""
        m, d, dt, nv = self.model, self.data, self.dt, self.nv
        pin.computeAllTerms(m, d, q, v)
        pin.updateFramePlacements(m, d)
        Js = [pin.getFrameJacobian(m, d, f, LOCAL) for f in feet]
        Rs = [d.oMf[f].rotation.copy() for f in feet]
        vfs = [pin.getFrameVelocity(m, d, f, LOCAL) for f in feet]
        tau = self.S @ u
        Jc = np.vstack([self._rows(f, R, J) for f, R, J in zip(feet, Rs, Js)])
        a0 = np.concatenate([self._drift(f, R, vf) for f, R, vf in zip(feet, Rs, vfs)])
        a = pin.forwardDynamics(m, d, tau, Jc, a0, 0.0).copy()
        lam = d.lambda_c.copy()
        v_next = v + a * dt
        w = v * dt + a * (dt * dt)
        q_next = pin.integrate(m, q, w)
        ev = NodeEval(q_next, v_next, lam, acc=a)
        if not derivatives:
            return ev
        Kp, Kd = self.gains
        dims = self.force_dims(feet)
        offs = np.cumsum([0] + dims)
        local = [self._local_forces(f, R, lam[offs[i]:offs[i + 1]]) for i, (f, R) in enumerate(zip(feet, Rs))]
        dtau_dq, dtau_dv, M = pin.computeRNEADerivatives(m, d, q, v, a, self._fext(feet, local))
        M = _symmetric_from_upper(M)
        nz = 2 * nv + self.nu
        rhs = np.zeros((nv + int(offs[-1]), nz))
        rhs[:nv, :nv], rhs[:nv, nv:2 * nv], rhs[:nv, 2 * nv:] = dtau_dq, dtau_dv, -self.S
        pin.computeForwardKinematicsDerivatives(m, d, q, v, a)
        rows = []
        for f, J, R, vf in zip(feet, Js, Rs, vfs):
            V_dq, A_dq, A_dv, _ = pin.getFrameAccelerationDerivatives(m, d, f, LOCAL)
            if self.kind(f) == "3d":  # the classical acceleration: a_lin + w x v_lin
                Wx, Vx = skew(vf.angular), skew(vf.linear)
                h_q = A_dq[:3] + Wx @ V_dq[:3] - Vx @ V_dq[3:]
                h_v = A_dv[:3] + Wx @ J[:3] - Vx @ J[3:]
                if Kp != 0.0:
                    h_q = h_q + Kp * (skew(R.T @ d.oMf[f].translation) @ J[3:] + J[:3])
                if Kd != 0.0:
                    h_q, h_v = h_q + Kd * V_dq[:3], h_v + Kd * J[:3]
                rows.append((J[:3], h_q, h_v))
            else:  # the spatial acceleration
                h_q, h_v = A_dq.copy(), A_dv.copy()
                if Kp != 0.0:
                    h_q += Kp * (pin.Jlog6(d.oMf[f]) @ J)
                if Kd != 0.0:
                    h_q += Kd * V_dq
                    h_v += Kd * J
                rows.append((J, h_q, h_v))
        da, Lz = self._kkt_first(feet, Js, Rs, lam, rows, M, rhs)
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

    def _impulse_general(self, q, v, feet, derivatives):
        """:meth:`impulse` with feet of any kind (Crocoddyl's ImpulseModel3D / ImpulseModel6D)."""
        m, d, nv = self.model, self.data, self.nv
        pin.computeAllTerms(m, d, q, v)
        pin.updateFramePlacements(m, d)
        Js = [pin.getFrameJacobian(m, d, f, LOCAL) for f in feet]
        Rs = [d.oMf[f].rotation.copy() for f in feet]
        Jc = np.vstack([self._rows(f, R, J) for f, R, J in zip(feet, Rs, Js)])
        pin.impulseDynamics(m, d, v, Jc, 0.0, self.impulse_damping)
        v_next, imp = d.dq_after.copy(), d.impulse_c.copy()
        ev = NodeEval(q.copy(), v_next, imp)
        if not derivatives:
            return ev
        dims = self.force_dims(feet)
        offs = np.cumsum([0] + dims)
        local = [self._local_forces(f, R, imp[offs[i]:offs[i + 1]]) for i, (f, R) in enumerate(zip(feet, Rs))]
        dtau_dq, _, M = pin.computeRNEADerivatives(m, d, q, np.zeros(nv), v_next - v, self._fext(feet, local))
        dtau_dq = dtau_dq.copy()
        M = _symmetric_from_upper(M)
        dg_dq = pin.computeGeneralizedGravityDerivatives(m, d, q)
        nz = 2 * nv + self.nu
        rhs = np.zeros((nv + int(offs[-1]), nz))
        rhs[:nv, :nv] = dtau_dq - dg_dq
        rhs[:nv, nv:2 * nv] = -M
        pin.computeForwardKinematicsDerivatives(m, d, q, v_next, np.zeros(nv))
        rows = []
        for f, J, k in zip(feet, Js, dims):
            v_dq, _ = pin.getFrameVelocityDerivatives(m, d, f, LOCAL)
            rows.append((J[:k], v_dq[:k], None))
        dvn, Lz = self._kkt_first(feet, Js, Rs, imp, rows, M, rhs)
        Fz = np.zeros((2 * nv, nz))
        Fz[:nv, :nv] = np.eye(nv)
        Fz[nv:] = dvn
        ev.Fz, ev.Lz, ev.Az = Fz, Lz, dvn
        return ev

    def _rot_model(self, f: int):
        """A massless copy of the robot with a unit rotational inertia (no mass) on the body of
        frame f, and no gravity: its RNEA is J_ang^T w'(q, v, a) (the body's Euler equation; the
        angular velocity's cross term vanishes for the identity inertia), whose free flyer's
        rotational rows give the world angular acceleration oR_b tau[3:6]."""
        aux = self._aux_models()
        key = ("rotation", f)
        if aux["feet"].get(key) is None:
            mr = pin.Model(self.model)
            for j in range(mr.njoints):
                mr.inertias[j] = pin.Inertia.Zero()
            mr.inertias[mr.frames[f].parentJoint] = pin.Inertia(0.0, np.zeros(3), np.eye(3))
            mr.gravity = pin.Motion.Zero()
            aux["feet"][key] = (mr, mr.createData())
        return aux["feet"][key]

    def _frame_terms(self, f: int, rotation: bool, q: np.ndarray, v: np.ndarray, a: np.ndarray):
        """Frame f's world linear acceleration p''(q, v, a) of its origin (``rotation`` False; the
        point-mass model) or its world angular acceleration w'(q, v, a) (True; the rotational
        model), with derivatives in the right chart: (value (3,), d/dq, d/dv, d/da (3, nv),
        qq, qv, qa, vv (3, nv, nv), qq symmetric). As :meth:`_point_terms`: oR_b times the free
        flyer's rows of the auxiliary model's RNEA, the product rule on oR_b(q exp(eta))."""
        mf, df = self._rot_model(f) if rotation else self._foot_model(f)
        rows = slice(3, 6) if rotation else slice(0, 3)
        w = pin.rnea(mf, df, q, v, a)[rows].copy()
        dq, dv, M = pin.computeRNEADerivatives(mf, df, q, v, a)
        Wq, Wv, Wa = dq[rows].copy(), dv[rows].copy(), _symmetric_from_upper(M)[rows]
        qq, vv, qv, aq = _core.rnea_second_order(mf, q, v, a, False)
        qq = 0.5 * (qq[rows] + qq[rows].transpose(0, 2, 1))
        qv, qa, vv = qv[rows].copy(), aq[rows].transpose(0, 2, 1).copy(), vv[rows].copy()
        G = _GENERATORS
        Gq = np.einsum("iab,bj->aij", G, Wq)
        qq[:, 3:6, :] += Gq
        qq[:, :, 3:6] += Gq.transpose(0, 2, 1)
        GG = np.einsum("iab,jbc,c->aij", G, G, w)
        qq[:, 3:6, 3:6] += 0.5 * (GG + GG.transpose(0, 2, 1))
        qv[:, 3:6, :] += np.einsum("iab,bk->aik", G, Wv)
        qa[:, 3:6, :] += np.einsum("iab,bk->aik", G, Wa)
        Jq = Wq.copy()
        Jq[:, 3:6] += np.einsum("iab,b->ai", G, w)
        R = pin.XYZQUATToSE3(q[:7]).rotation

        def rot(T):
            return np.einsum("ab,bjk->ajk", R, T)

        return R @ w, R @ Jq, R @ Wv, R @ Wa, rot(qq), rot(qv), rot(qa), rot(vv)

    @staticmethod
    def _cross_second(W, P, nv: int) -> np.ndarray:
        """(3, 2 nv, 2 nv): second derivatives in s = (q, v) of w x p' with w = J_ang,w(q) v and
        p' = J_w(q) v (``W``, ``P``: :meth:`_frame_terms` at (q, 0, v), both linear in v)."""
        def s_form(T):
            D = np.hstack([T[1], T[3]])
            H = np.zeros((3, 2 * nv, 2 * nv))
            H[:, :nv, :nv], H[:, :nv, nv:], H[:, nv:, :nv] = T[4], T[6], T[6].transpose(0, 2, 1)
            return T[0], D, H

        w, Dw, Hw = s_form(W)
        p, Dp, Hp = s_form(P)
        X = np.einsum("sab,ax,by->sxy", _EPS, Dw, Dp)
        return np.einsum("sab,axy,b->sxy", _EPS, Hw, p) + np.einsum("sab,a,bxy->sxy", _EPS, w, Hp) + X \
            + X.transpose(0, 2, 1)

    def _second_general(self, q, v, feet, ev, impulse: bool):
        """:meth:`contact_second` / :meth:`impulse_second` with feet of any kind. A 6D foot's
        condition in the world frame is E2 = (p''(q, v, a + Kd v) - w x p', w'(q, v, a + Kd v))
        (its foot-frame spatial condition rotated: R d/dt(v_lin) = p'' - w x p'), its forces'
        term J_w^T f + J_ang,w^T t, the torques' q-q block from the rotational model at rest under
        the angular gravity -t (its RNEA is then J_ang,w^T t)."""
        nv = self.nv
        Kp, Kd = self.gains
        if any(self.kind(f) == "6d_local" for f in feet):
            raise InputError("contact_kinds", "the exact second order takes 6D contacts in world-aligned axes ('6d')")
        if not impulse and Kp != 0.0 and any(self.kind(f) == "6d" for f in feet):
            raise InputError("gains", "the exact second order of a 6D contact takes Kp = 0 (Crocoddyl's biped: (0, 30))")
        dims = self.force_dims(feet)
        offs = np.cumsum([0] + dims)
        nc = int(offs[-1])
        ny = nv + nc
        Q, V = slice(0, nv), slice(nv, 2 * nv)
        Hss, Hsy = np.zeros((ny, 2 * nv, 2 * nv)), np.zeros((ny, 2 * nv, ny))
        zero = np.zeros(nv)
        if impulse:
            m0, _ = self._aux_models()["zero_gravity"]
            qq, _, _, aq = _core.rnea_second_order(m0, q, zero, ev.v_next - v, False)
            Hss[:nv, Q, Q] = 0.5 * (qq + qq.transpose(0, 2, 1))
            Hsy[:nv, Q, :nv] = aq.transpose(0, 2, 1)
            Hss[:nv, V, Q], Hss[:nv, Q, V] = -aq, -aq.transpose(0, 2, 1)
            vs, as_ = zero, ev.v_next
        else:
            qq, vv, qv, aq = _core.rnea_second_order(self.model, q, v, ev.acc, False)
            Hss[:nv, Q, Q] = 0.5 * (qq + qq.transpose(0, 2, 1))
            Hss[:nv, Q, V], Hss[:nv, V, Q], Hss[:nv, V, V] = qv, qv.transpose(0, 2, 1), vv
            Hsy[:nv, Q, :nv] = aq.transpose(0, 2, 1)
            vs, as_ = v, ev.acc + Kd * v
        lin = np.concatenate([ev.forces[o:o + 3] for o in offs[:-1]])
        self._force_terms(Hss, q, feet, lin, Q)
        Jw = np.zeros((nc, nv))
        for i, f in enumerate(feet):
            o = int(offs[i])
            blocks = [(slice(nv + o, nv + o + 3), self._frame_terms(f, False, q, vs, as_), o)]
            if dims[i] == 6:
                blocks.append((slice(nv + o + 3, nv + o + 6), self._frame_terms(f, True, q, vs, as_), o + 3))
                mr, _ = self._rot_model(f)
                mr.gravity = pin.Motion(np.zeros(3), -ev.forces[o + 3:o + 6])
                try:
                    gqq = _core.rnea_second_order(mr, q, zero, zero, False)[0]
                finally:
                    mr.gravity = pin.Motion.Zero()
                Hss[:nv, Q, Q] -= 0.5 * (gqq + gqq.transpose(0, 2, 1))
            for r, T, c in blocks:
                Jw[c:c + 3] = T[3]
                Hss[r, Q, Q] = T[4]
                if not impulse:
                    if dims[i] == 3 and Kp != 0.0:
                        Hss[r, Q, Q] += Kp * 0.5 * (T[6] + T[6].transpose(0, 2, 1))
                    Hss[r, Q, V] = T[5] + Kd * T[6]
                    Hss[r, V, Q] = Hss[r, Q, V].transpose(0, 2, 1)
                    Hss[r, V, V] = T[7]
                Hsy[r, Q, :nv] = T[6]
                Hsy[:nv, Q, nv + c:nv + c + 3] = -T[6].transpose(2, 1, 0)
            if dims[i] == 6 and not impulse:  # the linear rows' - w x p'
                cross = self._cross_second(self._frame_terms(f, True, q, zero, v),
                                           self._frame_terms(f, False, q, zero, v), nv)
                Hss[nv + o:nv + o + 3] -= cross
        return self._kkt_second_split(Hss, Hsy, ev, q, Jw)

    # ------------------------------------------------------------------ quasi-static controls
    def quasi_static(self, q: np.ndarray, feet: tuple[int, ...]) -> np.ndarray:
        """Crocoddyl's ``quasiStatic`` of a contact node: the (nu,) controls that, with the contact
        forces, hold q at rest (least squares of smallest norm of [S, J_c^T] (u, lambda) = g(q))."""
        m, d, nv = self.model, self.data, self.nv
        pin.computeAllTerms(m, d, q, np.zeros(nv))
        pin.updateFramePlacements(m, d)
        g = pin.rnea(m, d, q, np.zeros(nv), np.zeros(nv))
        cols = [self.S] + [self._rows(f, d.oMf[f].rotation, pin.getFrameJacobian(m, d, f, LOCAL)).T for f in feet]
        sol = np.linalg.pinv(np.hstack(cols)) @ g
        return sol[:self.nu].copy()
