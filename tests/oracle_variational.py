"""The tests' oracle of the forward variational Euler step (cpp/dynamics/variational_step.cpp runs it in geoddp):
the step by Newton's method and its derivatives by implicit differentiation, in numpy over
Pinocchio's Python calls, with the kinetic-energy Hessian and R_ww as central differences (the
core differences once, from Pinocchio's second-order RNEA). The equations are in
:mod:`geoddp.models.variational`'s docstring.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from geoddp import lie
from oracle_linalg import symmetric_from_upper
from geoddp.models.variational import NEWTON_MAX_ITER, NEWTON_TOL, StepDidNotConverge, not_converged_message

# Central-difference step for the kinetic-energy Hessian (error ~1e-10 relative, as for the ABA
# second derivatives) and for R_ww, which differentiates a Jacobian that already holds that
# difference: 1e-4 keeps the round-off of the nested difference (~1e-10 / h) near 1e-6 relative
# while the truncation (~h^2) stays below it.
HESSIAN_STEP = 1e-5
JACOBIAN_STEP = 1e-4


@dataclass
class VariationalEuler:
    """The forward variational Euler step of a Pinocchio model: constants only.

    Attributes:
        model: the Pinocchio model (gravity as the scene wants it).
        groups: its joint groups (:func:`geoddp.lie.product.joint_groups`).
        actuation: (nv, m) input map H (generalised forces per input).
        dt: time step, s.
    """

    model: pin.Model
    groups: list
    actuation: np.ndarray
    dt: float
    free_model: pin.Model = field(init=False, repr=False)  # gravity-free copy, for D(q, w)

    def __post_init__(self) -> None:
        self.free_model = self.model.copy()
        self.free_model.gravity = pin.Motion.Zero()

    def create_data(self) -> tuple[pin.Data, pin.Data]:
        """Workspaces for the model and its gravity-free copy."""
        return self.model.createData(), self.free_model.createData()

    # ------------------------------------------------------------------ pieces
    def _D(self, fdata: pin.Data, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        """D(q, w) = d(M(q) w)/dq, (nv, nv), right-trivialised."""
        pin.computeRNEADerivatives(self.free_model, fdata, q, np.zeros_like(w), w)
        return fdata.dtau_dq.copy()

    def _K(self, x: np.ndarray) -> np.ndarray:
        """Jr(x)^-1, (nv, nv), block-diagonal over joints."""
        return lie.block_Jr_inv(self.groups, self.model.nv, x)

    def _dKT(self, x: np.ndarray, K: np.ndarray, p: np.ndarray) -> np.ndarray:
        """d/dx [K(x)^T p] for fixed p, (nv, nv); dK = -K dJr K."""
        D, _ = lie.second_order_tensors(self.groups, self.model.nv, x)
        s = K.T @ p
        return -K.T @ np.einsum("jil,j->il", D, s)

    def _lagrangian_hessian(self, data: pin.Data, fdata: pin.Data, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d/deta [dL/dq(q exp(eta), v)] at eta = 0, (nv, nv): the kinetic part by central
        differences of the analytic D, the gravity part from Pinocchio's analytic derivative."""
        nv, h = self.model.nv, HESSIAN_STEP
        Hk = np.empty((nv, nv))
        for j in range(nv):
            e = np.zeros(nv)
            e[j] = h
            plus = self._D(fdata, pin.integrate(self.model, q, e), v).T @ v
            minus = self._D(fdata, pin.integrate(self.model, q, -e), v).T @ v
            Hk[:, j] = (plus - minus) / (4.0 * h)
        return Hk - pin.computeGeneralizedGravityDerivatives(self.model, data, q)

    def _mass(self, data: pin.Data, q: np.ndarray) -> np.ndarray:
        return symmetric_from_upper(pin.crba(self.model, data, q))

    # ------------------------------------------------------------------ step
    def momentum_before(self, data: pin.Data, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The y-independent part of R: K(dt v)^T M(q) v + dt tau, (nv,)."""
        return self._K(self.dt * v).T @ (self._mass(data, q) @ v) + self.dt * tau

    def _implicit_terms(self, fdata: pin.Data, q_next: np.ndarray, M1: np.ndarray, g1: np.ndarray, y: np.ndarray,
                        b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """R at y, with the y-dependent pieces R_y needs: (R (nv,), K(-dt y), D(q+, y)).

        R = K(-dt y)^T M(q+) y - dt dL/dq(q+, y) - b, dL/dq = 1/2 D(q+, y)^T y - g(q+), with
        M1 = M(q+) and g1 = g(q+) fixed over a step.
        """
        dt = self.dt
        K1 = self._K(-dt * y)
        D1 = self._D(fdata, q_next, y)
        return K1.T @ (M1 @ y) - dt * (0.5 * D1.T @ y - g1) - b, K1, D1

    def _residual_velocity_jacobian(self, K1: np.ndarray, M1: np.ndarray, D1: np.ndarray, y: np.ndarray) -> np.ndarray:
        """R_y = K(-dt y)^T M(q+) - dt d/dx[K(x)^T M y]|_(x=-dt y) - dt D(q+, y)^T, (nv, nv)."""
        dt = self.dt
        return K1.T @ M1 - dt * self._dKT(-dt * y, K1, M1 @ y) - dt * D1.T

    def step(self, data: pin.Data, fdata: pin.Data | None, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step: q (nq,), v (nv,), tau (nv,) generalised forces -> (q+, v+).

        ``fdata`` is a workspace of the gravity-free model (created if None).

        Raises:
            StepDidNotConverge: Newton's method needed more than NEWTON_MAX_ITER iterations.
        """
        dt = self.dt
        if fdata is None:
            fdata = self.free_model.createData()
        q_next = pin.integrate(self.model, q, dt * v)
        b = self.momentum_before(data, q, v, tau)
        M1 = self._mass(data, q_next)
        g1 = pin.computeGeneralizedGravity(self.model, data, q_next).copy()
        # Start from the better of v and the explicit (symplectic) Euler velocity; damped Newton
        # (backtracking on |R|) keeps stiff light links from throwing the iteration off.
        y = v + dt * pin.aba(self.model, data, q_next, v, tau)
        r, K1, D1 = self._implicit_terms(fdata, q_next, M1, g1, y, b)
        r0, K0, D0 = self._implicit_terms(fdata, q_next, M1, g1, v, b)
        if not np.all(np.isfinite(r)) or np.linalg.norm(r0) < np.linalg.norm(r):
            y, r, K1, D1 = v.copy(), r0, K0, D0
        for _ in range(NEWTON_MAX_ITER):
            dy = np.linalg.solve(self._residual_velocity_jacobian(K1, M1, D1, y), r)
            norm_r, alpha = np.linalg.norm(r), 1.0
            while True:
                y_try = y - alpha * dy
                r_try, K_try, D_try = self._implicit_terms(fdata, q_next, M1, g1, y_try, b)
                if np.linalg.norm(r_try) < norm_r or alpha < 1e-6 or alpha * np.linalg.norm(dy) <= NEWTON_TOL * (1.0 + np.linalg.norm(y)):
                    break
                alpha *= 0.5
            y, r, K1, D1 = y_try, r_try, K_try, D_try
            if not np.all(np.isfinite(y)):
                break
            if alpha == 1.0 and np.linalg.norm(dy) <= NEWTON_TOL * (1.0 + np.linalg.norm(y)):
                return q_next, y
        raise StepDidNotConverge(not_converged_message(dt, f"{np.linalg.norm(v):.3g}"))

    # ------------------------------------------------------------------ derivatives
    def _residual_jacobian(self, data: pin.Data, fdata: pin.Data, q: np.ndarray, v: np.ndarray, y: np.ndarray) -> np.ndarray:
        """[R_eta, R_dv, R_y], (nv, 3 nv), at any (q, v, y) (not only solutions)."""
        model, dt, nv = self.model, self.dt, self.model.nv
        omega = dt * v
        q_next = pin.integrate(model, q, omega)
        A, Jv = lie.block_Ad_Jr(self.groups, nv, omega)  # Ad_exp(-dt v): eta -> eta+, and Jr(dt v)
        K1 = self._K(-dt * y)
        M1 = self._mass(data, q_next)
        D1 = self._D(fdata, q_next, y)
        S = K1.T @ D1 - dt * self._lagrangian_hessian(data, fdata, q_next, y)  # dR/deta+
        M0 = self._mass(data, q)
        K0 = self._K(omega)
        J = np.empty((nv, 3 * nv))
        J[:, :nv] = S @ A - K0.T @ self._D(fdata, q, v)
        J[:, nv : 2 * nv] = dt * (S @ Jv) - K0.T @ M0 - dt * self._dKT(omega, K0, M0 @ v)
        J[:, 2 * nv :] = self._residual_velocity_jacobian(K1, M1, D1, y)
        return J

    def velocity_derivatives(
        self, Q: np.ndarray, V: np.ndarray, V_next: np.ndarray, controls: np.ndarray, order: int = 1
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Derivatives of v+ = f(q, v, u) w.r.t. z = (dq, dv, du) at N nodes, by implicit
        differentiation of R = 0 (paper eq. firstimp and the Hessian after it).

        Q (N, nq), V (N, nv), V_next (N, nv) the solved v+, controls (N, m) -> F1 (N, nv, nz),
        F2 (N, nv, nz, nz) or None, nz = 2 nv + m; F2 is the symmetric (0)-Hessian.
        """
        model, nv, Hm, dt = self.model, self.model.nv, self.actuation, self.dt
        N, m = controls.shape
        nz, nw = 2 * nv + m, 3 * nv
        data, fdata = self.create_data()
        F1 = np.empty((N, nv, nz))
        F2 = np.empty((N, nv, nz, nz)) if order >= 2 else None
        h = JACOBIAN_STEP
        for k in range(N):
            q, v, y = Q[k], V[k], V_next[k]
            J = self._residual_jacobian(data, fdata, q, v, y)
            Ry = J[:, 2 * nv :]
            Rz = np.concatenate([J[:, : 2 * nv], -dt * Hm], axis=1)
            F1[k] = -np.linalg.solve(Ry, Rz)
            if F2 is None:
                continue
            T = np.empty((nv, nw, nw))
            for j in range(nw):
                e = np.zeros(nw)
                e[j] = h
                plus = self._residual_jacobian(data, fdata, pin.integrate(model, q, e[:nv]), v + e[nv : 2 * nv], y + e[2 * nv :])
                minus = self._residual_jacobian(data, fdata, pin.integrate(model, q, -e[:nv]), v - e[nv : 2 * nv], y - e[2 * nv :])
                T[:, :, j] = (plus - minus) / (2.0 * h)
            # Differentiating the right-trivialised Jacobian along integrate(q, h e_j) adds an
            # antisymmetric bracket term to the eta-eta block: the symmetric part is the
            # (0)-Hessian. R is affine in u, so u enters only through P.
            T = 0.5 * (T + np.swapaxes(T, 1, 2))
            P = np.zeros((nw, nz))
            P[: 2 * nv, : 2 * nv] = np.eye(2 * nv)
            P[2 * nv :] = F1[k]
            F2[k] = -np.linalg.solve(Ry, np.einsum("ai,pab,bj->pij", P, T, P).reshape(nv, nz * nz)).reshape(nv, nz, nz)
        return F1, F2
