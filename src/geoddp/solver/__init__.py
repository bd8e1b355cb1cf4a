"""Geometric DDP (Algorithm 1 of the paper), split into named steps.

    options.py   SolverOptions: the only home of every solver default (and of EXPANSIONS)
    loop.py      solve(): a short loop over direction, step, stopping test, regularisation update
    backward.py  Riccati wrappers over the compiled kernels; regularisation; the gradient
    forward.py   the line search
    saddle.py    the saddle escape
    status.py    the status strings
    history.py   the one recorder of the iterates

``from geoddp.solver import solve, SolverOptions, cost_gradient`` is the public route. The names
load lazily (PEP 562) so that :mod:`geoddp.result`, which :mod:`.loop` imports, can import the
status strings from :mod:`.status` without an import circle.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .options import EXPANSIONS, SolverOptions
from .status import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_MAX_ITER,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_SADDLE,
    STATUS_STALLED,
    STATUS_NON_FINITE,
    STATUS_LINALG,
)

if TYPE_CHECKING:
    from .loop import cost_gradient, solve

__all__ = ["solve", "SolverOptions", "cost_gradient", "EXPANSIONS", "STATUS_CONVERGED_COST", "STATUS_CONVERGED_GRAD",
           "STATUS_MAX_ITER", "STATUS_MAX_REG", "STATUS_NO_DESCENT", "STATUS_SADDLE", "STATUS_STALLED",
           "STATUS_NON_FINITE", "STATUS_LINALG"]


def __getattr__(name: str) -> Any:
    if name in ("solve", "cost_gradient"):
        from . import loop

        return getattr(loop, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
