"""The augmented Lagrangian of a constrained problem for fixed multipliers: an ordinary cost.

For multipliers lambda and a penalty mu > 0 of one constraint (rows c_i at its nodes), the
Powell-Hestenes-Rockafellar (PHR) augmented Lagrangian terms are (Nocedal & Wright, Numerical
Optimization, 2nd ed., eqs. 17.36 and 17.65; Birgin & Martinez, Practical Augmented Lagrangian
Methods, 2014, ch. 4)

    equality   c = 0:   phi = lambda c + mu/2 c^2,                 lhat = lambda + mu c
    inequality c <= 0:  phi = (max(0, lambda + mu c)^2 - lambda^2) / (2 mu),   lhat = max(0, lambda + mu c)

with gradient lhat dc and Hessian mu dc dc^T (on the rows where lambda + mu c > 0, all rows of an
equality) + lhat d2c. lhat is the first-order multiplier estimate: the gradient of the augmented
Lagrangian at (lambda, mu) is that of the Lagrangian J + sum lhat c at the multipliers lhat, so
the inner solve's certificate (gradient norm, Newton decrement) at lambda is the Lagrangian's
stationarity at lhat.

:class:`AugmentedLagrangianProblem` wraps a problem and adds these terms to its running cost at
nodes k = 1..H-1 and its terminal cost at k = H: ``trajectory_cost`` adds phi, ``linearise``
adds lhat J_c to l_x and mu J_c^T J_c + sum lhat Hess c to l_xx (the paper's l_g and l_gg, eqs.
leftell; Hess c in the same (0)-Hessian sense). The dynamics, the controls' box limits and the
rest of the expansion are the wrapped problem's, untouched, so the inner solve is the exact
second-order DDP (first, second or switch) of the solver. A Gauss-Newton first-order
linearisation (``Linearisation.gauss_newton``) keeps its meaning: the constraint curvature
sum lhat Hess c is left out there, mu J_c^T J_c (the Gauss-Newton part) stays.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..problem.contract import Linearisation, Trajectory
from .kinds import Bound

__all__ = ["Placed", "AugmentedLagrangianProblem", "merit", "multiplier_estimate"]


@dataclass
class Placed:
    """A bound constraint at its nodes.

    Attributes:
        bound: the :class:`~geoddp.constraints.kinds.Bound` evaluator.
        nodes: (N,) node indices k in 1..H (int).
    """

    bound: Bound
    nodes: np.ndarray

    def states(self, traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
        """The trajectory's states at the nodes: q (N, ...), v (N, nv)."""
        return traj.q[self.nodes], traj.v[self.nodes]


def multiplier_estimate(c: np.ndarray, lam: np.ndarray, mu: float, equality: bool) -> np.ndarray:
    """lhat (N, nc): lambda + mu c (equality) or max(0, lambda + mu c) (inequality)."""
    t = lam + mu * c
    return t if equality else np.maximum(t, 0.0)


def merit(c: np.ndarray, lam: np.ndarray, mu: float, equality: bool) -> float:
    """The PHR terms summed over nodes and rows (units of the cost J)."""
    if equality:
        return float(np.sum(lam * c + 0.5 * mu * c * c))
    t = np.maximum(lam + mu * c, 0.0)
    return float(np.sum(t * t - lam * lam) / (2.0 * mu))


