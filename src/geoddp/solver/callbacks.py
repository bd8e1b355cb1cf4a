"""What a solve reports as it runs: hooks called once per event, never per node.

A callback is an object with four hooks (:class:`Callback` gives each a do-nothing default, as
Crocoddyl's ``CallbackAbstract`` and Aligator's ``CallbackBase`` do for their solvers):

    on_start(start)      the initial iterate (:class:`Start`), before the first iteration
    on_gradient(g)       ||dJ/dU|| of the current iterate, once per iterate, when first computed
                         (its linearisation comes one iteration after the step that reached it)
    on_iteration(step)   an accepted step to a new iterate (:class:`Step`): a line-search step
                         or a saddle escape
    on_finish(end)       after the final check (:class:`Finish`), before the Result is built

Every solve runs a :class:`History` (the recorder of the Result's histories), then a
:class:`VerboseTable` when ``SolverOptions.verbose``, then ``SolverOptions.callbacks`` in order.
A callback reads the records and must not change the arrays it is handed.
"""
from __future__ import annotations

from typing import NamedTuple, TextIO

import numpy as np


class Start(NamedTuple):
    """The initial iterate of a solve."""

    cost: float  #: J at the initial controls
    controls: np.ndarray  #: (H, m) initial controls
    time: float  #: seconds from the start of the solve (the initial rollout's time)


class Step(NamedTuple):
    """An accepted step from the nominal iterate (``iteration``, ``cost``, ``grad_norm``) to a new one."""

    iteration: int  #: i, the number of the nominal iterate (0 for the initial guess)
    cost: float  #: J_i at the nominal iterate
    grad_norm: float  #: ||dJ/dU|| there (projected with control limits)
    new_cost: float  #: J_(i+1) at the new iterate
    reg: float  #: the Q_uu regularisation lambda of the step
    step: float  #: the line search's gamma (a saddle escape: |alpha| along negative curvature)
    expansion: str  #: "first" or "second" (a saddle escape uses the exact second-order check)
    rungs: int  #: rungs of the lambda ladder climbed in the backward pass (0 for an escape)
    escape: bool  #: a step along negative curvature out of a saddle (geoddp.solver.saddle)
    controls: np.ndarray  #: (H, m) controls of the new iterate
    time: float  #: seconds from the start of the solve at which the new iterate was reached


class Finish(NamedTuple):
    """How a solve ended (the Result's status, message and certificate)."""

    status: str  #: one of the STATUS_* strings of geoddp.solver.status
    message: str
    converged: bool
    cost: float  #: J at the returned iterate
    grad_norm: float  #: ||dJ/dU|| the final check computed there (NaN if the check failed)
    iterations: int
    solve_time: float  #: seconds


class Callback:
    """Base class of the solver's callbacks: every hook does nothing."""

    def on_start(self, start: Start) -> None:
        """The solve starts from ``start``."""

    def on_gradient(self, grad_norm: float) -> None:
        """The gradient norm of the current iterate, first known now."""

    def on_iteration(self, step: Step) -> None:
        """A step was accepted."""

    def on_finish(self, end: Finish) -> None:
        """The solve ended."""


class History(Callback):
    """The one recorder of the iterates: cost/grad/time (and controls) per iterate; reg/step/
    expansion per accepted step (line-search steps and saddle escapes alike), so every history has
    one entry per iterate or per step.

    The gradient of an iterate is known only after its linearisation, one call after the step
    that reached it: it is recorded once, at :meth:`on_gradient` (a later linearisation of the
    same iterate, in an iteration redone with more regularisation or in the final check, adds
    nothing).
    """

    def __init__(self, record_controls: bool) -> None:
        self.cost: list[float] = []
        self.grad: list[float] = []
        self.reg: list[float] = []
        self.step: list[float] = []
        self.expansion: list[str] = []
        self.time: list[float] = []
        self.controls: list[np.ndarray] | None = [] if record_controls else None

    def on_start(self, start: Start) -> None:
        self.cost.append(start.cost)
        self.time.append(start.time)
        if self.controls is not None:
            self.controls.append(start.controls.copy())

    def on_gradient(self, grad_norm: float) -> None:
        self.grad.append(grad_norm)

    def on_iteration(self, step: Step) -> None:
        self.cost.append(step.new_cost)
        self.time.append(step.time)
        self.reg.append(step.reg)
        self.step.append(step.step)
        self.expansion.append(step.expansion)
        if self.controls is not None:
            self.controls.append(step.controls.copy())

    def arrays(self) -> dict:
        """The Result's history fields."""
        return dict(
            cost_history=np.array(self.cost), grad_norm_history=np.array(self.grad),
            reg_history=np.array(self.reg), step_history=np.array(self.step),
            expansion_history=self.expansion, time_history=np.array(self.time),
            control_history=np.array(self.controls) if self.controls is not None else None,
        )


class VerboseTable(Callback):
    """The per-iteration table and the final line (``SolverOptions.verbose``), on ``stream``."""

    def __init__(self, stream: TextIO) -> None:
        self.out = stream

    def on_start(self, start: Start) -> None:
        # One row per iteration: the nominal iterate's J and gradient, then the step taken from it;
        # 'rungs': how many rungs of its ladder lambda climbed there (the paper's restarts; the passes
        # that found them are fewer, geoddp.solver.ladder)
        self.out.write(f"{'iter':>4} {'cost':>20} {'|grad|':>10} {'dJ':>11} {'lambda':>9} {'gamma':>7} {'exp':>6} "
                       f"{'rungs':>8}\n")

    def on_iteration(self, step: Step) -> None:
        s, exp_name = step, "escape" if step.escape else step.expansion
        self.out.write(f"{s.iteration:4d} {s.cost:20.14e} {s.grad_norm:10.3e} {s.new_cost - s.cost:11.3e} {s.reg:9.2e} "
                       f"{s.step:7.4f} {exp_name:>6} {s.rungs:8d}\n")
        self.out.flush()

    def on_finish(self, end: Finish) -> None:
        self.out.write(f"{end.status} ({end.message}); J = {end.cost:.12e}, ||grad|| = {end.grad_norm:.3e}, "
                       f"{end.iterations} iterations, {end.solve_time*1e3:.1f} ms\n")
