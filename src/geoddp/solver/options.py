"""Solver options: the only home of every solver default and of the list of expansions.

Scene readers take their ``[solver]`` defaults from here (:data:`DEFAULT_EXPANSION`, ...), so a
default changes in one place. Options are validated where they enter; the solver trusts them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, TextIO

import numpy as np

from ..validate import InputError, choice, keywords_checked, nonnegative_float, positive_float, positive_int

EXPANSIONS = ("first", "second", "switch")

DEFAULT_EXPANSION = "switch"
DEFAULT_SWITCH_RATIO = 0.1
DEFAULT_SWITCH_AFTER = 5
DEFAULT_TOL = 1e-8
DEFAULT_GRAD_TOL = 1e-10
DEFAULT_MAX_ITER = 200
DEFAULT_REG_INIT = 0.0
DEFAULT_REG_MIN = 1e-8
DEFAULT_REG_MAX = 1e10
DEFAULT_REG_INCREASE = 1.9  # the paper's factor
DEFAULT_STEP_FACTOR = 1.0 / 3.0  # the paper's h
DEFAULT_MIN_STEP = 1e-10


@keywords_checked
@dataclass
class SolverOptions:
    """Options of :func:`geoddp.solver.solve`.

    Attributes:
        expansion: "first" (Phi, B only; with Gauss-Newton cost Hessians where the costs offer
            them: every multibody residual term), "second" (with Theta, Gamma, Xi and exact cost
            Hessians) or "switch" (first until J_i / J_0 < switch_ratio, then second; the
            paper's proposal), or after ``switch_after`` first-order iterations, or when a
            first-order step passes the cost test (``tol``), whichever comes first.
        switch_ratio: sigma of the switch rule, in (0, 1). Not applied when the first-order
            model is a Gauss-Newton one (multibody costs): it keeps converging like FDDP, and
            handing over early gave 1.5-3x slower solves on the real robots.
        switch_after: also switch after this many first-order iterations. The paper's test alone
            never fires when the optimum keeps most of the initial cost (a tumbling start,
            1:1000 inertia, an underactuated body), where first order then grinds on at a
            linear rate for tens of iterations. With a Gauss-Newton first-order model only full
            (gamma = 1) first-order steps count, at most 4 switch_after iterations in all, and
            not while the last one converged superlinearly (see geoddp.solver.loop).
        tol: stop when |J_i - J_(i-1)| <= tol.
        grad_tol: stop when ||dJ/dU||_2 <= grad_tol.
        max_iter: maximum number of accepted iterations.
        reg_init, reg_min, reg_max: Q_uu regularisation lambda (start, floor, ceiling).
        reg_increase: factor on lambda when Q_uu is not positive definite (paper: 1.9).
        step_factor: line-search factor h (paper: 1/3); min_step: smallest gamma tried.
        verbose: print the per-iteration table.
        record_controls: keep the controls of every iterate in the result.
        stream: where the table goes (sys.stdout when None).
        callbacks: objects whose hooks the solve calls as it runs, after the history recorder and
            the verbose table (:mod:`geoddp.solver.callbacks`: subclass ``Callback``); none by
            default.

    The derivative backend is not an option of the solver: it is chosen when the model is built
    (by structure for the satellite, ``Multibody(..., backend=...)`` for a multibody model).
    """

    expansion: str = DEFAULT_EXPANSION
    switch_ratio: float = DEFAULT_SWITCH_RATIO
    switch_after: int = DEFAULT_SWITCH_AFTER
    tol: float = DEFAULT_TOL
    grad_tol: float = DEFAULT_GRAD_TOL
    max_iter: int = DEFAULT_MAX_ITER
    reg_init: float = DEFAULT_REG_INIT
    reg_min: float = DEFAULT_REG_MIN
    reg_max: float = DEFAULT_REG_MAX
    reg_increase: float = DEFAULT_REG_INCREASE
    step_factor: float = DEFAULT_STEP_FACTOR
    min_step: float = DEFAULT_MIN_STEP
    verbose: bool = True
    record_controls: bool = False
    stream: TextIO | None = field(default=None, repr=False)
    callbacks: tuple[Any, ...] = field(default=(), repr=False)

    def __post_init__(self) -> None:
        self.expansion = choice(self.expansion, "expansion", EXPANSIONS)
        self.switch_ratio = positive_float(self.switch_ratio, "switch_ratio")
        if not self.switch_ratio < 1.0:
            raise InputError("switch_ratio", f"expected a number in (0, 1), got {self.switch_ratio}")
        self.switch_after = positive_int(self.switch_after, "switch_after")
        self.tol = nonnegative_float(self.tol, "tol")
        self.grad_tol = nonnegative_float(self.grad_tol, "grad_tol")
        self.max_iter = positive_int(self.max_iter, "max_iter")
        self.reg_init = nonnegative_float(self.reg_init, "reg_init")
        self.reg_min = positive_float(self.reg_min, "reg_min")
        self.reg_max = positive_float(self.reg_max, "reg_max")
        self.reg_increase = positive_float(self.reg_increase, "reg_increase")
        self.step_factor = positive_float(self.step_factor, "step_factor")
        self.min_step = positive_float(self.min_step, "min_step")
        # a schedule that does not increase would loop forever on an indefinite Q_uu
        if not self.reg_increase > 1.0:
            raise InputError("reg_increase", f"expected a factor > 1 (lambda must grow), got {self.reg_increase}")
        if self.reg_min > self.reg_max:
            raise InputError("reg_min", f"expected reg_min <= reg_max = {self.reg_max}, got {self.reg_min}")
        if self.reg_init > self.reg_max:
            raise InputError("reg_init", f"expected reg_init <= reg_max = {self.reg_max}, got {self.reg_init}")
        if not self.step_factor < 1.0:
            raise InputError("step_factor", f"expected a number in (0, 1) (gamma must shrink), got {self.step_factor}")
        if not self.min_step <= 1.0:
            raise InputError("min_step", f"expected a number in (0, 1], got {self.min_step}")
        for name in ("verbose", "record_controls"):
            val = getattr(self, name)
            if not isinstance(val, (bool, np.bool_)):
                raise InputError(name, f"expected True or False, got {val!r} ({type(val).__name__})")
            setattr(self, name, bool(val))
        if self.stream is not None and not callable(getattr(self.stream, "write", None)):
            raise InputError("stream", f"expected None or a text stream with write(), got {type(self.stream).__name__}")
        if isinstance(self.callbacks, (str, bytes)) or not hasattr(self.callbacks, "__iter__"):
            raise InputError("callbacks", f"expected a sequence of callbacks, got {type(self.callbacks).__name__}")
        self.callbacks = tuple(self.callbacks)
        for i, cb in enumerate(self.callbacks):
            missing = [h for h in ("on_start", "on_gradient", "on_iteration", "on_finish")
                       if not callable(getattr(cb, h, None))]
            if missing:
                raise InputError(f"callbacks[{i}]", f"expected a callback (a geoddp.solver.callbacks.Callback), got "
                                 f"{type(cb).__name__} without {', '.join(missing)}")
