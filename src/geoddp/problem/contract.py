"""The contract between a problem and the solver, written down once.

:func:`geoddp.solver.solve` calls the members of :class:`OptimalControlProblem` and nothing else:
no ``problem.model.*``, no backend option (a backend is chosen when the model is built), and the
problem never writes the :class:`~geoddp.solver.result.Result`'s schema (it only describes its model).

Shapes use H = horizon (number of control steps), m = nu (number of inputs) and nx = the
dimension of the tangent space of the state group (6 on TSO(3), 2 nv for a multibody). States are
opaque to the solver: it only hands a :class:`Trajectory` back to the problem that made it.

The perturbation convention is the paper's: zeta_k = difference(x_bar_k, x_k) in the tangent
space at the nominal x_bar_k (right/local, Pinocchio's ``difference``; (log(R_bar^T R),
Omega - Omega_bar) on TSO(3)), and the linearisation is that of zeta_{k+1} in (zeta_k, du_k)
(paper eqs. linearised dynamics and Qfunctions).

This module imports nothing else from geoddp: problems and the solver both import it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Trajectory", "Linearisation", "OptimalControlProblem"]


@dataclass
class Trajectory:
    """A state-control trajectory over H steps.

    Attributes:
        q: (H+1, ...) configuration part of the state: rotation matrices (H+1, 3, 3) on TSO(3),
            Pinocchio configurations (H+1, nq) for a multibody.
        v: (H+1, nv) velocity part of the state (rad/s, m/s): body angular velocity Omega on
            TSO(3), generalised velocities for a multibody.
        u: (H, m) controls (units of the model's actuation).
    """

    q: np.ndarray
    v: np.ndarray
    u: np.ndarray


@dataclass
class Linearisation:
    """Expansion of dynamics and costs along one trajectory (paper Section IV), arrays over k.

    Attributes:
        order: 1 (Phi, B only) or 2 (with Theta, Gamma, Xi: the exact second-order expansion).
        Phi: (H, nx, nx) d zeta_{k+1} / d zeta_k.   B: (H, nx, m) d zeta_{k+1} / d u_k.
        Theta: (H, nx, nx, nx), Gamma: (H, nx, nx, m), Xi: (H, nx, m, m): second derivatives of
            zeta_{k+1} in (zeta, zeta), (zeta, u), (u, u), indexed [k, output, ., .]; None at order 1.
        l_x: (H, nx), l_u: (H, m), l_xx: (H, nx, nx), l_ux: (H, m, nx), l_uu: (H, m, m): running
            cost derivatives (the backward pass reads only the upper triangle of symmetric blocks).
        lf_x: (nx,), lf_xx: (nx, nx): terminal cost derivatives at k = H.
        second_order: at order 2, the second-order terms in factored form instead of Theta,
            Gamma, Xi (which are then None): an object with ``contract(k, Vx)`` returning the
            (nx + m, nx + m) matrix sum_i Vx_i [[Theta_i[k], Gamma_i[k]], [Gamma_i[k]^T, Xi_i[k]]]
            for Vx (nx,) (geoddp._core.SecondOrderTerms: the backward pass contracts with V_x'
            without forming the tensors). None otherwise.
        gauss_newton: order 1 only: True when the cost Hessians are Gauss-Newton ones
            (J_r^T W J_r, the second-order parts of the cost residuals dropped, as in
            Crocoddyl's residual costs), so that the whole first-order model is a Gauss-Newton
            one; False when they are exact (the paper's first-order DDP).
    """

    order: int
    Phi: np.ndarray
    B: np.ndarray
    Theta: np.ndarray | None
    Gamma: np.ndarray | None
    Xi: np.ndarray | None
    l_x: np.ndarray
    l_u: np.ndarray
    l_xx: np.ndarray
    l_ux: np.ndarray
    l_uu: np.ndarray
    lf_x: np.ndarray
    lf_xx: np.ndarray
    second_order: Any = None
    gauss_newton: bool = False

    def tensors(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Theta, Gamma, Xi) of an order-2 linearisation as dense arrays (shapes above), formed
        from ``second_order`` by contracting with each unit vector when the tensors are factored
        (H nx contractions: for consumers that need them whole; the backward pass does not)."""
        if self.order != 2:
            raise ValueError("tensors(): an order-1 linearisation has no second-order terms")
        if self.second_order is None:
            return self.Theta, self.Gamma, self.Xi
        H, n, m = self.B.shape
        Theta, Gamma, Xi = np.empty((H, n, n, n)), np.empty((H, n, n, m)), np.empty((H, n, m, m))
        e = np.zeros(n)
        for k in range(H):
            for i in range(n):
                e[i] = 1.0
                S = self.second_order.contract(k, e)
                e[i] = 0.0
                Theta[k, i], Gamma[k, i], Xi[k, i] = S[:n, :n], S[:n, n:], S[n:, n:]
        return Theta, Gamma, Xi

    @classmethod
    def from_parts(cls, order: int, dynamics: Any, running: Any, terminal: Any,
                   gauss_newton: bool = False) -> "Linearisation":
        """Bundle a dynamics expansion (attributes Phi, B, Theta, Gamma, Xi) and running / terminal
        cost derivatives (attributes lx, lu, lxx, lux, luu over N nodes; terminal N = 1) without
        copying. Second-order arrays are dropped at order 1; a dynamics expansion whose second
        order is factored (attribute ``terms``) hands it on as ``second_order``.
        ``gauss_newton``: the cost derivatives' Hessians are Gauss-Newton ones (order 1 only)."""
        second = order == 2
        return cls(
            order=order, Phi=dynamics.Phi, B=dynamics.B,
            Theta=dynamics.Theta if second else None,
            Gamma=dynamics.Gamma if second else None,
            Xi=dynamics.Xi if second else None,
            second_order=getattr(dynamics, "terms", None) if second else None,
            l_x=running.lx, l_u=running.lu, l_xx=running.lxx, l_ux=running.lux, l_uu=running.luu,
            lf_x=terminal.lx[0], lf_xx=terminal.lxx[0], gauss_newton=bool(gauss_newton) and not second,
        )


@runtime_checkable
class OptimalControlProblem(Protocol):
    """What the solver may ask of a problem (min_U sum_k l(x_k, u_k) + l_f(x_H), x_0 given).

    Attributes:
        nx: dimension of the tangent state zeta.  nu: number of inputs m.
        horizon: number of control steps H.  dt: time step in seconds.
    """

    nx: int
    nu: int
    horizon: int
    dt: float

    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        """Validated (H, m) float64 copy of a control sequence; InputError naming ``name``."""
        ...

    def trajectory(self, controls: np.ndarray) -> Trajectory:
        """Open-loop rollout of (H, m) controls from the initial state, the whole horizon in one call."""
        ...

    def trajectory_cost(self, traj: Trajectory) -> float:
        """Total cost J of a trajectory (paper eq. J); may be inf or nan if the trajectory is."""
        ...

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        """Expansion of dynamics and costs along ``traj``, at order 1 or 2 (order 2 exact in
        both; order 1 may give Gauss-Newton cost Hessians and then says so in ``gauss_newton``)."""
        ...

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        """Closed-loop rollout around the nominal ``traj`` (forward pass of Algorithm 1, eq. dustar):
        u_j = u_bar_j - step k_j - K_j zeta_j, zeta_j = difference(x_bar_j, x_j), from the initial
        state; k (H, m), K (H, m, nx). Returns None when the state becomes non-finite."""
        ...

    # Optional member (control limits): ``control_bounds() -> (lower, upper) | None``,
    # each (H, m), -inf / inf where unbounded. A problem with bounds must keep every control of
    # ``rollout_policy`` inside them (clamping after the feedback law) and reject an initial guess
    # outside them in ``check_controls``; the solver then solves the box-constrained problem.

    # Optional member (the default start): ``quasi_static_controls() -> (H, m)``, the controls
    # the solver starts from when it is given none (geoddp.problem.Problem: those that hold the
    # initial posture against gravity, clipped into the limits; zeros without gravity). Without
    # it the solver starts from zeros projected into the limits.

    def describe(self) -> dict[str, Any]:
        """The model description a Result and the viewer need without the solver (a dict with at
        least ``kind``, ``integrator``, ``dt``, ``target_rotation`` (3, 3) and
        ``target_angular_velocity`` (3,); a multibody adds ``urdf``, ``urdf_xml``, ``root``,
        ``nq``, ``nv``)."""
        ...
