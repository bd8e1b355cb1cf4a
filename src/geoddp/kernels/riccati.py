"""The backward Riccati-like recursion of DDP on trivialised derivatives (paper eqs. Qfunctions,
dustar, backv) and the gradient recursion (Lemma psi), with the small Cholesky they need."""
from __future__ import annotations

import numpy as np
from numba import njit


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
    # literals, LLVM unrolls the small loops (1.9x faster for n = 6, m = 3). The body repeats the
    # argument list on purpose: packing the arguments into one tuple made the n = 6, m = 3 pass
    # 2.3x slower (measured, H = 300, second order).
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
