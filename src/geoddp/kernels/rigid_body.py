"""The rigid body on TSO(3) (the satellite, paper Section VI) in numba: rollout under the feedback
law of Algorithm 1 and the exact first- and second-order expansion along a trajectory."""
from __future__ import annotations

import numpy as np
from numba import njit

from .lie import jr_and_derivative, matmul33, so3_exp, so3_log


@njit(cache=True)
def _satellite_velocity_step(
    Om: np.ndarray, tau: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray, dt: float, out: np.ndarray
) -> None:
    """out = Om + dt I^-1 ((I Om) x Om + tau)   (paper eq. disceqs, velocity part)."""
    L0 = inertia[0, 0] * Om[0] + inertia[0, 1] * Om[1] + inertia[0, 2] * Om[2]
    L1 = inertia[1, 0] * Om[0] + inertia[1, 1] * Om[1] + inertia[1, 2] * Om[2]
    L2 = inertia[2, 0] * Om[0] + inertia[2, 1] * Om[1] + inertia[2, 2] * Om[2]
    g0 = L1 * Om[2] - L2 * Om[1] + tau[0]
    g1 = L2 * Om[0] - L0 * Om[2] + tau[1]
    g2 = L0 * Om[1] - L1 * Om[0] + tau[2]
    for i in range(3):
        out[i] = Om[i] + dt * (inertia_inv[i, 0] * g0 + inertia_inv[i, 1] * g1 + inertia_inv[i, 2] * g2)


@njit(cache=True)
def satellite_rollout(
    R0: np.ndarray,
    Om0: np.ndarray,
    R_bar: np.ndarray,
    Om_bar: np.ndarray,
    u_bar: np.ndarray,
    k_ff: np.ndarray,
    K_fb: np.ndarray,
    gamma: float,
    use_feedback: bool,
    inertia: np.ndarray,
    inertia_inv: np.ndarray,
    actuation: np.ndarray,
    dt: float,
    semi_implicit: bool,
    R_out: np.ndarray,
    Om_out: np.ndarray,
    u_out: np.ndarray,
) -> bool:
    """Roll the satellite forward under u_k = u_bar_k - gamma k_k - K_k zeta_k (paper eq. dustar).

    zeta_k = (log(R_bar_k^T R_k), Om_k - Om_bar_k). Without feedback, u_out = u_bar.
    Integrators: explicit Euler (R+ = R exp(dt Om), paper eq. disceqs) or semi-implicit Euler
    (Om+ first, then R+ = R exp(dt Om+), Crocoddyl's). Returns False if a state became non-finite.
    """
    return _rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, use_feedback, False, u_bar, u_bar,
                    inertia, inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out)


@njit(cache=True)
def satellite_rollout_box(
    R0: np.ndarray,
    Om0: np.ndarray,
    R_bar: np.ndarray,
    Om_bar: np.ndarray,
    u_bar: np.ndarray,
    k_ff: np.ndarray,
    K_fb: np.ndarray,
    gamma: float,
    lower: np.ndarray,
    upper: np.ndarray,
    inertia: np.ndarray,
    inertia_inv: np.ndarray,
    actuation: np.ndarray,
    dt: float,
    semi_implicit: bool,
    R_out: np.ndarray,
    Om_out: np.ndarray,
    u_out: np.ndarray,
) -> bool:
    """:func:`satellite_rollout` with feedback and control limits (issue 15): u_k = clamp(u_bar_k
    - gamma k_k - K_k zeta_k, lower_k, upper_k), lower/upper (H, m); the clamped u_k is applied and
    stored (a NaN stays NaN and stops the rollout)."""
    return _rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, True, True, lower, upper,
                    inertia, inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out)