class AugmentedLagrangianProblem:
    """``problem`` with the augmented Lagrangian terms of its constraints added to its costs.

    Satisfies :class:`geoddp.problem.contract.OptimalControlProblem` (the inner problem of the outer loop,
    :func:`geoddp.constraints.solve_constrained`).

    Args:
        problem: the unconstrained problem (any contract problem; states as its trajectories hold them).
        constraints: the :class:`Placed` constraints.
        multipliers: one (N_j, nc_j) array per constraint (lambda, >= 0 for inequalities).
        penalties: one mu_j > 0 per constraint.
    """

    def __init__(self, problem: Any, constraints: list[Placed], multipliers: list[np.ndarray],
                 penalties: list[float]) -> None:
        self.problem = problem
        self.constraints = list(constraints)
        self.multipliers = [np.asarray(m, dtype=float) for m in multipliers]
        self.penalties = [float(m) for m in penalties]
        self.nx, self.nu, self.horizon, self.dt = problem.nx, problem.nu, problem.horizon, problem.dt

    # ---------------------------------------------------------------- the contract, delegated
    def check_controls(self, controls: np.ndarray, name: str = "initial_controls") -> np.ndarray:
        return self.problem.check_controls(controls, name)

    def trajectory(self, controls: np.ndarray) -> Trajectory:
        return self.problem.trajectory(controls)

    def rollout_policy(self, traj: Trajectory, k: np.ndarray, K: np.ndarray, step: float) -> Trajectory | None:
        return self.problem.rollout_policy(traj, k, K, step)

    def describe(self) -> dict[str, Any]:
        return self.problem.describe()

    def control_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        bounds = getattr(self.problem, "control_bounds", None)
        return None if bounds is None else bounds()

    def __getattr__(self, name: str) -> Any:
        # the contract's optional default start, exactly when the wrapped problem offers it (the
        # solver tests hasattr): an inner solve without initial controls starts where the
        # unconstrained one would (quasi-static for a robot arm, not zero torques)
        if name == "quasi_static_controls":
            return getattr(self.problem, name)
        raise AttributeError(name)

    # ---------------------------------------------------------------- the terms added
    def values(self, traj: Trajectory) -> list[np.ndarray]:
        """c (N_j, nc_j) of every constraint along ``traj``."""
        return [p.bound.value(*p.states(traj)) for p in self.constraints]

    def augmentation(self, traj: Trajectory) -> float:
        """sum over constraints of the PHR terms along ``traj`` (units of J)."""
        total = 0.0
        for p, c, lam, mu in zip(self.constraints, self.values(traj), self.multipliers, self.penalties):
            total += merit(c, lam, mu, p.bound.equality)
        return total

    def trajectory_cost(self, traj: Trajectory) -> float:
        """J + the augmented Lagrangian terms (the merit the inner solve minimises)."""
        J = self.problem.trajectory_cost(traj)
        if not np.isfinite(J):
            return J
        return J + self.augmentation(traj)

    def linearise(self, traj: Trajectory, order: int) -> Linearisation:
        """The wrapped problem's expansion with the terms' gradients and Hessians added into
        l_x, l_xx (k = 1..H-1) and lf_x, lf_xx (k = H); the arrays it modifies are copies."""
        lin = self.problem.linearise(traj, order)
        H = self.horizon
        l_x, l_xx = lin.l_x.copy(), lin.l_xx.copy()
        lf_x, lf_xx = lin.lf_x.copy(), lin.lf_xx.copy()
        exact = not lin.gauss_newton
        for p, lam, mu in zip(self.constraints, self.multipliers, self.penalties):
            q, v = p.states(traj)
            eq = p.bound.equality
            nodes = p.nodes
            if not eq:
                # an inequality row with lambda + mu c <= 0 adds nothing (lhat = 0, off the
                # Gauss-Newton part): only the nodes with an active row are differentiated
                act = np.flatnonzero(np.any(lam + mu * p.bound.value(q, v) > 0.0, axis=1))
                if act.size == 0:
                    continue
                if act.size < nodes.size:
                    q, v, lam, nodes = q[act], v[act], lam[act], nodes[act]
            # the Hessian's weights are the multiplier estimates at c: handed over as a function of
            # c, so the constraint evaluates its kinematics once
            c, J, Hw = p.bound.derivatives(q, v, (lambda c_, lam=lam, mu=mu, eq=eq: multiplier_estimate(c_, lam, mu, eq))
                                           if exact else None)
            lhat = multiplier_estimate(c, lam, mu, eq)
            grad = np.matmul(lhat[:, None, :], J)[:, 0]  # sum_i lhat_i dc_i (N, nx)
            Jon = J if eq else J * (lam + mu * c > 0.0)[:, :, None]
            hess = mu * np.matmul(np.swapaxes(Jon, 1, 2), J)  # mu J_c^T J_c on the active rows
            if exact:
                hess += Hw
            run = nodes < H
            k = nodes[run]
            # the nodes are distinct: a fancy-indexed += adds each once
            l_x[k] += grad[run]
            l_xx[k] += hess[run]
            if not run.all():
                lf_x += grad[~run].sum(axis=0)
                lf_xx += hess[~run].sum(axis=0)
        return dataclasses.replace(lin, l_x=l_x, l_xx=l_xx, lf_x=lf_x, lf_xx=lf_xx)
