"""Cost kernels: the geodesic attitude cost 1/2 |log(R_d^T R)|_W^2 and its trivialised
derivatives over a batch of rotations."""
from __future__ import annotations

import numpy as np
from numba import njit

from .lie import jr_and_derivative, matmul33, so3_log


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
        jr_and_derivative(r, Jr, Dsym, K, K2, Es, EK, KE, D, True)
        Ji = np.linalg.inv(Jr)
        Wr = W @ r
        gn = Ji.T @ Wr
        l[n] += 0.5 * (r[0] * Wr[0] + r[1] * Wr[1] + r[2] * Wr[2])
        for i in range(3):
            g[n, i] += gn[i]
        for a in range(3):
            for b in range(3):
                M[a, b] = W[a, b] - (gn[0] * Dsym[0, a, b] + gn[1] * Dsym[1, a, b] + gn[2] * Dsym[2, a, b])
        matmul33(M, Ji, T)
        for a in range(3):
            for b in range(3):
                Hs[n, a, b] += Ji[0, a] * T[0, b] + Ji[1, a] * T[1, b] + Ji[2, a] * T[2, b]