@njit(cache=True)
def _rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, use_feedback, clamp, lower, upper,
             inertia, inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out):
    H = u_bar.shape[0]
    m = u_bar.shape[1]
    R_out[0] = R0
    Om_out[0] = Om0
    E = np.empty((3, 3))
    Ex = np.empty((3, 3))
    zeta = np.empty(6)
    eta = np.empty(3)
    tau = np.empty(3)
    Om_next = np.empty(3)
    for k in range(H):
        Rk = R_out[k]
        Omk = Om_out[k]
        if use_feedback:
            for i in range(3):
                for j in range(3):
                    E[i, j] = R_bar[k, 0, i] * Rk[0, j] + R_bar[k, 1, i] * Rk[1, j] + R_bar[k, 2, i] * Rk[2, j]
            so3_log(E, eta)
            for i in range(3):
                zeta[i] = eta[i]
                zeta[3 + i] = Omk[i] - Om_bar[k, i]
            for a in range(m):
                acc = u_bar[k, a] - gamma * k_ff[k, a]
                for b in range(6):
                    acc -= K_fb[k, a, b] * zeta[b]
                if clamp:  # explicit comparisons: a NaN stays NaN
                    if acc < lower[k, a]:
                        acc = lower[k, a]
                    elif acc > upper[k, a]:
                        acc = upper[k, a]
                u_out[k, a] = acc
        else:
            for a in range(m):
                u_out[k, a] = u_bar[k, a]
        for i in range(3):
            acc = 0.0
            for a in range(m):
                acc += actuation[i, a] * u_out[k, a]
            tau[i] = acc
        _satellite_velocity_step(Omk, tau, inertia, inertia_inv, dt, Om_next)
        if semi_implicit:
            so3_exp(dt * Om_next[0], dt * Om_next[1], dt * Om_next[2], Ex)
        else:
            so3_exp(dt * Omk[0], dt * Omk[1], dt * Omk[2], Ex)
        matmul33(Rk, Ex, R_out[k + 1])
        for i in range(3):
            Om_out[k + 1, i] = Om_next[i]
            if not np.isfinite(Om_next[i]):
                return False
    return True


