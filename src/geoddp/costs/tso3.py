"""Cost terms on TSO(3) x R^m with left-trivialised gradients and (0)-Cartan Hessians.

For a state g = (R, Omega) and the perturbation zeta = (eta, dOmega) of :class:`geoddp.lie.TSO3`,
each term supplies (paper eqs. leftell, trivdif)

    l_x  = T_eL_g^* D_g l           (6,)    d/ds l(g exp(s zeta)) = l_x . zeta
    l_xx = T_eL_g^* Hess^(0) l T_eL (6, 6)  symmetric part of d2/ds1 ds2 l(g exp(s1 z1) exp(s2 z2))
    l_u, l_uu, l_ux                          Euclidean in u.

Every term is evaluated on N nodes at once: R (N, 3, 3), Omega (N, 3), U (N, m) or None
(terminal). Derivatives accumulate into a :class:`CostDerivatives`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..lie import SO3, vee
from ..validate import InputError, finite_array, rotation_matrix, spd_matrix


@dataclass
class CostDerivatives:
    """Cost value and derivatives at N nodes: l (N,), lx (N,nx), lu (N,m), lxx (N,nx,nx),
    lux (N,m,nx), luu (N,m,m); nx = 6 on TSO(3), 2 nv for a multibody. m = 0 for terminal costs."""

    l: np.ndarray
    lx: np.ndarray
    lu: np.ndarray
    lxx: np.ndarray
    lux: np.ndarray
    luu: np.ndarray

    @classmethod
    def zeros(cls, N: int, m: int, nx: int = 6) -> "CostDerivatives":
        """Zero value and derivatives for N nodes, m inputs and an nx-dimensional tangent state."""
        return cls(np.zeros(N), np.zeros((N, nx)), np.zeros((N, m)), np.zeros((N, nx, nx)),
                   np.zeros((N, m, nx)), np.zeros((N, m, m)))


class CostTerm:
    """Base class: ``value`` and ``accumulate`` over N nodes."""

    uses_control = False

    def value(self, R: np.ndarray, Omega: np.ndarray, U: np.ndarray | None) -> np.ndarray:
        """(N,) cost values."""
        raise NotImplementedError

    def accumulate(self, R: np.ndarray, Omega: np.ndarray, U: np.ndarray | None, d: CostDerivatives) -> None:
        """Add this term's value, gradient and (0)-Hessian into ``d``."""
        raise NotImplementedError


class ControlQuadratic(CostTerm):
    """1/2 (u - u_ref)^T S_u (u - u_ref); S_u (m, m) SPD (paper eq. costR, running)."""

    uses_control = True

    def __init__(self, S_u, u_ref=None) -> None:
        S = np.asarray(S_u, dtype=float)
        m = S.shape[0] if S.ndim == 2 else (S.size if S.ndim == 1 else None)
        if m is None:
            raise InputError("cost.control", "expected a length-m vector or an (m, m) matrix (a scalar does not "
                             f"fix the number of inputs m), got {S_u!r}")
        self.S = spd_matrix(S_u, "cost.control", m)
        self.u_ref = np.zeros(m) if u_ref is None else finite_array(u_ref, "cost.u_ref", (m,))

    def value(self, R, Omega, U):
        e = U - self.u_ref
        return 0.5 * np.einsum("ni,ij,nj->n", e, self.S, e)

    def accumulate(self, R, Omega, U, d):
        e = U - self.u_ref
        Se = e @ self.S
        d.l += 0.5 * np.einsum("ni,ni->n", e, Se)
        d.lu += Se
        d.luu += self.S


class AttitudeChordal(CostTerm):
    """1/2 ||I - R_d^T R||^2_{m, S_R} = 1/2 tr[(I - E)^T S_R (I - E)], E = R_d^T R (eq. costR).

    Gradient 2 vee(skew(S_R E)) (eq. gradF), (0)-Hessian sym(tr[S_R E] I - S_R E) (eq. hessF).
    On TSO(3) R is the state's rotation; in a :class:`geoddp.costs.multibody.MultibodyCostSum` the
    same term penalises the world rotation of ``frame`` (it becomes a
    :class:`geoddp.costs.multibody.FrameRotationChordal` with the same S_R and R_d).
    """

    def __init__(self, S_R, R_d, frame: str | None = None) -> None:
        self.S = spd_matrix(S_R, "cost.attitude", 3, semidefinite=True)
        self.R_d = rotation_matrix(R_d, "target.rotation")
        self.frame = frame

    def _E(self, R):
        return np.einsum("ji,njk->nik", self.R_d, R)

    def value(self, R, Omega, U):
        D = np.eye(3) - self._E(R)
        return 0.5 * np.einsum("nji,jk,nki->n", D, self.S, D)

    def accumulate(self, R, Omega, U, d):
        E = self._E(R)
        D = np.eye(3) - E
        d.l += 0.5 * np.einsum("nji,jk,nki->n", D, self.S, D)
        SE = self.S @ E
        d.lx[:, 0:3] += 2.0 * vee(0.5 * (SE - np.swapaxes(SE, 1, 2)))
        tr = np.trace(SE, axis1=1, axis2=2)
        Hm = tr[:, None, None] * np.eye(3) - SE
        d.lxx[:, 0:3, 0:3] += 0.5 * (Hm + np.swapaxes(Hm, 1, 2))


