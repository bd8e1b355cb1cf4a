"""The rotation group SO(3): hat/vee, exp/log, right Jacobians, their derivative and inverse.

Conventions (Pinocchio's, see :mod:`geoddp.lie`): right / local (body frame); ``Ad(R) = R``,
``ad(x) = hat(x)``; ``Jr(x)`` with ``exp(x + d) = exp(x) exp(Jr(x) d + O(d^2))`` is ``pin.Jexp3``
and the paper's ``dexp_{-x}``, its inverse ``pin.Jlog3(exp3(x))``.

The closed forms below have Taylor branches chosen so that neither cancellation nor truncation
error exceeds ~1e-15 relative anywhere in [0, pi]: they never return NaN near the identity,
unlike ``pin.Hlog3``. Batched versions take (N, 3) arrays and return (N, 3, 3) or (N, 3, 3, 3).
"""
from __future__ import annotations

from math import factorial

import numpy as np
import pinocchio as pin

from .. import kernels

_EYE3 = np.eye(3)

# --- scalar coefficient functions of theta = |x|, with series generated from their definitions ---
# a(t) = (1 - cos t)/t^2 = sum (-1)^k t^2k / (2k+2)!
# b(t) = (t - sin t)/t^3 = sum (-1)^k t^2k / (2k+3)!
# alpha(t) = a'(t)/t, beta(t) = b'(t)/t   (derivatives of Jr need them)
# c(t) = (1 - (t/2) cot(t/2)) / t^2 = -sum_{n>=1} (-1)^n B_2n t^(2n-2) / (2n)!   (Jr^-1)
_NTERMS = 7
_A = np.array([(-1) ** k / factorial(2 * k + 2) for k in range(_NTERMS)])
_B = np.array([(-1) ** k / factorial(2 * k + 3) for k in range(_NTERMS)])
_ALPHA = np.array([(-1) ** k * 2 * k / factorial(2 * k + 2) for k in range(1, _NTERMS + 1)])
_BETA = np.array([(-1) ** k * 2 * k / factorial(2 * k + 3) for k in range(1, _NTERMS + 1)])
_BERNOULLI = [1 / 6, -1 / 30, 1 / 42, -1 / 30, 5 / 66, -691 / 2730, 7 / 6]
_C = np.array([-((-1) ** n) * _BERNOULLI[n - 1] / factorial(2 * n) for n in range(1, _NTERMS + 1)])

# Below these angles the closed forms lose more than ~1e-14 to cancellation; the series
# (7 terms) is exact to machine precision there.
_SMALL_B = 0.25
_SMALL_ALPHA = 0.5
_SMALL_C = 0.25


def _series(coeffs: np.ndarray, t2: np.ndarray) -> np.ndarray:
    out = np.zeros_like(t2)
    for c in coeffs[::-1]:
        out = out * t2 + c
    return out


def _coefficients(theta: np.ndarray) -> tuple[np.ndarray, ...]:
    """a, b, alpha, beta for Jr and its derivative; theta (N,) >= 0."""
    t = np.asarray(theta, dtype=float)
    t2 = t * t
    safe = np.where(t > 0.0, t, 1.0)
    half = 0.5 * safe
    sinc_half = np.where(t > 0.0, np.sin(half) / half, 1.0)
    a = 0.5 * sinc_half**2  # 2 sin^2(t/2)/t^2, no cancellation
    s = np.sin(safe)
    one_minus_cos = 2.0 * np.sin(half) ** 2
    b = np.where(t < _SMALL_B, _series(_B, t2), (safe - s) / safe**3)
    alpha = np.where(t < _SMALL_ALPHA, _series(_ALPHA, t2), s / safe**3 - 2.0 * one_minus_cos / safe**4)
    beta = np.where(t < _SMALL_ALPHA, _series(_BETA, t2), one_minus_cos / safe**4 - 3.0 * (safe - s) / safe**5)
    return a, b, alpha, beta


def _inv_coefficient(theta: np.ndarray) -> np.ndarray:
    """c(theta) of Jr^-1 = I + hat/2 + c hat^2; finite on [0, 2 pi)."""
    t = np.asarray(theta, dtype=float)
    safe = np.where(t > 0.0, t, 1.0)
    closed = 1.0 / safe**2 - np.cos(0.5 * safe) / (2.0 * safe * np.sin(0.5 * safe))
    return np.where(t < _SMALL_C, _series(_C, t * t), closed)


