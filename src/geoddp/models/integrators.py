"""Euler integrators on a Lie group x velocities and their first- and second-order expansions
(paper Section IV), written once for any product group (:mod:`geoddp.lie.product`).

A state g = (q, v) on G x R^nv moves by a velocity map v+ = f(q, v, u) and a reconstruction
q+ = q exp(dt w), where w = v (explicit Euler, paper eq. disceq) or w = v+ (semi-implicit Euler,
Crocoddyl's). The satellite is the instance G = SO(3), q = R, v = Omega (TSO(3),
:class:`geoddp.lie.TSO3`); a Pinocchio model is the product of its joints' groups. Perturbations
are zeta = (eta, delta v) with q = q_bar exp(eta); z = (zeta, delta u) stacks state and control
perturbations.

Exact second-order expansion of the reconstruction. With omega = dt w_bar, A = exp(-omega),
rho = dt delta w and exp(omega + rho) = exp(omega) exp(nu(rho)):

    exp(eta+) = exp(-omega) exp(eta) exp(omega + rho) = exp(Ad_A eta) exp(nu(rho)),
    nu(rho)   = Jr(omega) rho + 1/2 dJr(omega)[rho] rho + O(3),
    eta+      = Ad_A eta + nu(rho) + 1/2 [Ad_A eta, Jr(omega) rho] + O(3)      (BCH).

The last line needs nothing beyond BCH at second order, so it holds for any dt. In particular,
with delta w = 0, eta+ = Ad_A eta exactly: there is no eta-eta term. The paper's Omega_ij
(appendix, eq. etamatrixterms) is an O(dt) approximation of this zero; it is available as
``second_order="paper"`` for the explicit Euler scheme, for comparison only.

On a product group, Ad_A, Jr and dJr are block-diagonal over the factors and the bracket
vanishes across factors and on commutative ones (:func:`expand`).

Array layout over the horizon (N nodes, n = 2 nv state (6 for TSO(3)), m inputs, nz = n + m):
Phi (N, n, n), B (N, n, m), Theta (N, n, n, n), Gamma (N, n, n, m), Xi (N, n, m, m), with
zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..lie import NONCOMMUTATIVE, SO3, JointGroup, block_Ad_Jr, group_second_order_tensors, hat

INTEGRATORS = ("euler", "semi_implicit")
SECOND_ORDER_KINDS = ("exact", "paper")


@dataclass
class Expansion:
    """Linearisation (and optionally second-order terms) of zeta+ along a trajectory.

    Shapes as in the module docstring; second-order arrays are None for a first-order expansion.
    """

    Phi: np.ndarray
    B: np.ndarray
    Theta: np.ndarray | None = None
    Gamma: np.ndarray | None = None
    Xi: np.ndarray | None = None
    # Compiled multibody models may keep the second-order terms factored instead (Theta, Gamma, Xi
    # then None): a geoddp._core.SecondOrderTerms, contracted with V_x' by the backward pass.
    terms: Any = None

    @classmethod
    def from_blocks(cls, n: int, G1: np.ndarray, G2: np.ndarray | None = None) -> "Expansion":
        """Contiguous Phi, B from the Jacobian G1 (H, n, n + m) of zeta+ in (zeta, du), and Theta,
        Gamma, Xi from its Hessian G2 (H, n, n + m, n + m) if given."""
        c = np.ascontiguousarray
        if G2 is None:
            return cls(c(G1[:, :, :n]), c(G1[:, :, n:]))
        return cls(c(G1[:, :, :n]), c(G1[:, :, n:]), c(G2[:, :, :n, :n]), c(G2[:, :, :n, n:]), c(G2[:, :, n:, n:]))


def expand(
    groups: Sequence[JointGroup],
    dt: float,
    w_bar: np.ndarray,
    F1: np.ndarray,
    F2: np.ndarray | None,
    semi_implicit: bool,
) -> Expansion:
    """The expansion of zeta+ = (eta+, dv+) from the velocity map's derivatives, on any product group.

    eta+ = Ad_A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [Ad_A eta, Jr rho] (module docstring), with
    rho = dt delta w and delta w = delta v (euler) or delta v+ = F1 z + 1/2 F2(z, z) (semi-implicit).

    Args:
        groups: the configuration group as its factors in tangent order (nv = their total
            dimension; :func:`geoddp.lie.joint_groups`, or :data:`geoddp.lie.SO3_ROOT` for TSO(3)).
        dt: time step (s), > 0.
        w_bar: (N, nv) nominal reconstruction velocity, see :func:`reconstruction_velocity`.
        F1: (N, nv, nz) Jacobian of v+ w.r.t. z = (eta, dv, du), eta right-trivialised, nz = 2 nv + m.
        F2: (N, nv, nz, nz) symmetric (0)-Hessians of v+ w.r.t. z, or None for first order.
        semi_implicit: reconstruct with v+ (True) or v (False).

    Returns:
        :class:`Expansion` with Phi (N, 2 nv, 2 nv), B (N, 2 nv, m) and, when F2 is given,
        Theta, Gamma, Xi.
    """
    H, nv, nz = F1.shape
    n = 2 * nv
    Omega = dt * w_bar
    # First-order part of delta w as a function of z: a selector (euler) or F1 (semi-implicit).
    if semi_implicit:
        W1 = F1
    else:
        W1 = np.zeros((H, nv, nz))
        W1[:, :, nv : 2 * nv] = np.eye(nv)
    A = np.empty((H, nv, nv))  # Ad_exp(-omega), block-diagonal
    Jr = np.empty((H, nv, nv))  # Jr(omega), block-diagonal
    for k in range(H):
        # dIntegrate's ARG0 / ARG1, with the exact SE(3) Jr (geoddp.lie.product)
        A[k], Jr[k] = block_Ad_Jr(groups, nv, Omega[k])
    JW = Jr @ W1
    G1 = np.empty((H, n, nz))
    G1[:, :nv] = dt * JW
    G1[:, :nv, :nv] += A
    G1[:, nv:] = F1
    if F2 is None:
        return Expansion.from_blocks(n, G1)
    G2 = np.empty((H, n, nz, nz))
    G2[:, nv:] = F2
    if semi_implicit:
        # Jr rho's own second-order part: rho = dt (F1 z + 1/2 F2(z, z)); Jr is the identity on
        # commutative factors, so the product is taken per non-commutative factor only
        G2[:, :nv] = dt * F2
        for g in groups:
            if g.kind in NONCOMMUTATIVE:
                s = g.slice
                G2[:, s] = dt * (Jr[:, s, s] @ F2[:, s].reshape(H, -1, nz * nz)).reshape(H, -1, nz, nz)
    else:
        G2[:, :nv] = 0.0
    # dJr and the bracket vanish on commutative factors and across factors, so both terms are
    # assembled per non-commutative factor s (rows p, a, b in s), on all H nodes at once.
    for g in groups:
        if g.kind not in NONCOMMUTATIVE:
            continue
        s = g.slice
        D, C = group_second_order_tensors(g.kind, Omega[:, s])  # (H, d, d, d), (d, d, d)
        Dsym = 0.5 * (D + np.swapaxes(D, 2, 3))
        Ws = W1[:, None, s, :]  # (H, 1, d, nz)
        # 1/2 dJr[rho] rho with rho = dt W1 z: dt^2 W1^T Dsym_p W1 for each row p
        G2[:, s] += (dt * dt) * (np.swapaxes(Ws, 2, 3) @ (Dsym @ Ws))
        # 1/2 [A eta, Jr rho]_p = z^T Mz_p z with eta = z[:nv] and Jr rho = dt JW z:
        # Mz_p = dt/2 A^T C_p JW on the (eta in s, z) block
        Mz = (0.5 * dt) * (np.swapaxes(A[:, None, s, s], 2, 3) @ (C[None] @ JW[:, None, s, :]))  # (H, d, d, nz)
        G2[:, s, s, :] += Mz
        G2[:, s, :, s] += np.swapaxes(Mz, 2, 3)
    return Expansion.from_blocks(n, G1, G2)


def paper_eta_rows(e: Expansion, dt: float, w_bar: np.ndarray) -> None:
    """Replace the eta rows of a TSO(3) second-order expansion by the paper's (eq. etamatrixterms;
    explicit Euler, w_bar = Omega (N, 3)), for comparison: Theta's from Omega_ij and K_ij, Gamma's
    and Xi's zero."""
    e.Theta[:, 0:3] = _paper_theta_eta(dt, w_bar)
    e.Gamma[:, 0:3] = 0.0
    e.Xi[:, 0:3] = 0.0


