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
# Stopping (see SolverOptions.cost_tolerance): relative to |J| by default, so that scaling every
# weight by c changes nothing; an absolute ``tol`` (the paper's Table I criterion, 1e-8) replaces it
# when given, and then the gradient test is absolute too (DEFAULT_GRAD_TOL), as before.
DEFAULT_RTOL = 1e-11
DEFAULT_GRAD_RTOL = 1e-12
DEFAULT_GRAD_TOL = 1e-10
# The relative tests measure |J| from ZERO_COST |J_0| up (J_0: the cost of the initial guess):
# where the optimum is J* = 0 (every residual can vanish), rtol |J| shrinks with J and no test
# would pass before round-off stalls the line search (a free spin reached exactly: 68 iterations,
# "stalled" at J = 2e-26, where the absolute tol stopped after 2); below 1e-12 of the initial
# cost, J counts as zero. Scaling every weight by c scales J_0 too: the rule stays scale-free.
ZERO_COST = 1e-12
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
            first-order step passes the cost test (``tol``), whichever comes first. A
            second-order iteration whose Q_uu no lambda up to ``reg_max`` makes positive definite
            hands back to first order until a first-order step is full and unregularised
            (:mod:`geoddp.solver.policy`).
        switch_ratio: sigma of the switch rule, in (0, 1). Not applied when the first-order
            model is a Gauss-Newton one (multibody costs): it keeps converging like FDDP, and
            handing over early gave 1.5-3x slower solves on the real robots.
        switch_after: also switch after this many first-order iterations. The paper's test alone
            never fires when the optimum keeps most of the initial cost (a tumbling start,
            1:1000 inertia, an underactuated body), where first order then grinds on at a
            linear rate for tens of iterations. With a Gauss-Newton first-order model only full
            (gamma = 1) first-order steps count, at most 4 switch_after iterations in all, and
            not while the last one converged superlinearly (see geoddp.solver.loop).
        tol: absolute tolerance, in units of J: stop when |J_i - J_(i-1)| <= tol, and call the
            returned point converged when its Newton decrement is <= tol (the paper's Table I
            criterion: tol = 1e-8). None (the default): not used.
        rtol: relative tolerance: the same tests against rtol |J_i|. None (the default): 1e-11
            (:data:`DEFAULT_RTOL`) when ``tol`` is None too, else not used. Given both, either
            test suffices: the threshold is max(tol, rtol |J_i|) (:meth:`cost_tolerance`).
        grad_tol: stop when ||dJ/dU||_2 <= grad_tol (absolute, units of J per unit of u).
            None (the default): 1e-10 (:data:`DEFAULT_GRAD_TOL`) when the cost test is absolute
            (``tol`` given, ``rtol`` not), else not used.
        grad_rtol: stop when ||dJ/dU||_2 <= grad_rtol |J_i|. None (the default): 1e-12
            (:data:`DEFAULT_GRAD_RTOL`) unless the cost test is absolute or ``grad_tol`` is given.
            Given both: max(grad_tol, grad_rtol |J_i|) (:meth:`grad_tolerance`).
        max_iter: maximum number of accepted iterations.
        reg_init, reg_min, reg_max: Q_uu regularisation lambda (start, floor, ceiling).
        reg_increase: factor on lambda when Q_uu is not positive definite (paper: 1.9).
        step_factor: line-search factor h (paper: 1/3); min_step: smallest gamma tried.
        verbose: print the per-iteration table and the final line (on ``stream``); False by
            default: a solve from Python is silent unless asked (the command line prints the
            table unless ``--quiet``).
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
    tol: float | None = None
    rtol: float | None = None
    grad_tol: float | None = None
    grad_rtol: float | None = None
    max_iter: int = DEFAULT_MAX_ITER
    reg_init: float = DEFAULT_REG_INIT
    reg_min: float = DEFAULT_REG_MIN
    reg_max: float = DEFAULT_REG_MAX
    reg_increase: float = DEFAULT_REG_INCREASE
    step_factor: float = DEFAULT_STEP_FACTOR
    min_step: float = DEFAULT_MIN_STEP
    verbose: bool = False
    record_controls: bool = False
    stream: TextIO | None = field(default=None, repr=False)
    callbacks: tuple[Any, ...] = field(default=(), repr=False)

    def __post_init__(self) -> None:
        self.expansion = choice(self.expansion, "expansion", EXPANSIONS)
        self.switch_ratio = positive_float(self.switch_ratio, "switch_ratio")
        if not self.switch_ratio < 1.0:
            raise InputError("switch_ratio", f"expected a number in (0, 1), got {self.switch_ratio}")
        self.switch_after = positive_int(self.switch_after, "switch_after")
        for name in ("tol", "rtol", "grad_tol", "grad_rtol"):
            if getattr(self, name) is not None:
                setattr(self, name, nonnegative_float(getattr(self, name), name))
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

    # ------------------------------------------------------------ the stopping thresholds
    # The fields keep what the user gave (None = not given), so that dataclasses.replace(opt,
    # tol=...) means what it says; the defaults are resolved here, on each call.
    def absolute(self) -> bool:
        """True when the cost test is absolute only (``tol`` given, ``rtol`` not): the paper's
        criterion, and the scene files that set ``tol``."""
        return self.tol is not None and self.rtol is None

    def cost_tolerance(self, J: float, J0: float = 0.0) -> float:
        """The threshold on |J_i - J_(i-1)| and on the Newton decrement at cost J, J0 being the
        cost of the initial guess: max(tol, rtol max(|J|, ZERO_COST |J0|)), a missing tol
        counting 0 and a missing rtol DEFAULT_RTOL (0 if tol is given). Relative by default:
        multiplying every weight by c multiplies J, J0, every |dJ| and every decrement by c, and
        this threshold with them."""
        tol = 0.0 if self.tol is None else self.tol
        rtol = self.rtol if self.rtol is not None else (0.0 if self.tol is not None else DEFAULT_RTOL)
        return max(tol, rtol * max(abs(J), ZERO_COST * abs(J0))) if rtol else tol

    def grad_tolerance(self, J: float, J0: float = 0.0) -> float:
        """The threshold on ||dJ/dU|| at cost J: max(grad_tol, grad_rtol max(|J|, ZERO_COST
        |J0|)); when neither is given, DEFAULT_GRAD_TOL with an absolute cost test
        (:meth:`absolute`), else the relative test with DEFAULT_GRAD_RTOL."""
        if self.grad_tol is None and self.grad_rtol is None:
            if self.absolute():
                return DEFAULT_GRAD_TOL
            return DEFAULT_GRAD_RTOL * max(abs(J), ZERO_COST * abs(J0))
        gtol = 0.0 if self.grad_tol is None else self.grad_tol
        grtol = 0.0 if self.grad_rtol is None else self.grad_rtol
        return max(gtol, grtol * max(abs(J), ZERO_COST * abs(J0))) if grtol else gtol

    def stopping_rule(self) -> str:
        """The cost test in words, for messages: "tol = 1e-08", "rtol = 1e-11" or both."""
        if self.absolute():
            return f"tol = {self.tol:g}"
        rtol = DEFAULT_RTOL if self.rtol is None else self.rtol
        return f"rtol = {rtol:g}" + ("" if self.tol is None else f", tol = {self.tol:g}")
