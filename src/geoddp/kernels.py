"""Compiled hot loops over plain arrays (numba, cached to disk).

Everything the solver does per node and in sequence lives here: the backward Riccati-like
recursion (paper eqs. Qfunctions, dustar, backv), the gradient recursion (Lemma psi) and the
satellite rollout with the feedback law of Algorithm 1. Inputs are contiguous float64 arrays
over the horizon; there is no Python call per node.

Why numba: a Python loop over 300 nodes with a dozen small numpy calls per node costs ~10 ms per
pass; compiled, the same recursion costs ~1 us per node. ``cache=True`` keeps the compiled code
on disk, so only the first run after install pays the compilation (a few seconds).
"""
from __future__ import annotations

import numpy as np
from numba import njit

_PI = np.pi


# ----------------------------------------------------------------------------- SO(3) in numba
@njit(cache=True, fastmath=False)
def so3_exp(x0: float, x1: float, x2: float, out: np.ndarray) -> None:
    """Rodrigues' formula into out (3, 3), NaN-free at 0."""
    t2 = x0 * x0 + x1 * x1 + x2 * x2
    t = np.sqrt(t2)
    if t < 1e-4:
        s = 1.0 - t2 / 6.0
        a = 0.5 - t2 / 24.0
    else:
        s = np.sin(t) / t
        h = np.sin(0.5 * t) / (0.5 * t)
        a = 0.5 * h * h
    out[0, 0] = 1.0 - a * (x1 * x1 + x2 * x2)
    out[1, 1] = 1.0 - a * (x0 * x0 + x2 * x2)
    out[2, 2] = 1.0 - a * (x0 * x0 + x1 * x1)
    out[0, 1] = -s * x2 + a * x0 * x1
    out[1, 0] = s * x2 + a * x0 * x1
    out[0, 2] = s * x1 + a * x0 * x2
    out[2, 0] = -s * x1 + a * x0 * x2
    out[1, 2] = -s * x0 + a * x1 * x2
    out[2, 1] = s * x0 + a * x1 * x2


@njit(cache=True)
def so3_log(R: np.ndarray, out: np.ndarray) -> None:
    """Rotation vector of R into out (3,), angle in [0, pi]; robust near 0 and near pi."""
    w0 = 0.5 * (R[2, 1] - R[1, 2])
    w1 = 0.5 * (R[0, 2] - R[2, 0])
    w2 = 0.5 * (R[1, 0] - R[0, 1])
    s = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)  # sin(theta)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)  # cos(theta)
    t = np.arctan2(s, c)
    if c > -0.99:
        # theta / sin(theta), with its series where sin(theta) ~ theta.
        if s < 1e-6:
            f = 1.0 + s * s / 6.0
        else:
            f = t / s
        out[0] = f * w0
        out[1] = f * w1
        out[2] = f * w2
        return
    # Near pi, the skew part vanishes: take the axis from the symmetric part,
    # (R + R^T)/2 - cos I = (1 - cos) n n^T, and its sign from the skew part.
    d0 = R[0, 0] - c
    d1 = R[1, 1] - c
    d2 = R[2, 2] - c
    omc = 1.0 - c
    if d0 >= d1 and d0 >= d2:
        n0 = np.sqrt(max(d0 / omc, 0.0))
        n1 = 0.5 * (R[0, 1] + R[1, 0]) / (omc * n0)
        n2 = 0.5 * (R[0, 2] + R[2, 0]) / (omc * n0)
    elif d1 >= d2:
        n1 = np.sqrt(max(d1 / omc, 0.0))
        n0 = 0.5 * (R[0, 1] + R[1, 0]) / (omc * n1)
        n2 = 0.5 * (R[1, 2] + R[2, 1]) / (omc * n1)
    else:
        n2 = np.sqrt(max(d2 / omc, 0.0))
        n0 = 0.5 * (R[0, 2] + R[2, 0]) / (omc * n2)
        n1 = 0.5 * (R[1, 2] + R[2, 1]) / (omc * n2)
    nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    n0 /= nn
    n1 /= nn
    n2 /= nn
    if n0 * w0 + n1 * w1 + n2 * w2 < 0.0:
        n0, n1, n2 = -n0, -n1, -n2
    out[0] = t * n0
    out[1] = t * n1
    out[2] = t * n2