def _paper_theta_eta(dt: float, xi: np.ndarray) -> np.ndarray:
    """The paper's eta-rows of Theta for explicit Euler (appendix, eq. etamatrixterms).

    Returns (N, 3, 6, 6): Theta_chichi from Omega_ij (symmetrised as in the appendix), Theta_chixi
    from K_ij, Theta_xixi = 0. Here dexp_{-x} = Jr(x) and dexp^{-1}_{x} = Jl(x)^-1 = Jr(-x)^-1.
    """
    N = xi.shape[0]
    omega = dt * xi
    Jr = SO3.right_jacobian_batch(omega)
    Jl_inv = SO3.right_jacobian_inv_batch(-omega)
    E = hat(np.eye(3))  # ad_{E_i}
    adxi = hat(xi)  # (N, 3, 3)
    out = np.zeros((N, 3, 6, 6))
    for n_ in range(N):
        Om = np.zeros((3, 3, 3))  # Om[i, j] = vector Omega_ij
        K = np.zeros((3, 3, 3))
        x = xi[n_]
        ad = adxi[n_]
        DiE = Jl_inv[n_]  # columns: dexp^{-1}_{omega} E_j
        for i in range(3):
            for j in range(3):
                Om[i, j] = (dt / 12.0) * (
                    Jr[n_] @ (E[i] @ (E[j] @ x))
                    + 0.5 * dt * (E[i] @ (ad @ (ad @ np.eye(3)[j])))
                    + 0.5 * dt * (E[i] @ (E[j] @ x))
                    - hat(DiE[:, i]) @ (hat(DiE[:, j]) @ x)
                )
                K[i, j] = 0.5 * dt * (
                    Jr[n_] @ (E[i] @ np.eye(3)[j])
                    + (dt / 6.0) * (ad @ (E[j] @ np.eye(3)[i]) + 2.0 * E[j] @ (ad @ np.eye(3)[i]) + E[i] @ (ad @ np.eye(3)[j]))
                )
        for c in range(3):
            out[n_, c, 0:3, 0:3] = Om[:, :, c] + Om[:, :, c].T
            out[n_, c, 0:3, 3:6] = K[:, :, c]
            out[n_, c, 3:6, 0:3] = K[:, :, c].T
    return out
