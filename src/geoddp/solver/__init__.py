"""Geometric DDP (Algorithm 1 of the paper), split into named steps.

    options.py    SolverOptions: the only home of every solver default (and of EXPANSIONS)
    loop.py       solve(): Algorithm 1 as a short loop over named steps (direction, backward pass,
                  stopping tests, line search, accept, regularisation update)
    policy.py     the expansion switch and the early-certification rules
    callbacks.py  what a solve reports as it runs: the verbose table, the history recorder
    backward.py   Riccati wrappers over the compiled kernels; regularisation; the gradient
    ladder.py     the lambda ladder of the backward pass's restarts
    forward.py    the line search
    saddle.py     the saddle escape
    status.py     the status strings
    result.py     the Result a solve returns (its kinds: satellite, multibody) and its JSON
    reference.py  a second solver for cross-checks: scipy's L-BFGS on the same problem

``from geoddp.solver import solve, SolverOptions, cost_gradient`` is the public route.
"""
from __future__ import annotations

from .loop import cost_gradient, solve
from .options import EXPANSIONS, SolverOptions
from .status import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_LINALG,
    STATUS_MAX_ITER,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_NON_FINITE,
    STATUS_SADDLE,
    STATUS_STALLED,
)

__all__ = ["solve", "SolverOptions", "cost_gradient", "EXPANSIONS", "STATUS_CONVERGED_COST", "STATUS_CONVERGED_GRAD",
           "STATUS_MAX_ITER", "STATUS_MAX_REG", "STATUS_NO_DESCENT", "STATUS_SADDLE", "STATUS_STALLED",
           "STATUS_NON_FINITE", "STATUS_LINALG"]
