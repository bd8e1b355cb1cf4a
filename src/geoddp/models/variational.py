"""Forward variational Euler on a Pinocchio state space: the paper's implicit transition dynamics.

Discrete Lagrange-d'Alembert-Pontryagin principle (paper eq. disceq1) with the discrete Lagrangian
L_d(q_k, v_k) = dt L(q_k, v_k), L(q, v) = 1/2 v^T M(q) v - V(q), and reconstruction
q_{k+1} = q_k exp(dt v_k) per joint group (``pin.integrate``, paper eq. receq1). With right
(body-frame) perturbations q -> q exp(eta) the reconstruction varies as
eta_{k+1} = Ad_exp(-dt v_k) eta_k + dt Jr(dt v_k) delta v_k, and since
Jr(x)^-1 Ad_exp(-x) = Jr(-x)^-1, stationarity of sum_k L_d plus the virtual work of the inputs
(u_k acting on eta_{k+1}) gives, at every node, the implicit velocity update (paper eq.
dynamicseq1)

    R(q, v, y, u) = K(-dt y)^T M(q+) y - dt dL/dq(q+, y) - K(dt v)^T M(q) v - dt H u = 0,
    q+ = q exp(dt v),   K(x) = Jr(x)^-1,   y = v+.

For a single rigid body (dL/dq = 0) this is Kobilarov and Marsden's
dexp^-1*_{dt xi_k} mu_k - dexp^-1*_{-dt xi_(k-1)} mu_(k-1) = dt f; its dt -> 0 limit is the
Euler-Poincare equation, i.e. Pinocchio's ``aba``. The trivialised gradient of the Lagrangian is
dL/dq(q, v) = 1/2 D(q, v)^T v - g(q), where D(q, w) = d(M(q) w)/dq is RNEA's dtau/dq at
(q, v = 0, a = w) without gravity and g is the generalised gravity (``computeGeneralizedGravity``).

The step solves R = 0 for y by Newton's method with the analytic dR/dy. Its derivatives follow by
implicit differentiation (paper eq. firstimp and the Hessian after it): with w = (eta, delta v, y)
and z = (eta, delta v, delta u),

    dy/dz      = -R_y^-1 R_z,
    d2y/dz2    = -R_y^-1 [P^T R_ww P],   P = dw/dz = [I 0; 0 I; dy/dz]   (R is affine in u).

R_z and R_y are analytic (Pinocchio's RNEA and gravity derivatives, closed-form Jr per joint
group); the compiled core (cpp/dynamics/variational_*.cpp) takes the kinetic-energy Hessian from Pinocchio's
second-order RNEA and R_ww as one central difference of the analytic Jacobian (q through
``integrate``), symmetrised to the (0)-connection Hessian. The tests' numpy oracle of all this is
tests/oracle_variational.py.

This module holds what the compiled step shares with that oracle: Newton's stopping constants
(cpp/dynamics/variational_step.cpp uses the same) and the error a step that does not converge raises.
"""
from __future__ import annotations

NEWTON_MAX_ITER = 30
# Newton converges quadratically: once a correction is below 1e-9 relative, the updated velocity
# is exact to round-off (the residual's own floor is ~1e-13 relative).
NEWTON_TOL = 1e-9


class StepDidNotConverge(ArithmeticError):
    """Newton's method for the implicit velocity update did not converge (dt too large)."""


def not_converged_message(dt: float, v_norm: str) -> str:
    """The one message of a step that did not converge (the core's and the oracle's); v_norm is |v|
    at the step, already formatted."""
    return f"the variational Euler velocity update did not converge at dt = {dt} s (|v| = {v_norm}); use a smaller dt"
