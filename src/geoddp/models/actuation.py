"""Actuation matrices mapping thrust magnitudes to the body wrench of a free-flyer root, and the
inputs that hold a configuration against gravity (:func:`quasi_static_inputs`, :func:`hover_inputs`).

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


def quasi_static_inputs(model, actuation: np.ndarray, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Inputs u (m,) that hold configuration q at rest against gravity where the actuation can.

    With g(q) Pinocchio's generalised gravity at (q, v = 0) (``computeGeneralizedGravity``: the
    generalised force that holds q at rest) and H the actuation:

    * where some input balances gravity exactly (residual |H u - g| <= tol max(1, |g|)): the
      least-squares solution of smallest norm, u = pinv(H) g(q), which is what Crocoddyl's
      ``quasiStatic`` computes for its free-dynamics action models (pinv(dtau/du) tau). A
      fixed-base arm with every joint actuated gets its gravity torques g(q); a quadrotor level at
      rest its hover thrusts m g / 4; redundant thrusters the balancing thrusts of smallest norm.
      These are the inputs of :func:`hover_inputs` (the scene files' "hover"), bit for bit.
    * where none does (underactuated): the least squares in the metric of the mass matrix M(q),
      u = argmin_u (H u - g)^T M^-1 (H u - g), the inputs that minimise the kinetic-energy norm
      of the acceleration a = M^-1 (H u - g) left by the unbalanced gravity (the Euclidean residual
      would add newtons to newton-metres). A free-flyer base with actuated joints only then gets
      zero joint torques to round-off: in uniform gravity the whole robot falls with its posture
      held (g = M a_fall) and no torque is needed for that, where Crocoddyl's Euclidean pinv(H) g
      gives the joint rows of g, the torques that would hold the posture were the base held,
      which make a free-falling robot flail (Solo12 with gravity, no contacts: the rollout
      overflowed). A tilted quadrotor gets the thrusts that cancel gravity along its rotors.
    * without gravity (g = 0): exact zeros.

    Args:
        model: a ``pinocchio.Model`` (its gravity field and inertias are used).
        actuation: (nv, m) input-to-generalised-force matrix (N, N m per unit input).
        q: (nq,) configuration.
        tol: residual below which gravity counts as balanced, relative to max(1, |g(q)|).

    Returns:
        (m,) float64 inputs, in the actuation's units (N m for joint torques, N for thrusts).
    """
    import pinocchio as pin

    u, A, g = _holding(model, actuation, q)
    if float(np.linalg.norm(A @ u - g)) <= tol * max(1.0, float(np.linalg.norm(g))):
        return u
    # M = L L^T: (H u - g)^T M^-1 (H u - g) = |L^-1 (H u - g)|^2
    data = model.createData()
    M = pin.crba(model, data, np.asarray(q, dtype=float))
    M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    L = np.linalg.cholesky(M)
    return np.linalg.lstsq(np.linalg.solve(L, A), np.linalg.solve(L, g), rcond=None)[0]


def _holding(model, actuation: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, actuation as float64, g(q)): the least-squares inputs of smallest norm, pinv(H) g(q)."""
    import pinocchio as pin

    g = pin.computeGeneralizedGravity(model, model.createData(), np.asarray(q, dtype=float))
    A = np.asarray(actuation, dtype=float)
    if not np.any(g):  # no gravity (or none that acts at q): exact zeros, not a solve's round-off
        return np.zeros(A.shape[1]), A, g
    return np.linalg.lstsq(A, g, rcond=None)[0], A, g


def hover_inputs(model, actuation: np.ndarray, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Inputs u (m,) that balance gravity at rest at configuration q exactly: actuation @ u = g(q).

    The strict form of :func:`quasi_static_inputs` (the scene files' ``"hover"``): the same
    inputs where gravity can be balanced, refused where it cannot.

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
    u, A, g = _holding(model, actuation, q)
    res = float(np.linalg.norm(A @ u - g))
    if res > tol * max(1.0, float(np.linalg.norm(g))):
        raise InputError("hover", "expected an actuation that can balance gravity at the configuration, got a "
                         f"least-squares residual of {res:.3g} (N, N m)")
    return u
