"""An off-the-shelf cross-check: scipy's L-BFGS-B on the single-shooting cost.

The cost J(U) is evaluated by rollout and its gradient by the psi recursion (Lemma lemm:psi), so
the optimiser solves exactly the discrete problem DDP solves. Used by ``geoddp compare``, the tests
and the benchmarks.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..problem import Problem
from .loop import cost_gradient


@dataclass
class ReferenceSolution:
    """L-BFGS result: cost J, controls (H, m), gradient norm, iterations, per-iteration cost and
    wall-time histories (s), and scipy's message."""

    cost: float
    controls: np.ndarray
    grad_norm: float
    iterations: int
    cost_history: np.ndarray
    time_history: np.ndarray
    message: str


def lbfgs(problem: Problem, initial_controls: np.ndarray | None = None, max_iter: int = 5000,
          gtol: float = 1e-8) -> ReferenceSolution:
    """Minimise J(U) with L-BFGS-B from ``initial_controls`` (H, m), by default from the solver's
    default start (:meth:`geoddp.problem.Problem.quasi_static_controls`: zeros without gravity)."""
    H, m = problem.horizon, problem.nu
    U0 = problem.check_controls(problem.quasi_static_controls() if initial_controls is None else initial_controls)
    history, times = [problem.total_cost(U0)], [0.0]
    t0 = time.perf_counter()

    def fg(x):
        J, g = cost_gradient(problem, x.reshape(H, m))
        return J, g.ravel()

    def callback(xk):
        history.append(problem.total_cost(xk.reshape(H, m)))
        times.append(time.perf_counter() - t0)

    res = minimize(fg, U0.ravel(), jac=True, method="L-BFGS-B", callback=callback,
                   options=dict(maxiter=max_iter, ftol=1e-15, gtol=gtol, maxcor=30))
    return ReferenceSolution(cost=float(res.fun), controls=res.x.reshape(H, m),
                             grad_norm=float(np.linalg.norm(res.jac)), iterations=int(res.nit),
                             cost_history=np.array(history), time_history=np.array(times),
                             message=str(res.message))