@njit(cache=True, error_model="numpy")
def satellite_linearise(
    Om: np.ndarray,
    dt: float,
    inertia: np.ndarray,
    inertia_inv: np.ndarray,
    actuation: np.ndarray,
    semi_implicit: bool,
    second_order: bool,
    Phi: np.ndarray,
    B: np.ndarray,
    Theta: np.ndarray,
    Gamma: np.ndarray,
    Xi: np.ndarray,
) -> None:
    """Compiled twin of the numpy closed forms (tests/oracle_satellite.py, backend "analytic") (exact second order).

    Om: (H+1, 3) nominal body rates. Fills Phi (H,6,6), B (H,6,m) and, when second_order,
    Theta (H,6,6,6), Gamma (H,6,6,m), Xi (H,6,m,m). The formulas are those of
    :func:`geoddp.integrators.expand` on SO(3) with the satellite's velocity map
    Omega+ = Omega + dt I^-1((I Omega) x Omega + H u), which does not depend on R and is linear in u.
    """
    H = Phi.shape[0]
    m = actuation.shape[1]
    nz = 6 + m
    Fu = dt * (inertia_inv @ actuation)  # (3, m)
    # constant second derivative of Omega+ in Omega: T[i, j, l] = dt I^-1((I e_j) x e_l + (I e_l) x e_j)
    T = np.zeros((3, 3, 3))
    for j in range(3):
        for l in range(3):
            c = np.zeros(3)
            Ij = inertia[:, j]
            c[0] = Ij[1] * (1.0 if l == 2 else 0.0) - Ij[2] * (1.0 if l == 1 else 0.0)
            c[1] = Ij[2] * (1.0 if l == 0 else 0.0) - Ij[0] * (1.0 if l == 2 else 0.0)
            c[2] = Ij[0] * (1.0 if l == 1 else 0.0) - Ij[1] * (1.0 if l == 0 else 0.0)
            for i in range(3):
                T[i, j, l] += dt * (inertia_inv[i, 0] * c[0] + inertia_inv[i, 1] * c[1] + inertia_inv[i, 2] * c[2])
    for i in range(3):
        for j in range(3):
            for l in range(j + 1):
                s = T[i, j, l] + T[i, l, j]
                T[i, j, l] = s
                T[i, l, j] = s
    Ex = np.empty((3, 3))
    A = np.empty((3, 3))
    Jr = np.empty((3, 3))
    Dsym = np.empty((3, 3, 3))
    Fx = np.empty((3, 3))
    W1 = np.zeros((3, nz))  # first-order part of the reconstruction velocity w.r.t. z
    JW = np.empty((3, nz))
    w = np.empty(3)
    L = np.empty(3)
    G = np.empty((3, 3))
    ej = np.empty(3)
    DW = np.empty((3, nz))
    K, K2, E, EK, KE = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    D = np.empty((3, 3, 3))
    for k in range(H):
        Omk = Om[k]
        for i in range(3):
            L[i] = inertia[i, 0] * Omk[0] + inertia[i, 1] * Omk[1] + inertia[i, 2] * Omk[2]
        # Fx = I + dt I^-1 (hat(I Om) - hat(Om) I)
        for j in range(3):
            # column j of hat(L) - hat(Om) I  = L x e_j - Om x I e_j
            ej[0] = ej[1] = ej[2] = 0.0
            ej[j] = 1.0
            G[0, j] = (L[1] * ej[2] - L[2] * ej[1]) - (Omk[1] * inertia[2, j] - Omk[2] * inertia[1, j])
            G[1, j] = (L[2] * ej[0] - L[0] * ej[2]) - (Omk[2] * inertia[0, j] - Omk[0] * inertia[2, j])
            G[2, j] = (L[0] * ej[1] - L[1] * ej[0]) - (Omk[0] * inertia[1, j] - Omk[1] * inertia[0, j])
        matmul33(inertia_inv, G, Fx)
        for i in range(3):
            for j in range(3):
                Fx[i, j] *= dt
            Fx[i, i] += 1.0
        for i in range(3):
            w[i] = dt * (Om[k + 1, i] if semi_implicit else Omk[i])
        so3_exp(w[0], w[1], w[2], Ex)
        for i in range(3):
            for j in range(3):
                A[i, j] = Ex[j, i]
        jr_and_derivative(w, Jr, Dsym, K, K2, E, EK, KE, D, second_order)
        W1[:, :] = 0.0
        if semi_implicit:
            for i in range(3):
                for j in range(3):
                    W1[i, 3 + j] = Fx[i, j]
                for a in range(m):
                    W1[i, 6 + a] = Fu[i, a]
        else:
            for i in range(3):
                W1[i, 3 + i] = 1.0
        for i in range(3):
            for b in range(nz):
                JW[i, b] = Jr[i, 0] * W1[0, b] + Jr[i, 1] * W1[1, b] + Jr[i, 2] * W1[2, b]
        # first order
        for i in range(3):
            for j in range(3):
                Phi[k, i, j] = A[i, j] + dt * JW[i, j]
                Phi[k, i, 3 + j] = dt * JW[i, 3 + j]
                Phi[k, 3 + i, j] = 0.0
                Phi[k, 3 + i, 3 + j] = Fx[i, j]
            for a in range(m):
                B[k, i, a] = dt * JW[i, 6 + a]
                B[k, 3 + i, a] = Fu[i, a]
        if not second_order:
            continue
        Th = Theta[k]
        Ga = Gamma[k]
        X = Xi[k]
        Th[:, :, :] = 0.0
        Ga[:, :, :] = 0.0
        X[:, :, :] = 0.0
        for i in range(3):
            # dt^2 W1^T Dsym_i W1 (+ dt (Jr T)_i in the Omega block for semi-implicit)
            for p in range(3):
                for b in range(nz):
                    DW[p, b] = Dsym[i, p, 0] * W1[0, b] + Dsym[i, p, 1] * W1[1, b] + Dsym[i, p, 2] * W1[2, b]
            for a in range(3, nz):
                for b in range(3, nz):
                    s = dt * dt * (W1[0, a] * DW[0, b] + W1[1, a] * DW[1, b] + W1[2, a] * DW[2, b])
                    if semi_implicit and a < 6 and b < 6:
                        s += dt * (Jr[i, 0] * T[0, a - 3, b - 3] + Jr[i, 1] * T[1, a - 3, b - 3] + Jr[i, 2] * T[2, a - 3, b - 3])
                    if a < 6 and b < 6:
                        Th[i, a, b] += s
                    elif a < 6:
                        Ga[i, a, b - 6] += s
                    elif b >= 6:
                        X[i, a - 6, b - 6] += s
            # 1/2 [A eta, Jr rho]: M[a, b] = 1/2 dt ((A e_a) x (JW e_b))_i, a in eta, b in z
            i1 = (i + 1) % 3
            i2 = (i + 2) % 3
            for a in range(3):
                for b in range(3, nz):
                    mab = 0.5 * dt * (A[i1, a] * JW[i2, b] - A[i2, a] * JW[i1, b])
                    if b < 6:
                        Th[i, a, b] += mab
                        Th[i, b, a] += mab
                    else:
                        Ga[i, a, b - 6] += mab
        for i in range(3):
            for a in range(3):
                for b in range(3):
                    Th[3 + i, 3 + a, 3 + b] = T[i, a, b]