class AttitudeGeodesic(CostTerm):
    """1/2 r^T W r with r = log(R_d^T R) (rad).

    Gradient Jr(r)^-T W r; (0)-Hessian Jr^-T W Jr^-1 + sum_k (W r)_k T_k(r), with T the
    second-order term of log (:meth:`geoddp.lie.SO3.log_second_order_batch`). At exactly pi the
    log is two-valued and the gradient jumps: a geodesic cost has a cut locus there.

    One term for every model backend: on TSO(3) (the closed forms below, compiled) R is the
    state's rotation; in a :class:`geoddp.costs.multibody.MultibodyCostSum` the same term penalises
    the world rotation of ``frame`` through the model's frame kinematics (it becomes a
    :class:`geoddp.costs.multibody.FrameRotation` with the same W and R_d, compiled or python).
    """

    def __init__(self, W, R_d, frame: str | None = None) -> None:
        self.W = spd_matrix(W, "cost.attitude", 3, semidefinite=True)
        self.R_d = rotation_matrix(R_d, "target.rotation")
        self.frame = frame

    def residual(self, R: np.ndarray) -> np.ndarray:
        """(N, 3) r = log(R_d^T R)."""
        return SO3.log_batch(np.einsum("ji,njk->nik", self.R_d, R))

    def value(self, R, Omega, U):
        r = self.residual(R)
        return 0.5 * np.einsum("ni,ij,nj->n", r, self.W, r)

    def accumulate(self, R, Omega, U, d):
        # compiled: a numpy version of these few 3x3 products costs ~0.35 ms of call overhead
        E = np.ascontiguousarray(np.einsum("ji,njk->nik", self.R_d, R))
        g = np.zeros((E.shape[0], 3))
        Hs = np.zeros((E.shape[0], 3, 3))
        kernels.geodesic_attitude_derivatives(E, self.W, d.l, g, Hs)
        d.lx[:, 0:3] += g
        d.lxx[:, 0:3, 0:3] += 0.5 * (Hs + np.swapaxes(Hs, 1, 2))


class AngularVelocityQuadratic(CostTerm):
    """1/2 (Omega - Omega_d)^T S_Omega (Omega - Omega_d) (eq. costR, terminal)."""

    def __init__(self, S_Omega, Omega_d=None) -> None:
        self.S = spd_matrix(S_Omega, "cost.angular_velocity", 3, semidefinite=True)
        self.Omega_d = np.zeros(3) if Omega_d is None else finite_array(Omega_d, "target.angular_velocity", (3,))

    def value(self, R, Omega, U):
        e = Omega - self.Omega_d
        return 0.5 * np.einsum("ni,ij,nj->n", e, self.S, e)

    def accumulate(self, R, Omega, U, d):
        e = Omega - self.Omega_d
        Se = e @ self.S
        d.l += 0.5 * np.einsum("ni,ni->n", e, Se)
        d.lx[:, 3:6] += Se
        d.lxx[:, 3:6, 3:6] += self.S


class CostSum:
    """A sum of terms; the running or the terminal cost of a problem."""

    # The satellite's terms keep the paper's exact expansion at order 1 too (Section VI: its
    # first-order DDP drops only the dynamics' second-order terms), so its solves are the paper's.
    first_order_gauss_newton = False

    def __init__(self, terms: list[CostTerm] | None = None) -> None:
        self.terms: list[CostTerm] = list(terms or [])

    def value(self, R: np.ndarray, Omega: np.ndarray, U: np.ndarray | None) -> np.ndarray:
        """(N,) summed values."""
        out = np.zeros(R.shape[0])
        for t in self.terms:
            out += t.value(R, Omega, U)
        return out

    def derivatives(self, R: np.ndarray, Omega: np.ndarray, U: np.ndarray | None) -> CostDerivatives:
        """Summed :class:`CostDerivatives` at the N nodes."""
        m = 0 if U is None else U.shape[1]
        d = CostDerivatives.zeros(R.shape[0], m)
        for t in self.terms:
            if t.uses_control and U is None:
                raise ValueError("a control cost term cannot be part of a terminal cost")
            t.accumulate(R, Omega, U, d)
        return d
