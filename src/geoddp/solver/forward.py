"""The forward pass with line search (Algorithm 1, inner repeat)."""
from __future__ import annotations

import numpy as np

from ..problem.contract import OptimalControlProblem, Trajectory
from .options import SolverOptions


def line_search(
    problem: OptimalControlProblem, nominal: Trajectory, J: float, k: np.ndarray, K: np.ndarray, opt: SolverOptions,
    full_step_only: bool = False,
) -> tuple[Trajectory, float, float] | None:
    """Closed-loop rollouts with gamma = 1, h, h^2, ... (h = step_factor) until J_new <= J (the
    paper's test), down to min_step. Returns (trajectory, J_new, gamma), or None if no gamma
    decreased J (or every trial went non-finite). With ``full_step_only`` only gamma = 1 is tried
    (the caller knows no shorter step can matter: see ``Solve.iterate``)."""
    gamma = 1.0
    while gamma >= (1.0 if full_step_only else opt.min_step):
        trial = problem.rollout_policy(nominal, k, K, gamma)
        J_new = problem.trajectory_cost(trial) if trial is not None else np.inf
        if np.isfinite(J_new) and J_new <= J:
            return trial, J_new, gamma
        gamma *= opt.step_factor
    return None