# --- hat / vee ---
def hat(x: np.ndarray) -> np.ndarray:
    """so(3) hat: (..., 3) -> (..., 3, 3) skew matrices with hat(x) y = x cross y."""
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape[:-1] + (3, 3))
    out[..., 0, 1] = -x[..., 2]
    out[..., 0, 2] = x[..., 1]
    out[..., 1, 0] = x[..., 2]
    out[..., 1, 2] = -x[..., 0]
    out[..., 2, 0] = -x[..., 1]
    out[..., 2, 1] = x[..., 0]
    return out


def vee(M: np.ndarray) -> np.ndarray:
    """Inverse of :func:`hat` on the skew part: (..., 3, 3) -> (..., 3)."""
    M = np.asarray(M, dtype=float)
    return 0.5 * np.stack(
        [M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]], axis=-1
    )


class SO3:
    """The rotation group. Elements are 3x3 matrices, tangent vectors are (3,) body-frame."""

    dim = 3
    #: bracket tensor C (3, 3, 3): [x, y]_i = C[i, p, q] x_p y_q (x cross y); C[i, p, q] = hat(e_p)[i, q]
    structure_constants = np.moveaxis(hat(np.eye(3)), 0, 1)

    @staticmethod
    def exp(x: np.ndarray) -> np.ndarray:
        """(3,) rad -> (3, 3) rotation (``pin.exp3``)."""
        return pin.exp3(np.asarray(x, dtype=float))

    @staticmethod
    def log(R: np.ndarray) -> np.ndarray:
        """(3, 3) rotation -> (3,) rotation vector with angle in [0, pi] (``pin.log3``).

        Across pi the vector flips sign: log is discontinuous there by nature.
        """
        return pin.log3(np.asarray(R, dtype=float))

    @staticmethod
    def log_batch(R: np.ndarray) -> np.ndarray:
        """(N, 3, 3) -> (N, 3), compiled; ~1e-15 accurate up to pi (``pin.log3`` loses up to
        ~1e-10 between 150 and 180 degrees, which matters for costs near the cut locus)."""
        R = np.ascontiguousarray(R, dtype=float).reshape(-1, 3, 3)
        out = np.empty((R.shape[0], 3))
        kernels.so3_log_batch(R, out)
        return out

    @staticmethod
    def compose(R1: np.ndarray, R2: np.ndarray) -> np.ndarray:
        """Group product R1 R2, (3, 3)."""
        return np.asarray(R1, dtype=float) @ np.asarray(R2, dtype=float)

    @staticmethod
    def inverse(R: np.ndarray) -> np.ndarray:
        """R^-1 = R^T, (3, 3)."""
        return np.asarray(R, dtype=float).T.copy()

    @staticmethod
    def right_jacobian(x: np.ndarray) -> np.ndarray:
        """Right Jacobian Jr(x) (3, 3): exp(x + d) = exp(x) exp(Jr(x) d). Equals ``pin.Jexp3``
        and the paper's dexp_{-x}, but with a Taylor branch: ``pin.Jexp3``'s (1 - cos t)/t^2
        cancels below ~1e-4 rad (compiled: :func:`geoddp.kernels.so3_right_jacobian`)."""
        return kernels.so3_right_jacobian(np.ascontiguousarray(x, dtype=float), False)

    @staticmethod
    def right_jacobian_inv(x: np.ndarray) -> np.ndarray:
        """Jr(x)^-1 (3, 3), valid for |x| < 2 pi (``pin.Jlog3(exp3(x))`` for |x| < pi)."""
        return kernels.so3_right_jacobian(np.ascontiguousarray(x, dtype=float), True)

    @staticmethod
    def left_jacobian(x: np.ndarray) -> np.ndarray:
        """Left Jacobian Jl(x) = Jr(-x) = Ad_exp(x) Jr(x), the paper's dexp_x."""
        return SO3.right_jacobian(-np.asarray(x, dtype=float))

    @staticmethod
    def Ad(R: np.ndarray) -> np.ndarray:
        """Adjoint action matrix of a rotation on so(3) ~ R^3: the rotation itself."""
        return np.asarray(R, dtype=float).copy()

    @staticmethod
    def Ad_exp_neg(x: np.ndarray) -> np.ndarray:
        """Ad_{exp(-x)} = exp(x)^T (3, 3): how a right step by exp(x) moves a body-frame
        perturbation (``dIntegrate``'s ARG0)."""
        return pin.exp3(np.asarray(x, dtype=float)).T

    @staticmethod
    def ad(x: np.ndarray) -> np.ndarray:
        """Adjoint of so(3) on itself: ad_x y = [x, y] = x cross y, i.e. hat(x)."""
        return hat(x)

    # --- batched closed forms (N, 3) ---
    @staticmethod
    def right_jacobian_batch(X: np.ndarray) -> np.ndarray:
        """(N, 3) -> (N, 3, 3) Jr(x) = I - a(t) hat(x) + b(t) hat(x)^2."""
        X = np.asarray(X, dtype=float)
        a, b, _, _ = _coefficients(np.linalg.norm(X, axis=-1))
        K = hat(X)
        return _EYE3 - a[:, None, None] * K + b[:, None, None] * (K @ K)

    @staticmethod
    def right_jacobian_inv_batch(X: np.ndarray) -> np.ndarray:
        """(N, 3) -> (N, 3, 3) Jr(x)^-1 = I + hat(x)/2 + c(t) hat(x)^2, |x| < 2 pi."""
        X = np.asarray(X, dtype=float)
        c = _inv_coefficient(np.linalg.norm(X, axis=-1))
        K = hat(X)
        return _EYE3 + 0.5 * K + c[:, None, None] * (K @ K)

    @staticmethod
    def right_jacobian_derivative_batch(X: np.ndarray) -> np.ndarray:
        """(N, 3) -> (N, 3, 3, 3) D with D[n, i, j, l] = d Jr(x_n)[i, j] / d x_l.

        The second-order term of exp(x + d) = exp(x) exp(nu(d)) is
        nu(d) = Jr(x) d + 1/2 (dJr(x)[d]) d + O(d^3)   (derived in models/satellite.py).
        """
        X = np.asarray(X, dtype=float)
        a, b, alpha, beta = _coefficients(np.linalg.norm(X, axis=-1))
        K = hat(X)
        K2 = K @ K
        E = hat(_EYE3)  # E[l] = hat(e_l), (3, 3, 3)
        # d/dx_l: -alpha x_l K - a E_l + beta x_l K^2 + b (E_l K + K E_l)
        D = (
            -alpha[:, None, None, None] * X[:, None, None, :] * K[:, :, :, None]
            - a[:, None, None, None] * np.moveaxis(E, 0, -1)[None]
            + beta[:, None, None, None] * X[:, None, None, :] * K2[:, :, :, None]
            + b[:, None, None, None]
            * (np.einsum("lij,njk->nikl", E, K) + np.einsum("nij,ljk->nikl", K, E))
        )
        return D

    @staticmethod
    def log_second_order_batch(X: np.ndarray) -> np.ndarray:
        """(0)-Hessian of eta -> log(exp(x) exp(eta)) at eta = 0, per component.

        Returns (N, 3, 3, 3) T with log(exp(x) exp(eta)) = x + Jr^-1 eta + 1/2 T[:, i] (eta, eta).
        From exp(r(s)) = exp(x) exp(s eta):  Jr(r) r' = eta, so r'' = -Jr^-1 (dJr(x)[r']) r'.
        """
        Ji = SO3.right_jacobian_inv_batch(X)
        D = SO3.right_jacobian_derivative_batch(X)
        # q_k(eta) = -sum_p Ji[k,p] D[p,a,b] y_b y_a? careful: (dJr[y] y)_p = sum_{a,b} D[p,a,b] y_a y_b
        # with y = Ji eta; D[p, a, b] = dJr[p, a]/dx_b.
        T = -np.einsum("nkp,npab,naj,nbl->nkjl", Ji, D, Ji, Ji)
        return 0.5 * (T + np.swapaxes(T, -1, -2))
