"""Frame kinematics with first and contracted second derivatives along the group, over N nodes.

The constraints need, for a frame f of a Pinocchio model at configurations Q (N, nq), a few
residuals of its placement oMf(q) and, for weights w (N, nr), their Jacobians J_r (N, nr, nv) in
the tangent coordinates dq of ``pin.integrate`` and the contracted Hessian

    sum_i w_i Hess r_i   (N, nv, nv),  the symmetric second derivative along q exp(s dq),

which is exactly what a residual cost 1/2 r^T W r needs beyond J_r^T W J_r (with w = W r), and
what the augmented Lagrangian needs with w = the multiplier estimate (geoddp.constraints.augmented).

The one expansion all of them rest on (the derivation of the compiled cost kernels, cpp/costs/costs.cpp):
along q(s) = q exp(s dq) the frame moves as

    oMf(q(s)) = oMf exp(xi(s)),   xi(s) = s J dq + s^2 / 2 Hk(dq, dq) + O(s^3),

with J the frame's LOCAL Jacobian (6, nv) and Hk(dq, dq)_r = sum_ik H[r, i, k] dq_i dq_k the
frame's LOCAL kinematic Hessian (Pinocchio's getFrameKinematicHessian); the Lie-bracket term of the
exponential is antisymmetric and drops out of the symmetric second derivative. Each residual then
adds its own second-order term:

    body vector a (frame coordinates) in the world, y = R_f a = R_f exp(theta(s)) a, theta = xi_ang:
        d2(w.y) = g.Hk_ang(dq, dq) + (J_a dq)^T [sym(a b^T) - (a.b) I] (J_a dq),
        b = R_f^T w, g = a x b                                      (:meth:`FrameKinematics.vector`)
    origin p (world, m), p(s) = p + R_f (xi_lin + 1/2 hat(xi_ang) xi_lin + O(3)):
        d2(w.p) = u.Hk_lin(dq, dq) + u.((J_a dq) x (J_l dq)),  u = R_f^T w
                                                                    (:meth:`FrameKinematics.point`)
    log6 of M_ref^-1 oMf (6,), r(s) = x + Ji xi - 1/2 Ji dJr(x)[Ji xi] (Ji xi) + O(3), Ji = Jr(x)^-1:
        sum_i w_i Hess r_i = sum_p g_p Hk_p - A^T D_g A,  g = Ji^T w, A = Ji J,
        D_g[a, b] = sum_p g_p dJr(x)[p, a] / dx_b                   (:meth:`FrameKinematics.log6`)

dJr is the compiled core's exact SE(3) derivative (``se3_jr_derivative``: forward-mode dual
numbers through the closed form, Taylor branches included), so nothing is differenced, near the
identity and up to a relative rotation of pi alike. The per-node loop is Python over Pinocchio
(the compiled cost kernels do the same in C++; moving these there is the next step): the kinematic
Hessians are computed only at nodes whose weights are not all zero (an inactive inequality).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from .. import kernels
from ..lie import hat

__all__ = ["FrameKinematics", "Frames", "frame_kinematic_hessian", "sym"]


def sym(A: np.ndarray) -> np.ndarray:
    """(A + A^T) / 2 over the last two axes."""
    return 0.5 * (A + np.swapaxes(A, -1, -2))


#: (R (N, 3, 3), p (N, 3), J (N, 6, nv)): a frame's placements and LOCAL Jacobians at N nodes
Frames = tuple[np.ndarray, np.ndarray, np.ndarray]
#: residual weights (N, nr), a function of the residual (N, nr) giving them, or None
Weights = np.ndarray | Callable[[np.ndarray], np.ndarray] | None


def frame_kinematic_hessian(model: pin.Model, data: pin.Data, frame_id: int) -> np.ndarray:
    """The frame's LOCAL kinematic Hessian H (6, nv, nv), H[r, i, k] = d J_LOCAL[r, i] / d q_k along
    q exp(s e_k), after ``computeJointKinematicHessians``.

    Pinocchio 4.1's binding hands the Eigen tensor (column-major, H(r, i, k) at r + 6 i + 6 nv k)
    over as a C-ordered array of the same shape without reordering its memory: read in C order it
    is a permutation of H. The memory is reinterpreted here in the tensor's own (Fortran) order;
    tests/test_constraints_derivatives.py checks the result against differences of the Jacobian,
    so a binding that changes this fails there, not silently."""
    raw = pin.getFrameKinematicHessian(model, data, frame_id, pin.LOCAL)
    return np.asarray(raw).reshape(-1).reshape((6, model.nv, model.nv), order="F")


class FrameKinematics:
    """Placement, LOCAL Jacobian and contracted kinematic Hessian of one frame at N configurations.

    Args:
        model: the ``pin.Model``.
        frame_id: the frame's index in ``model.frames``.

    A pinocchio Data is made once and kept (Crocoddyl's model/data split: the constraint holds the
    model, this helper the workspace).
    """

    def __init__(self, model: pin.Model, frame_id: int) -> None:
        self.model = model
        self.frame_id = int(frame_id)
        self.data = model.createData()
        self.nv = int(model.nv)

    # ---------------------------------------------------------------- the frame itself
    def placements(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (N, 3, 3) and origins (N, 3) (m) of the frame at Q (N, nq)."""
        N = Q.shape[0]
        R, p = np.empty((N, 3, 3)), np.empty((N, 3))
        m, d = self.model, self.data
        for n in range(N):
            pin.forwardKinematics(m, d, Q[n])
            M = pin.updateFramePlacement(m, d, self.frame_id)
            R[n], p[n] = M.rotation, M.translation
        return R, p

    def jacobians(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(R (N, 3, 3), p (N, 3), J (N, 6, nv)): placements and LOCAL Jacobians [linear; angular]."""
        N = Q.shape[0]
        R, p, J = np.empty((N, 3, 3)), np.empty((N, 3)), np.empty((N, 6, self.nv))
        m, d = self.model, self.data
        for n in range(N):
            pin.computeJointJacobians(m, d, Q[n])  # also the forward kinematics
            M = pin.updateFramePlacement(m, d, self.frame_id)
            R[n], p[n] = M.rotation, M.translation
            J[n] = pin.getFrameJacobian(m, d, self.frame_id, pin.LOCAL)
        return R, p, J

    def hessian_contraction(self, Q: np.ndarray, g6: np.ndarray) -> np.ndarray:
        """S (N, nv, nv) = sym(sum_r g6[n, r] H[r]) with H the LOCAL kinematic Hessian (6, nv, nv)
        of the frame at Q[n]; exactly 0 (nothing computed) where g6[n] = 0."""
        N = Q.shape[0]
        S = np.zeros((N, self.nv, self.nv))
        m, d = self.model, self.data
        for n in np.flatnonzero(np.any(g6 != 0.0, axis=1)):
            pin.computeJointJacobians(m, d, Q[n])
            pin.computeJointKinematicHessians(m, d)
            S[n] = np.tensordot(g6[n], frame_kinematic_hessian(m, d, self.frame_id), axes=1)
        return sym(S)

    # ---------------------------------------------------------------- residuals
    def vector(self, Q: np.ndarray, a: np.ndarray, w: np.ndarray | None = None, frames: Frames | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The frame's unit vector ``a`` (3,) in the world, y = R_f a.

        Returns y (N, 3), its Jacobian dy/ddq (N, 3, nv) = -R_f hat(a) J_ang and, for world
        weights w (N, 3), sum_i w_i Hess y_i (N, nv, nv) (else None). ``frames``: the result of
        :meth:`jacobians` at Q when already computed."""
        R, _, J = self.jacobians(Q) if frames is None else frames
        y = R @ a
        Ja = J[:, 3:]
        Jy = -np.einsum("nij,jk,nkl->nil", R, hat(a), Ja)
        if w is None:
            return y, Jy, None
        b = np.einsum("nji,nj->ni", R, w)  # R_f^T w
        # y(s) = R_f exp(hat(theta)) a: w.y'' = b.(theta'' x a) + b^T hat(theta')^2 a, with
        # theta' = J_ang dq, theta'' = Hk_ang(dq, dq); b^T hat(x)^2 a = x^T [sym(a b^T) - (a.b) I] x
        g6 = np.zeros((Q.shape[0], 6))
        g6[:, 3:] = np.cross(a, b)  # b.(t x a) = t.(a x b)
        Hth = sym(np.einsum("i,nj->nij", a, b)) - np.einsum("ni,i->n", b, a)[:, None, None] * np.eye(3)
        return y, Jy, sym(np.einsum("nai,nab,nbj->nij", Ja, Hth, Ja)) + self.hessian_contraction(Q, g6)

    def point(self, Q: np.ndarray, w: np.ndarray | None = None, frames: Frames | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The frame's origin p (N, 3) in the world (m), its Jacobian (N, 3, nv) = R_f J_lin and,
        for world weights w (N, 3), sum_i w_i Hess p_i (N, nv, nv) (else None). ``frames``: as
        for :meth:`vector`."""
        R, p, J = self.jacobians(Q) if frames is None else frames
        Jl, Ja = J[:, :3], J[:, 3:]
        Jp = R @ Jl
        if w is None:
            return p, Jp, None
        u = np.einsum("nji,nj->ni", R, w)  # R_f^T w
        # p(s) = p + R_f (xi_lin + 1/2 hat(xi_ang) xi_lin + O(3)): w.p'' = u.Hk_lin(dq, dq)
        # + u.((J_a dq) x (J_l dq)), and u.(x x y) = -x^T hat(u) y
        g6 = np.zeros((Q.shape[0], 6))
        g6[:, :3] = u
        cross = -np.einsum("nai,nab,nbj->nij", Ja, hat(u), Jl)
        return p, Jp, sym(cross) + self.hessian_contraction(Q, g6)

    def log6_value(self, Q: np.ndarray, M_ref: np.ndarray) -> np.ndarray:
        """r = log6(M_ref^-1 oMf) (N, 6) alone (the forward kinematics, no Jacobian): :meth:`log6`'s r."""
        return _log6_residuals(*self.placements(Q), M_ref)

    def log6(self, Q: np.ndarray, M_ref: np.ndarray, w: Weights = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """r = log6(M_ref^-1 oMf) (N, 6) [linear (m); angular (rad)], the residual of the
        frame_placement cost (geoddp.costs.multibody.FramePlacement), its Jacobian Jr(r)^-1 J
        (N, 6, nv) and, for weights w (N, 6), sum_i w_i Hess r_i (N, nv, nv) (else None).

        M_ref: (4, 4) homogeneous target placement. ``w`` may also be a function of r giving
        the weights (the augmented Lagrangian's multiplier estimates depend on r)."""
        N = Q.shape[0]
        R, p, J = self.jacobians(Q)
        r = _log6_residuals(R, p, M_ref)
        Jr_res = np.empty((N, 6, self.nv))
        Ji = np.empty((N, 6, 6))
        for n in range(N):
            Ji[n] = kernels.se3_right_jacobian(r[n], True)
            Jr_res[n] = Ji[n] @ J[n]
        if callable(w):
            w = w(r)
        if w is None:
            return r, Jr_res, None
        g = np.einsum("nji,nj->ni", Ji, w)  # Ji^T w
        S = self.hessian_contraction(Q, np.where(np.any(w != 0.0, axis=1)[:, None], g, 0.0))
        for n in np.flatnonzero(np.any(w != 0.0, axis=1)):
            D = kernels.core.se3_jr_derivative(r[n]).reshape(6, 6, 6)  # D[p, a, b] = dJr[p, a] / dx_b
            Dg = np.tensordot(g[n], D, axes=1)
            S[n] -= sym(Jr_res[n].T @ Dg @ Jr_res[n])
        return r, Jr_res, S


def _log6_residuals(R: np.ndarray, p: np.ndarray, M_ref: np.ndarray) -> np.ndarray:
    """log6(M_ref^-1 (R_n, p_n)) (N, 6) [linear; angular] of N placements."""
    Mref_inv = pin.SE3(M_ref[:3, :3], M_ref[:3, 3]).inverse()
    r = np.empty((R.shape[0], 6))
    for n in range(R.shape[0]):
        if np.array_equal(R[n], M_ref[:3, :3]):
            # the reference orientation reached exactly: as the cost kernel, the identity
            # keeps the rotation residual exactly 0 (R_ref^T R would leave round-off)
            E = pin.SE3(np.eye(3), M_ref[:3, :3].T @ (p[n] - M_ref[:3, 3]))
        else:
            E = Mref_inv * pin.SE3(R[n], p[n])
        r[n] = pin.log6(E).vector
    return r
