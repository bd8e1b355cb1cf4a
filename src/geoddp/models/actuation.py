"""Actuation matrices mapping thrust magnitudes to the body wrench of a free-flyer root.

Pinocchio's free-flyer joint takes its generalised force as the body wrench [force; torque]
(N, N m) expressed in the root body frame about the frame origin. These helpers build the
(6, k) columns for k thrusters or rotors; for a model with more joints, stack them into the
first six rows of a (nv, m) actuation (:class:`geoddp.models.multibody.Multibody`).
"""
from __future__ import annotations

import numpy as np

from ..validate import InputError, finite_array, nonnegative_float, positive_float


def thruster_actuation(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Body wrench per unit thrust of k thrusters.

    Args:
        positions: (k, 3) points of application in the root body frame, m (relative to the
            frame origin, where Pinocchio takes the root wrench).
        directions: (k, 3) thrust directions in the body frame (normalised here; non-zero).

    Returns:
        (6, k) matrix whose column i is [d_i; p_i x d_i] with d_i the unit direction: the wrench
        [force (N); torque (N m)] of thruster i firing with unit thrust (1 N).
    """
    P = finite_array(positions, "positions")
    D = finite_array(directions, "directions")
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 1:
        raise InputError("positions", f"expected shape (k, 3) with k >= 1, got shape {P.shape}")
    if D.shape != P.shape:
        raise InputError("directions", f"expected shape {P.shape} (one per position), got shape {D.shape}")
    norms = np.linalg.norm(D, axis=1)
    zero = np.flatnonzero(norms == 0.0)
    if zero.size:
        raise InputError("directions", f"expected non-zero directions, got an all-zero row {int(zero[0])}")
    D = D / norms[:, None]
    return np.vstack([D.T, np.cross(P, D).T])


def quadrotor_actuation(arm_length: float, torque_coefficient: float) -> np.ndarray:
    """Body wrench per unit rotor thrust of a "+" quadrotor.

    Rotors 0..3 sit at arm_length along body +x, +y, -x, -y and push along body +z. Rotor i's
    drag torque about body z is s_i c f_i with s = (+1, -1, +1, -1): opposite rotors spin the
    same way, adjacent rotors opposite ways, so equal thrusts give no yaw torque.

    Args:
        arm_length: distance from the centre (the body frame origin) to each rotor, m, > 0.
        torque_coefficient: c, drag torque per unit thrust, m (N m / N), >= 0.

    Returns:
        (6, 4) matrix mapping rotor thrusts (N) to the wrench [force; torque] (N, N m).
    """
    ell = positive_float(arm_length, "arm_length")
    c = nonnegative_float(torque_coefficient, "torque_coefficient")
    positions = ell * np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    Hm = thruster_actuation(positions, np.tile([0.0, 0.0, 1.0], (4, 1)))
    Hm[5] += c * np.array([1.0, -1.0, 1.0, -1.0])  # rotor drag (reaction) torques about z
    return Hm


def hover_inputs(model, actuation: np.ndarray, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Inputs u (m,) that balance gravity at rest at configuration q: actuation @ u = g(q).

    Args:
        model: a ``pinocchio.Model`` (its gravity field is used).
        actuation: (nv, m) input-to-generalised-force matrix.
        q: (nq,) configuration.
        tol: largest accepted residual |actuation u - g(q)|, relative to max(1, |g(q)|).

    Returns:
        The least-squares solution u of actuation @ u = g(q), Pinocchio's generalised gravity
        (for a "+" quadrotor level at rest, m g / 4 per rotor).

    Raises:
        InputError ("hover"): no input balances gravity (residual above ``tol``).
    """
    import pinocchio as pin

    g = pin.computeGeneralizedGravity(model, model.createData(), np.asarray(q, dtype=float))
    A = np.asarray(actuation, dtype=float)
    u = np.linalg.lstsq(A, g, rcond=None)[0]
    res = float(np.linalg.norm(A @ u - g))
    if res > tol * max(1.0, float(np.linalg.norm(g))):
        raise InputError("hover", "expected an actuation that can balance gravity at the configuration, got a "
                         f"least-squares residual of {res:.3g} (N, N m)")
    return u
