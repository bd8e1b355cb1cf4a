"""The rigid-motion group SE(3): exp/log, right Jacobian (exact closed form), its inverse and
derivative, Ad, ad and the bracket tensor.

Elements are ``pin.SE3``; twists are (6,) [linear; angular] (Pinocchio's Motion order), body frame.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .. import kernels

# Central-difference step for dJr of SE(3): truncation ~ h^2 |d^3 Jr| / 6 ~ 1e-11,
# round-off ~ 1e-16 / h ~ 1e-11 (tested against Richardson extrapolation).
_DJR_STEP = 1e-5


class SE3:
    """Rigid motions. Elements are ``pin.SE3``; twists are (6,) [linear; angular] (body frame)."""

    dim = 6
    #: bracket tensor C (6, 6, 6): [x, y]_i = C[i, p, q] x_p y_q, the Motion cross product
    #: (C[:, p, :] = ad_{e_p})
    structure_constants = np.stack([pin.Motion(e).action for e in np.eye(6)], axis=1)

    @staticmethod
    def exp(x: np.ndarray) -> pin.SE3:
        """(6,) twist -> SE3 (``pin.exp6``)."""
        return pin.exp6(np.asarray(x, dtype=float))

    @staticmethod
    def log(M: pin.SE3) -> np.ndarray:
        """SE3 -> (6,) twist (``pin.log6``)."""
        return pin.log6(M).vector

    @staticmethod
    def compose(M1: pin.SE3, M2: pin.SE3) -> pin.SE3:
        """Group product M1 M2."""
        return M1 * M2

    @staticmethod
    def inverse(M: pin.SE3) -> pin.SE3:
        """M^-1."""
        return M.inverse()

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
    def Ad_exp_neg(x: np.ndarray) -> np.ndarray:
        """(6, 6) Ad_{exp(-x)}: how a right step by exp(x) moves a body-frame perturbation
        (``dIntegrate``'s ARG0)."""
        return pin.exp6(-np.asarray(x, dtype=float)).action

    @staticmethod
    def right_jacobian_derivative(x: np.ndarray) -> np.ndarray:
        """D (6, 6, 6) with D[i, j, l] = d Jr(x)[i, j] / d x_l; x (6,) [linear; angular].

        Central differences of the closed-form :meth:`right_jacobian` (error ~1e-10, tested).
        """
        return SE3.right_jacobian_derivative_batch(np.asarray(x, dtype=float)[None])[0]

    @staticmethod
    def right_jacobian_derivative_batch(X: np.ndarray) -> np.ndarray:
        """:meth:`right_jacobian_derivative` at N points: X (N, 6) -> (N, 6, 6, 6), one flat pass
        of the closed-form Jr."""
        X = np.asarray(X, dtype=float)
        h = _DJR_STEP
        steps = h * np.eye(6)
        pts = np.stack([X[:, None, :] + steps, X[:, None, :] - steps], axis=1).reshape(-1, 6)  # [n, sign, l]
        J = np.array([SE3.right_jacobian(x) for x in pts]).reshape(X.shape[0], 2, 6, 6, 6)  # [n, sign, l, i, j]
        return np.moveaxis((J[:, 0] - J[:, 1]) / (2.0 * h), 1, -1)

    @staticmethod
    def ad(x: np.ndarray) -> np.ndarray:
        """(6, 6) ad_x, the Motion cross product ``Motion(x).action``."""
        return pin.Motion(np.asarray(x, dtype=float)).action
