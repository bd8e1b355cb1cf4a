"""SO(3) and SE(3) numerics for the compiled kernels: exp, log, right Jacobians and their
Taylor coefficients (the numba twins of :mod:`geoddp.lie`, same series and thresholds).

Called from Python (``so3_exp``, ``so3_log``, ``so3_log_batch``, ``so3_right_jacobian``,
``se3_right_jacobian``) and from the other kernels (``matmul33``, ``jr_coefficients``,
``jr_and_derivative``, which write into caller-owned scratch buffers so that loops over the
horizon do not allocate).
"""
from __future__ import annotations

import numpy as np
from numba import njit


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
def matmul33(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]



@njit(cache=True)
def jr_coefficients(t: float) -> tuple[float, float, float, float]:
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
def jr_and_derivative(
    x: np.ndarray, Jr: np.ndarray, Dsym: np.ndarray, K: np.ndarray, K2: np.ndarray, E: np.ndarray,
    EK: np.ndarray, KE: np.ndarray, D: np.ndarray, derivative: bool,
) -> None:
    """Jr(x) (3, 3) and Dsym[i, a, b] = sym_{a,b} d Jr[i, a] / d x_b.

    K, K2, E, EK, KE (3, 3) and D (3, 3, 3) are scratch buffers (no allocation per node).
    """
    t = np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    a, b, alpha, beta = jr_coefficients(t)
    K[0, 0] = K[1, 1] = K[2, 2] = 0.0
    K[0, 1] = -x[2]
    K[0, 2] = x[1]
    K[1, 0] = x[2]
    K[1, 2] = -x[0]
    K[2, 0] = -x[1]
    K[2, 1] = x[0]
    matmul33(K, K, K2)
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
        matmul33(E, K, EK)
        matmul33(K, E, KE)
        for i in range(3):
            for j in range(3):
                D[i, j, l] = -alpha * x[l] * K[i, j] - a * E[i, j] + beta * x[l] * K2[i, j] + b * (EK[i, j] + KE[i, j])
    for i in range(3):
        for p in range(3):
            for q in range(3):
                Dsym[i, p, q] = 0.5 * (D[i, p, q] + D[i, q, p])



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
    a, b, _, _ = jr_coefficients(t)
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