@njit(cache=True)
def so3_log_batch(R: np.ndarray, out: np.ndarray) -> None:
    """:func:`so3_log` over (N, 3, 3) into (N, 3). Accurate to ~1e-15 up to pi, where
    ``pin.log3`` loses up to ~1e-10 between 150 and 180 degrees."""
    for n in range(R.shape[0]):
        so3_log(R[n], out[n])


@njit(cache=True)
def _matmul33(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


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
        _matmul33(Rk, Ex, R_out[k + 1])
        for i in range(3):
            Om_out[k + 1, i] = Om_next[i]
            if not np.isfinite(Om_next[i]):
                return False
    return True


# ----------------------------------------------------------------------------- backward pass
@njit(cache=True, error_model="numpy")
def _cholesky_inplace(A: np.ndarray) -> bool:
    """Lower Cholesky factor of a small SPD matrix, in place. False if not positive definite."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for p in range(j):
            s -= A[j, p] * A[j, p]
        if not (s > 0.0):  # also catches NaN
            return False
        d = np.sqrt(s)
        A[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for p in range(j):
                s -= A[i, p] * A[j, p]
            A[i, j] = s / d
        for i in range(j):
            A[i, j] = 0.0
    return True


@njit(cache=True, error_model="numpy")
def _cholesky_solve(L: np.ndarray, b: np.ndarray) -> None:
    """Solve (L L^T) x = b in place, b (n,) or (n, k)."""
    n = L.shape[0]
    if b.ndim == 1:
        for i in range(n):
            s = b[i]
            for p in range(i):
                s -= L[i, p] * b[p]
            b[i] = s / L[i, i]
        for i in range(n - 1, -1, -1):
            s = b[i]
            for p in range(i + 1, n):
                s -= L[p, i] * b[p]
            b[i] = s / L[i, i]
    else:
        for c in range(b.shape[1]):
            for i in range(n):
                s = b[i, c]
                for p in range(i):
                    s -= L[i, p] * b[p, c]
                b[i, c] = s / L[i, i]
            for i in range(n - 1, -1, -1):
                s = b[i, c]
                for p in range(i + 1, n):
                    s -= L[p, i] * b[p, c]
                b[i, c] = s / L[i, i]


@njit(error_model="numpy", inline="always")
def _backward_pass_body(
    Phi: np.ndarray,
    B: np.ndarray,
    lx: np.ndarray,
    lu: np.ndarray,
    lxx: np.ndarray,
    lux: np.ndarray,
    luu: np.ndarray,
    Vx_final: np.ndarray,
    Vxx_final: np.ndarray,
    Theta: np.ndarray,
    Gamma: np.ndarray,
    Xi: np.ndarray,
    second_order: bool,
    reg: float,
    k_ff: np.ndarray,
    K_fb: np.ndarray,
    Quu_min_eig_proxy: np.ndarray,
    n: int,
    m: int,
) -> tuple[int, float, float]:
    """Body of :func:`backward_pass`; n, m are the state and input dimensions (literals where known)."""
    H = Phi.shape[0]
    Vx = Vx_final.copy()
    Vxx = Vxx_final.copy()
    Qx = np.empty(n)
    Qu = np.empty(m)
    Qxx = np.empty((n, n))
    Qux = np.empty((m, n))
    Quu = np.empty((m, m))
    L = np.empty((m, m))
    VxxPhi = np.empty((n, n))
    VxxB = np.empty((n, m))
    d1 = 0.0
    d2 = 0.0
    for k in range(H - 1, -1, -1):
        P = Phi[k]
        Bk = B[k]
        for i in range(n):
            for j in range(n):
                s = 0.0
                for p in range(n):
                    s += Vxx[i, p] * P[p, j]
                VxxPhi[i, j] = s
            for j in range(m):
                s = 0.0
                for p in range(n):
                    s += Vxx[i, p] * Bk[p, j]
                VxxB[i, j] = s
        for i in range(n):
            s = lx[k, i]
            for p in range(n):
                s += P[p, i] * Vx[p]
            Qx[i] = s
            for j in range(i, n):
                s = lxx[k, i, j]
                for p in range(n):
                    s += P[p, i] * VxxPhi[p, j]
                Qxx[i, j] = s
        for a in range(m):
            s = lu[k, a]
            for p in range(n):
                s += Bk[p, a] * Vx[p]
            Qu[a] = s
            for j in range(n):
                s = lux[k, a, j]
                for p in range(n):
                    s += Bk[p, a] * VxxPhi[p, j]
                Qux[a, j] = s
            for b in range(a, m):
                s = luu[k, a, b]
                for p in range(n):
                    s += Bk[p, a] * VxxB[p, b]
                Quu[a, b] = s
        if second_order:
            for i in range(n):
                v = Vx[i]
                if v == 0.0:
                    continue
                for a in range(n):
                    for b in range(a, n):
                        Qxx[a, b] += v * Theta[k, i, a, b]
                    for c in range(m):
                        Qux[c, a] += v * Gamma[k, i, a, c]
                for a in range(m):
                    for b in range(a, m):
                        Quu[a, b] += v * Xi[k, i, a, b]
        for i in range(n):
            for j in range(i):
                Qxx[i, j] = Qxx[j, i]
        for a in range(m):
            for b in range(a):
                Quu[a, b] = Quu[b, a]
            for b in range(m):
                L[a, b] = Quu[a, b]
            L[a, a] += reg
        if not _cholesky_inplace(L):
            return k, d1, d2
        mn = L[0, 0] * L[0, 0]
        for a in range(1, m):
            if L[a, a] * L[a, a] < mn:
                mn = L[a, a] * L[a, a]
        Quu_min_eig_proxy[k] = mn
        kk = k_ff[k]
        KK = K_fb[k]
        for a in range(m):
            kk[a] = Qu[a]
            for j in range(n):
                KK[a, j] = Qux[a, j]
        _cholesky_solve(L, kk)
        _cholesky_solve(L, KK)
        for a in range(m):
            d1 += Qu[a] * kk[a]
            s = 0.0
            for b in range(m):
                s += Quu[a, b] * kk[b]
            d2 += kk[a] * s
        for i in range(n):
            s = Qx[i]
            for a in range(m):
                s -= Qux[a, i] * kk[a]
            Vx[i] = s
            for j in range(i, n):
                s = Qxx[i, j]
                for a in range(m):
                    s -= Qux[a, i] * KK[a, j]
                Vxx[i, j] = s
        for i in range(n):
            for j in range(i):
                Vxx[i, j] = Vxx[j, i]
    return -1, d1, d2


@njit(cache=True, error_model="numpy")
def backward_pass(
    Phi: np.ndarray,
    B: np.ndarray,
    lx: np.ndarray,
    lu: np.ndarray,
    lxx: np.ndarray,
    lux: np.ndarray,
    luu: np.ndarray,
    Vx_final: np.ndarray,
    Vxx_final: np.ndarray,
    Theta: np.ndarray,
    Gamma: np.ndarray,
    Xi: np.ndarray,
    second_order: bool,
    reg: float,
    k_ff: np.ndarray,
    K_fb: np.ndarray,
    Quu_min_eig_proxy: np.ndarray,
) -> tuple[int, float, float]:
    """The paper's backward recursion on trivialised derivatives, nodes H-1 ... 0.

    Per node (eq. Qfunctions): Q_x = l_x + Phi^T V_x', Q_u = l_u + B^T V_x',
    Q_xx = l_xx + Phi^T V_xx' Phi (+ sum_i V_x'_i Theta_i), Q_ux = l_ux + B^T V_xx' Phi
    (+ sum_i V_x'_i Gamma_i^T), Q_uu = l_uu + B^T V_xx' B (+ sum_i V_x'_i Xi_i) + reg I
    (Remark rem:theta). Gains (eq. dustar): k = Q_uu^-1 Q_u, K = Q_uu^-1 Q_ux. Value backup
    (eq. backv): V_x = Q_x - Q_ux^T k, V_xx = Q_xx - Q_ux^T K. Terminal values (eq. vfinal) are
    passed in.

    Shapes: Phi (H,n,n), B (H,n,m), lx (H,n), lu (H,m), lxx (H,n,n), lux (H,m,n), luu (H,m,m),
    Theta (H,n,n,n), Gamma (H,n,n,m), Xi (H,n,m,m) (ignored unless second_order).

    Returns (failed_node, d1, d2): failed_node = -1 on success, else the node where Q_uu + reg I
    was not positive definite (the pass stops there); d1 = sum_k Q_u^T k_k and
    d2 = sum_k k_k^T Q_uu k_k give the model's predicted change
    dJ(gamma) = -gamma d1 + gamma^2 d2 / 2 (Theorem th1 to first order).
    Quu_min_eig_proxy (H,) receives min_j L_jj^2 of the Cholesky factor (a cheap conditioning
    signal; exact minimum eigenvalue for diagonal Q_uu).
    """
    # TSO(3) states have n = 6 (and fully actuated bodies m = 3): with the dimensions inlined as
    # literals, LLVM unrolls the small loops (1.9x faster for n = 6, m = 3).
    n, m = Phi.shape[1], B.shape[2]
    if n == 6 and m == 3:
        return _backward_pass_body(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi,
                                   second_order, reg, k_ff, K_fb, Quu_min_eig_proxy, 6, 3)
    if n == 6:
        return _backward_pass_body(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi,
                                   second_order, reg, k_ff, K_fb, Quu_min_eig_proxy, 6, m)
    return _backward_pass_body(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi,
                               second_order, reg, k_ff, K_fb, Quu_min_eig_proxy, n, m)


@njit(cache=True)
def gradient(Phi: np.ndarray, B: np.ndarray, lx: np.ndarray, lu: np.ndarray, lx_final: np.ndarray, out: np.ndarray) -> None:
    """dJ/du_k = l_u^k + B_k^T psi^{k+1}, psi^k = l_x^k + Phi_k^T psi^{k+1}, psi^H = l_x^H
    (Lemma lemm:psi). out: (H, m)."""
    H = Phi.shape[0]
    n = Phi.shape[1]
    m = B.shape[2]
    psi = lx_final.copy()
    nxt = np.empty(n)
    for k in range(H - 1, -1, -1):
        for a in range(m):
            s = lu[k, a]
            for p in range(n):
                s += B[k, p, a] * psi[p]
            out[k, a] = s
        for i in range(n):
            s = lx[k, i]
            for p in range(n):
                s += Phi[k, p, i] * psi[p]
            nxt[i] = s
        for i in range(n):
            psi[i] = nxt[i]


# ----------------------------------------------------------------------------- linearisation
@njit(cache=True)
def _jr_coefficients(t: float) -> tuple[float, float, float, float]:
    """a, b, alpha, beta of Jr(x) = I - a hat(x) + b hat(x)^2 and of its derivative
    (see geoddp.lie: same series and thresholds)."""
    t2 = t * t
    if t < 0.25:
        # a = 1/2 - t^2/24 + t^4/720 - t^6/40320 + t^8/3628800
        a = 0.5 + t2 * (-1.0 / 24 + t2 * (1.0 / 720 + t2 * (-1.0 / 40320 + t2 * (1.0 / 3628800))))
        b = 1.0 / 6 + t2 * (-1.0 / 120 + t2 * (1.0 / 5040 + t2 * (-1.0 / 362880 + t2 * (1.0 / 39916800))))
    else:
        h = np.sin(0.5 * t) / (0.5 * t)
        a = 0.5 * h * h
        b = (t - np.sin(t)) / (t2 * t)
    if t < 0.5:
        alpha = -2.0 / 24 + t2 * (4.0 / 720 + t2 * (-6.0 / 40320 + t2 * (8.0 / 3628800 + t2 * (-10.0 / 479001600 + t2 * (12.0 / 87178291200)))))
        beta = -2.0 / 120 + t2 * (4.0 / 5040 + t2 * (-6.0 / 362880 + t2 * (8.0 / 39916800 + t2 * (-10.0 / 6227020800 + t2 * (12.0 / 1307674368000)))))
    else:
        s = np.sin(t)
        omc = 2.0 * np.sin(0.5 * t) ** 2
        alpha = s / (t2 * t) - 2.0 * omc / (t2 * t2)
        beta = omc / (t2 * t2) - 3.0 * (t - s) / (t2 * t2 * t)
    return a, b, alpha, beta


@njit(cache=True)
def _jr_and_derivative(
    x: np.ndarray, Jr: np.ndarray, Dsym: np.ndarray, K: np.ndarray, K2: np.ndarray, E: np.ndarray,
    EK: np.ndarray, KE: np.ndarray, D: np.ndarray, derivative: bool,
) -> None:
    """Jr(x) (3, 3) and Dsym[i, a, b] = sym_{a,b} d Jr[i, a] / d x_b.

    K, K2, E, EK, KE (3, 3) and D (3, 3, 3) are scratch buffers (no allocation per node).
    """
    t = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    a, b, alpha, beta = _jr_coefficients(t)
    K[0, 0] = K[1, 1] = K[2, 2] = 0.0
    K[0, 1] = -x[2]
    K[0, 2] = x[1]
    K[1, 0] = x[2]
    K[1, 2] = -x[0]
    K[2, 0] = -x[1]
    K[2, 1] = x[0]
    _matmul33(K, K, K2)
    for i in range(3):
        for j in range(3):
            Jr[i, j] = (1.0 if i == j else 0.0) - a * K[i, j] + b * K2[i, j]
    if not derivative:
        return
    for l in range(3):
        for i in range(3):
            for j in range(3):
                E[i, j] = 0.0
        if l == 0:
            E[1, 2] = -1.0
            E[2, 1] = 1.0
        elif l == 1:
            E[0, 2] = 1.0
            E[2, 0] = -1.0
        else:
            E[0, 1] = -1.0
            E[1, 0] = 1.0
        _matmul33(E, K, EK)
        _matmul33(K, E, KE)
        for i in range(3):
            for j in range(3):
                D[i, j, l] = -alpha * x[l] * K[i, j] - a * E[i, j] + beta * x[l] * K2[i, j] + b * (EK[i, j] + KE[i, j])
    for i in range(3):
        for p in range(3):
            for q in range(3):
                Dsym[i, p, q] = 0.5 * (D[i, p, q] + D[i, q, p])


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
    """Compiled twin of ``Satellite.expansion(..., backend="analytic")`` (exact second order).

    Om: (H+1, 3) nominal body rates. Fills Phi (H,6,6), B (H,6,m) and, when second_order,
    Theta (H,6,6,6), Gamma (H,6,6,m), Xi (H,6,m,m). The formulas are those of
    :func:`geoddp.integrators.assemble` with the satellite's velocity map
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
        _matmul33(inertia_inv, G, Fx)
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
        _jr_and_derivative(w, Jr, Dsym, K, K2, E, EK, KE, D, second_order)
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



# ----------------------------------------------------------------------------- right Jacobians
# Series coefficients (see geoddp.lie): c(t) of Jr^-1 = I + hat/2 + c hat^2, and the SE(3)
# coupling coefficients c1, c2, c3 of Barfoot's Q (eq. 7.86); 7 terms each.
_JRINV_C = np.array([1 / 12, 1 / 720, 1 / 30240, 1 / 1209600, 1 / 47900160, 691 / 1307674368000, 1 / 74724249600])
_Q1 = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 4))) for k in range(7)])
_Q2 = np.array([(-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 1))) for k in range(2, 9)])
_Q3 = np.array([(-1.0) ** k * (k - 1) / float(np.prod(np.arange(1, 2 * k + 2))) for k in range(2, 9)])


