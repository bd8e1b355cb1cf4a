"""The tests' oracle of the RKMK4 step (cpp/dynamics/rkmk4.cpp runs it in geoddp): the fourth-order
Runge-Kutta-Munthe-Kaas step on a Pinocchio state space, and its Jacobian, in numpy.

The continuous dynamics are q^-1 dq/dt = v (body-frame velocity, per joint group) and
dv/dt = aba(q, v, tau) with tau held constant over the step. Over one step write
q(t) = q_n exp(theta(t)); then v = Jr(theta) theta', i.e. theta' = Jr(theta)^-1 v (the exact
dexpinv), and (theta, v) obeys an ODE on a vector space. The classical RK4 tableau applied to it
(RKMK with exact dexpinv, Munthe-Kaas 1998) is fourth order on the group:

    k_i  = (Jr(theta_i)^-1 v_i,  aba(q_n exp(theta_i), v_i, tau)),     i = 1..4,
    (theta_1, v_1) = (0, v_n),  (theta_i, v_i) = (0, v_n) + c_i h k_{i-1},  c = (0, 1/2, 1/2, 1),
    theta = h/6 (k1 + 2 k2 + 2 k3 + k4)_theta,  v+ = v_n + h/6 (k1 + 2 k2 + 2 k3 + k4)_v,
    q+ = q_n exp(theta).

Jr(theta) is ``pin.dIntegrate(model, q, theta, ARG1)`` (block-diagonal over joints), taken from
:func:`geoddp.lie.product.block_Ad_Jr`, which is exact where Pinocchio's SE(3) block is not.

The Jacobian w.r.t. z = (dq, dv, du) (q_n -> q_n exp(dq)) chains the stages' analytic
derivatives: the tangent of q_i = q_n exp(dq) exp(theta_i) is Ad_exp(-theta_i) dq + Jr dtheta_i
(``dIntegrate`` ARG0 / ARG1), the acceleration's comes from ``computeABADerivatives``, and
d(Jr^-1 v) = Jr^-1 (dv - dJr[dtheta] Jr^-1 v) with dJr from :mod:`geoddp.lie.product`.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from geoddp import lie
from oracle_linalg import symmetric_from_upper

_C = (0.0, 0.5, 0.5, 1.0)
_W = (1.0, 2.0, 2.0, 1.0)


def step(model: pin.Model, data: pin.Data, groups: list[lie.JointGroup], q: np.ndarray, v: np.ndarray,
         tau: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """One RKMK4 step: q (nq,), v (nv,), tau (nv,) generalised forces, h (s) -> (q+, v+)."""
    theta_sum = np.zeros(model.nv)
    v_sum = np.zeros(model.nv)
    k_theta = k_v = None
    for c, w in zip(_C, _W):
        if k_theta is None:
            theta_i, v_i = np.zeros(model.nv), v
        else:
            theta_i, v_i = c * h * k_theta, v + c * h * k_v
        k_theta = lie.block_Jr_inv(groups, model.nv, theta_i) @ v_i
        k_v = pin.aba(model, data, pin.integrate(model, q, theta_i), v_i, tau)
        theta_sum += w * k_theta
        v_sum += w * k_v
    return pin.integrate(model, q, (h / 6.0) * theta_sum), v + (h / 6.0) * v_sum


def step_jacobian(
    model: pin.Model, data: pin.Data, groups: list[lie.JointGroup], q: np.ndarray, v: np.ndarray,
    tau: np.ndarray, actuation: np.ndarray, h: float,
) -> np.ndarray:
    """Jacobian (2 nv, 2 nv + m) of the step's zeta+ = (dq+, dv+) w.r.t. z = (dq, dv, du).

    q (nq,), v (nv,), tau = actuation @ u (nv,), actuation (nv, m), h (s).
    """
    nv = model.nv
    m = actuation.shape[1]
    nz = 2 * nv + m
    Pq = np.zeros((nv, nz))
    Pq[:, :nv] = np.eye(nv)
    Pv = np.zeros((nv, nz))
    Pv[:, nv : 2 * nv] = np.eye(nv)
    theta_sum = np.zeros(nv)
    Theta_sum = np.zeros((nv, nz))
    A_sum = np.zeros((nv, nz))
    k_theta = k_v = K_theta = K_v = None
    for c, w in zip(_C, _W):
        if k_theta is None:
            theta_i, v_i = np.zeros(nv), v
            Th_i, V_i = np.zeros((nv, nz)), Pv
        else:
            theta_i, v_i = c * h * k_theta, v + c * h * k_v
            Th_i, V_i = c * h * K_theta, Pv + c * h * K_v
        q_i = pin.integrate(model, q, theta_i)
        Ad_i, Jr_i = lie.block_Ad_Jr(groups, nv, theta_i)
        Qtan_i = Ad_i @ Pq + Jr_i @ Th_i  # tangent of q_i at q_i
        pin.computeABADerivatives(model, data, q_i, v_i, tau)
        Minv = symmetric_from_upper(data.Minv)
        K_v = data.ddq_dq @ Qtan_i + data.ddq_dv @ V_i
        K_v[:, 2 * nv :] += Minv @ actuation
        k_v = data.ddq.copy()
        y = np.linalg.solve(Jr_i, v_i)
        D, _ = lie.second_order_tensors(groups, nv, theta_i)
        Mdj = np.einsum("abl,b->al", D, y)  # dJr[dtheta] y = Mdj dtheta
        k_theta = y
        K_theta = np.linalg.solve(Jr_i, V_i - Mdj @ Th_i)
        theta_sum += w * k_theta
        Theta_sum += w * K_theta
        A_sum += w * K_v
    theta = (h / 6.0) * theta_sum
    G = np.empty((2 * nv, nz))
    Ad, Jr = lie.block_Ad_Jr(groups, nv, theta)
    G[:nv] = Ad @ Pq + Jr @ ((h / 6.0) * Theta_sum)
    G[nv:] = Pv + (h / 6.0) * A_sum
    return G
