"""Discrete TSO(3) integrators and their first- and second-order expansions (paper Section IV).

A state g = (R, Omega) moves by a velocity map Omega+ = f(R, Omega, u) and a reconstruction
R+ = R exp(dt w), where w = Omega (explicit Euler, paper eq. disceq) or w = Omega+ (semi-implicit
Euler, Crocoddyl's). Perturbations are zeta = (eta, delta Omega) with R = R_bar exp(eta)
(:class:`geoddp.lie.TSO3`); z = (zeta, delta u) stacks state and control perturbations.

Exact second-order expansion of the reconstruction. With omega = dt w_bar, A = exp(-omega),
rho = dt delta w and exp(omega + rho) = exp(omega) exp(nu(rho)):

    exp(eta+) = exp(-omega) exp(eta) exp(omega + rho) = exp(Ad_A eta) exp(nu(rho)),
    nu(rho)   = Jr(omega) rho + 1/2 dJr(omega)[rho] rho + O(3),
    eta+      = Ad_A eta + nu(rho) + 1/2 [Ad_A eta, Jr(omega) rho] + O(3)      (BCH).

The last line needs nothing beyond BCH at second order, so it holds for any dt. In particular,
with delta w = 0, eta+ = Ad_A eta exactly: there is no eta-eta term. The paper's Omega_ij
(appendix, eq. etamatrixterms) is an O(dt) approximation of this zero; it is available as
``second_order="paper"`` for the explicit Euler scheme, for comparison only.

Array layout over the horizon (N nodes, n = 6 state, m inputs, nz = n + m):
Phi (N, n, n), B (N, n, m), Theta (N, n, n, n), Gamma (N, n, n, m), Xi (N, n, m, m), with
zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lie import SO3, hat

INTEGRATORS = ("euler", "semi_implicit")
SECOND_ORDER_KINDS = ("exact", "paper")

_LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI_CIVITA[_i, _j, _k] = 1.0
    _LEVI_CIVITA[_i, _k, _j] = -1.0


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

    @property
    def is_second_order(self) -> bool:
        return self.Theta is not None


def reconstruction_velocity(Omega: np.ndarray, Omega_next: np.ndarray, integrator: str) -> np.ndarray:
    """The velocity w used in R+ = R exp(dt w): Omega (euler) or Omega+ (semi_implicit). (N, 3)."""
    return Omega if integrator == "euler" else Omega_next


def assemble(
    dt: float,
    w_bar: np.ndarray,
    F1: np.ndarray,
    F2: np.ndarray | None,
    integrator: str,
    second_order: str = "exact",
) -> Expansion:
    """Build the expansion of zeta+ from the velocity map's derivatives.

    Args:
        dt: time step (s), > 0.
        w_bar: (N, 3) nominal reconstruction velocity (rad/s), see :func:`reconstruction_velocity`.
        F1: (N, 3, nz) Jacobian of Omega+ w.r.t. z = (eta, dOmega, du), eta left-trivialised.
        F2: (N, 3, nz, nz) symmetric (0)-Hessians of Omega+ w.r.t. z, or None for first order.
        integrator: "euler" (paper) or "semi_implicit" (Crocoddyl).
        second_order: "exact" (default) or "paper" (eq. etamatrixterms; euler only).

    Returns:
        :class:`Expansion` with Phi, B and, when F2 is given, Theta, Gamma, Xi.
    """
    N, _, nz = F1.shape
    n = 6
    omega = dt * w_bar
    A = np.swapaxes(SO3.exp_batch(omega), 1, 2)  # Ad_{exp(-omega)} = exp(omega)^T
    Jr = SO3.right_jacobian_batch(omega)
    # First-order part of delta w as a function of z: a selector (euler) or F1 (semi-implicit).
    if integrator == "euler":
        W1 = np.zeros((N, 3, nz))
        W1[:, :, 3:6] = np.eye(3)
    else:
        W1 = F1
    P_eta = np.zeros((3, nz))
    P_eta[:, 0:3] = np.eye(3)
    G1 = np.empty((N, n, nz))
    G1[:, 0:3, :] = A @ P_eta + dt * (Jr @ W1)
    G1[:, 3:6, :] = F1
    exp = Expansion(Phi=np.ascontiguousarray(G1[:, :, :n]), B=np.ascontiguousarray(G1[:, :, n:]))
    if F2 is None:
        return exp

    G2 = np.zeros((N, n, nz, nz))
    if second_order == "exact":
        D = SO3.right_jacobian_derivative_batch(omega)
        Dsym = 0.5 * (D + np.swapaxes(D, 2, 3))
        JW = Jr @ W1  # (N, 3, nz)
        W1T = np.swapaxes(W1, 1, 2)[:, None]  # (N, 1, nz, 3)
        # 1/2 dJr(omega)[rho] rho with rho = dt W1 z  -> Hessian dt^2 W1^T Dsym_i W1 per row i
        G2[:, 0:3] += (dt * dt) * (W1T @ Dsym @ W1[:, None])
        # 1/2 [A eta, Jr rho]: bilinear M_i = 1/2 dt (A P_eta)^T eps_i (Jr W1), eps_i[p, q] = eps_ipq
        AP = A @ P_eta
        M = (0.5 * dt) * (np.swapaxes(AP, 1, 2)[:, None] @ _LEVI_CIVITA[None] @ JW[:, None])
        G2[:, 0:3] += M + np.swapaxes(M, 2, 3)
        if integrator == "semi_implicit":
            # Jr(omega) rho's own second-order part: rho = dt (F1 z + 1/2 F2(z, z)).
            G2[:, 0:3] += dt * (Jr @ F2.reshape(N, 3, nz * nz)).reshape(N, 3, nz, nz)
    elif second_order == "paper":
        if integrator != "euler":
            raise ValueError(
                "second_order: 'paper' (eq. etamatrixterms) is derived for the explicit Euler "
                f"scheme only; got integrator={integrator!r}. Use second_order='exact'."
            )
        G2[:, 0:3, 0:6, 0:6] = _paper_theta_eta(dt, w_bar)
    else:
        raise ValueError(f"second_order: expected one of {SECOND_ORDER_KINDS}, got {second_order!r}")
    G2[:, 3:6] = F2
    exp.Theta = np.ascontiguousarray(G2[:, :, :n, :n])
    exp.Gamma = np.ascontiguousarray(G2[:, :, :n, n:])
    exp.Xi = np.ascontiguousarray(G2[:, :, n:, n:])
    return exp


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