@njit(cache=True)
def _poly(c: np.ndarray, t2: float) -> float:
    out = 0.0
    for i in range(c.shape[0] - 1, -1, -1):
        out = out * t2 + c[i]
    return out


@njit(cache=True)
def _hat(x0: float, x1: float, x2: float) -> np.ndarray:
    K = np.zeros((3, 3))
    K[0, 1] = -x2
    K[0, 2] = x1
    K[1, 0] = x2
    K[1, 2] = -x0
    K[2, 0] = -x1
    K[2, 1] = x0
    return K


@njit(cache=True)
def so3_right_jacobian(x: np.ndarray, inverse: bool) -> np.ndarray:
    """Jr(x) or Jr(x)^-1 (3, 3) of SO(3), exact to round-off (Taylor branches near 0)."""
    t = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    K = _hat(x[0], x[1], x[2])
    K2 = K @ K
    J = np.eye(3)
    if inverse:
        if t < 0.25:
            c = _poly(_JRINV_C, t * t)
        else:
            c = 1.0 / (t * t) - np.cos(0.5 * t) / (2.0 * t * np.sin(0.5 * t))
        return J + 0.5 * K + c * K2
    a, b, _, _ = _jr_coefficients(t)
    return J - a * K + b * K2


@njit(cache=True)
def _se3_coupling(r: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Barfoot's Q(rho, phi) (3, 3), the coupling block of the SE(3) left Jacobian."""
    t = np.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    t2 = t * t
    if t < 0.6:
        c1 = _poly(_Q1, t2)
        c2 = _poly(_Q2, t2)
        c3 = _poly(_Q3, t2)
    else:
        s = np.sin(t)
        c = np.cos(t)
        c1 = (t - s) / (t2 * t)
        c2 = (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2)
        c3 = (2.0 * t - 3.0 * s + t * c) / (2.0 * t2 * t2 * t)
    P = _hat(p[0], p[1], p[2])
    R = _hat(r[0], r[1], r[2])
    PR = P @ R
    RP = R @ P
    PRP = PR @ P
    return 0.5 * R + c1 * (PR + RP + PRP) + c2 * (P @ PR + RP @ P - 3.0 * PRP) + c3 * (PRP @ P + P @ PRP)


@njit(cache=True)
def se3_right_jacobian(x: np.ndarray, inverse: bool) -> np.ndarray:
    """Jr(x) or Jr(x)^-1 (6, 6) of SE(3), x = [linear; angular]: [[J3, Q(-v, -w)], [0, J3]]
    (inverse: [[K3, -K3 Q K3], [0, K3]]), exact to round-off (Taylor branches near 0)."""
    J3 = so3_right_jacobian(x[3:], inverse)
    Q = _se3_coupling(-x[:3], -x[3:])
    out = np.zeros((6, 6))
    out[:3, :3] = J3
    out[3:, 3:] = J3
    if inverse:
        out[:3, 3:] = -(J3 @ Q @ J3)
    else:
        out[:3, 3:] = Q
    return out


_WARM = False


def warm_up() -> None:
    """Load (or compile, on the first run after install) every kernel on tiny inputs.

    Idempotent. The solver calls it before starting its clock so that ``solve_time_s`` measures
    the solve, not numba's one-off loading of cached machine code (~0.4 s per process).
    """
    global _WARM
    if _WARM:
        return
    H, m = 2, 3
    I3 = np.eye(3)
    R = np.broadcast_to(I3, (H + 1, 3, 3)).copy()
    Om = np.zeros((H + 1, 3))
    U = np.zeros((H, m))
    for semi in (False, True):
        satellite_rollout(I3, np.zeros(3), R, Om, U, U, np.zeros((H, m, 6)), 1.0, True, I3, I3, I3, 0.1, semi,
                          R.copy(), Om.copy(), U.copy())
        for second in (False, True):
            satellite_linearise(Om, 0.1, I3, I3, I3, semi, second, np.empty((H, 6, 6)), np.empty((H, 6, m)),
                                np.empty((H, 6, 6, 6)), np.empty((H, 6, 6, m)), np.empty((H, 6, m, m)))
    Phi = np.broadcast_to(np.eye(6), (H, 6, 6)).copy()
    B = np.zeros((H, 6, m))
    for second in (False, True):
        backward_pass(Phi, B, np.zeros((H, 6)), U, np.zeros((H, 6, 6)), np.zeros((H, m, 6)),
                      np.broadcast_to(I3, (H, m, m)).copy(), np.zeros(6), np.eye(6), np.zeros((H, 6, 6, 6)),
                      np.zeros((H, 6, 6, m)), np.zeros((H, 6, m, m)), second, 0.0, np.zeros((H, m)),
                      np.zeros((H, m, 6)), np.zeros(H))
    gradient(Phi, B, np.zeros((H, 6)), U, np.zeros(6), np.zeros((H, m)))
    so3_log_batch(R, np.empty((H + 1, 3)))
    for inverse in (False, True):
        se3_right_jacobian(np.zeros(6), inverse)
    _WARM = True


# ----------------------------------------------------------------------------- costs
@njit(cache=True)
def geodesic_attitude_derivatives(E: np.ndarray, W: np.ndarray, l: np.ndarray, g: np.ndarray, Hs: np.ndarray) -> None:
    """Add 1/2 r^T W r, r = log(E_n), its trivialised gradient and (0)-Hessian into l (N,),
    g (N, 3), Hs (N, 3, 3).

    With Ji = Jr(r)^-1: gradient g = Ji^T W r; Hessian Ji^T (W - sum_p g_p Dsym_p) Ji, where
    Dsym is the symmetrised derivative of Jr (the second-order term of log, see
    geoddp.lie.SO3.log_second_order_batch, contracted with W r).
    """
    r = np.empty(3)
    Jr = np.empty((3, 3))
    Dsym = np.empty((3, 3, 3))
    K, K2, Es, EK, KE = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    D = np.empty((3, 3, 3))
    M = np.empty((3, 3))
    T = np.empty((3, 3))
    for n in range(E.shape[0]):
        so3_log(E[n], r)
        _jr_and_derivative(r, Jr, Dsym, K, K2, Es, EK, KE, D, True)
        Ji = np.linalg.inv(Jr)
        Wr = W @ r
        gn = Ji.T @ Wr
        l[n] += 0.5 * (r[0] * Wr[0] + r[1] * Wr[1] + r[2] * Wr[2])
        for i in range(3):
            g[n, i] += gn[i]
        for a in range(3):
            for b in range(3):
                M[a, b] = W[a, b] - (gn[0] * Dsym[0, a, b] + gn[1] * Dsym[1, a, b] + gn[2] * Dsym[2, a, b])
        _matmul33(M, Ji, T)
        for a in range(3):
            for b in range(3):
                Hs[n, a, b] += Ji[0, a] * T[0, b] + Ji[1, a] * T[1, b] + Ji[2, a] * T[2, b]
