"""Lie groups over Pinocchio's operators: SO(3), SE(3) and the tangent bundle TSO(3).

Conventions (Pinocchio's): everything is right / local (body frame).
* ``exp``/``log`` are the group exponential and its inverse (``pin.exp3``, ``pin.log3``, ...).
* The *right Jacobian* ``Jr(x)`` satisfies ``exp(x + d) = exp(x) exp(Jr(x) d + O(d^2))``.
  It is ``pin.Jexp3`` and the paper's ``dexp_{-x}``. Its inverse is ``pin.Jlog3(exp3(x))``.
* ``Ad(R) = R`` for SO(3); ``ad(x) = hat(x)``.
* SE(3) twists are ``[linear; angular]`` (Pinocchio's Motion order).

The closed forms below have Taylor branches chosen so that neither cancellation nor truncation
error exceeds ~1e-15 relative anywhere in [0, pi]: they never return NaN near the identity,
unlike ``pin.Hlog3``. Batched versions take (N, 3) arrays and return (N, 3, 3) or (N, 3, 3, 3).
"""
from __future__ import annotations

from math import factorial

import numpy as np
import pinocchio as pin

from . import kernels

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
    def right_jacobian(x: np.ndarray) -> np.ndarray:
        """Right Jacobian Jr(x) (3, 3): exp(x + d) = exp(x) exp(Jr(x) d). Equals ``pin.Jexp3``
        and the paper's dexp_{-x}."""
        return pin.Jexp3(np.asarray(x, dtype=float))

    @staticmethod
    def right_jacobian_inv(x: np.ndarray) -> np.ndarray:
        """Jr(x)^-1 (3, 3), valid for |x| < 2 pi (``pin.Jlog3(exp3(x))`` for |x| < pi)."""
        return kernels.so3_right_jacobian(np.ascontiguousarray(x, dtype=float), True)

    @staticmethod
    def left_jacobian(x: np.ndarray) -> np.ndarray:
        """Left Jacobian Jl(x) = Jr(-x) = Ad_exp(x) Jr(x), the paper's dexp_x."""
        return pin.Jexp3(-np.asarray(x, dtype=float))

    @staticmethod
    def Ad(R: np.ndarray) -> np.ndarray:
        """Adjoint action matrix of a rotation on so(3) ~ R^3: the rotation itself."""
        return np.asarray(R, dtype=float).copy()

    @staticmethod
    def ad(x: np.ndarray) -> np.ndarray:
        """Adjoint of so(3) on itself: ad_x y = [x, y] = x cross y, i.e. hat(x)."""
        return hat(x)

    # --- batched closed forms (N, 3) ---
    @staticmethod
    def exp_batch(X: np.ndarray) -> np.ndarray:
        """(N, 3) -> (N, 3, 3) rotations, Rodrigues with a NaN-free small-angle branch."""
        X = np.asarray(X, dtype=float)
        t = np.linalg.norm(X, axis=-1)
        safe = np.where(t > 0.0, t, 1.0)
        sinc = np.where(t > 1e-4, np.sin(safe) / safe, 1.0 - t * t / 6.0)
        a, _, _, _ = _coefficients(t)
        K = hat(X)
        return _EYE3 + sinc[:, None, None] * K + a[:, None, None] * (K @ K)

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


class SE3:
    """Rigid motions. Elements are ``pin.SE3``; twists are (6,) [linear; angular] (body frame)."""

    dim = 6

    @staticmethod
    def exp(x: np.ndarray) -> pin.SE3:
        """(6,) twist -> SE3 (``pin.exp6``)."""
        return pin.exp6(np.asarray(x, dtype=float))

    @staticmethod
    def log(M: pin.SE3) -> np.ndarray:
        """SE3 -> (6,) twist (``pin.log6``)."""
        return pin.log6(M).vector

    @staticmethod
    def right_jacobian(x: np.ndarray) -> np.ndarray:
        """(6, 6) right Jacobian: exp(x + d) = exp(x) exp(Jr d + O(d^2)), x (6,) [linear; angular].

        Jr(x) = [[Jr3(w), Q(-v, -w)], [0, Jr3(w)]] with Barfoot's Q (State Estimation for
        Robotics, eq. 7.86), whose coefficients use their Taylor series below |w| = 0.6
        (compiled: :func:`geoddp.kernels.se3_right_jacobian`).
        Why not ``pin.Jexp6``: in Pinocchio 4.1 it loses up to 3e-5 absolute in the coupling
        block for 1e-5 < |w| < 1e-2 (cancellation without a Taylor branch); so do
        ``pin.Jlog6`` and the free-flyer ``dIntegrate`` / ``dDifference`` (measured against
        the series sum_k (-ad_x)^k / (k+1)!). This form is exact to ~1e-16 there (tested).
        """
        return kernels.se3_right_jacobian(np.ascontiguousarray(x, dtype=float), False)

    @staticmethod
    def right_jacobian_inv(x: np.ndarray) -> np.ndarray:
        """(6, 6) inverse right Jacobian, |angular part| < 2 pi: [[K, -K Q K], [0, K]] with
        K = Jr3(w)^-1 (block inverse of :meth:`right_jacobian`; exact where ``pin.Jlog6`` is not)."""
        return kernels.se3_right_jacobian(np.ascontiguousarray(x, dtype=float), True)

    @staticmethod
    def log_jacobian(M: pin.SE3) -> np.ndarray:
        """(6, 6) d log(M exp(d)) / d d at d = 0, i.e. Jr(log M)^-1 (``pin.Jlog6``, but exact near
        the identity; see :meth:`right_jacobian`)."""
        return SE3.right_jacobian_inv(pin.log6(M).vector)

    @staticmethod
    def Ad(M: pin.SE3) -> np.ndarray:
        """(6, 6) adjoint action matrix (``SE3.action``)."""
        return M.action

    @staticmethod
    def ad(x: np.ndarray) -> np.ndarray:
        """(6, 6) ad_x, the Motion cross product ``Motion(x).action``."""
        return pin.Motion(np.asarray(x, dtype=float)).action


class TSO3:
    """The satellite state space G = SO(3) x R^3 with g = (R, Omega) (paper, Section IV).

    Tangent vectors are the paper's zeta = (eta, delta_xi) stacked as (6,): the first block acts
    on SO(3) by right multiplication, the second on R^3 by addition. This is the one place the
    ordering is defined.
    """

    nx = 6
    ETA = slice(0, 3)
    XI = slice(3, 6)

    @staticmethod
    def retract(R: np.ndarray, Omega: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g exp(zeta) = (R exp(eta), Omega + delta_xi)."""
        zeta = np.asarray(zeta, dtype=float)
        return R @ pin.exp3(zeta[TSO3.ETA]), Omega + zeta[TSO3.XI]

    @staticmethod
    def local(R_bar: np.ndarray, Omega_bar: np.ndarray, R: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """zeta = log(g_bar^-1 g) = (log(R_bar^T R), Omega - Omega_bar), (6,)."""
        return np.concatenate([pin.log3(R_bar.T @ R), Omega - Omega_bar])

    @staticmethod
    def local_batch(R_bar: np.ndarray, Omega_bar: np.ndarray, R: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """Batched :meth:`local`: (N,3,3),(N,3),(N,3,3),(N,3) -> (N, 6)."""
        E = np.einsum("nji,njk->nik", R_bar, R)
        return np.concatenate([SO3.log_batch(E), Omega - Omega_bar], axis=1)
