"""Model predictive control: re-solve a receding horizon from the measured state, warm-started.

The problem is built once. :class:`MPC` makes the window's problem from the plan's (the same
model, costs and compiled backends: nothing is re-read or re-parsed) once per window length, and
each re-solve starts it from the measured state with
:meth:`geoddp.problem.Problem.with_initial_state`, which validates the state and nothing else.

Every ``every`` plan steps (k = 0, every, 2 every, ...):

* the window: H_mpc = ``horizon`` steps from the measured state, with the problem's costs (the
  terminal cost at the window's end; ``shrink=True`` ends the window at the plan's end instead,
  min(H_mpc, H - k) steps, and keeps H_mpc once past it);
* the warm start: the previous solution shifted by the steps elapsed, u_j <- u_{j + every}; the
  new last controls repeat the previous solution's last control (zero-order extrapolation: at a
  static target that is the holding input, e.g. the hover thrust). The first solve starts from
  the plan's controls (its first H_mpc, the last repeated if the plan is shorter);
* the solve: :func:`geoddp.solver.solve` with at most ``max_iter`` iterations (the options'
  other fields as given; not verbose).

Between re-solves the policy is the latest solution's feedback law u = u_j - K_j zeta_j at j
steps into it (at j = 0 the measured state is the window's initial state, so u = u_0).

Costs and control limits must be time-invariant (one reference per term, one bound per input): a
per-node reference or bound cannot slide with a window (InputError "policy").
"""
from __future__ import annotations

import copy
import dataclasses
import time
from typing import Any

import numpy as np

from ..problem import ControlLimits, Problem
from ..solver.result import Result
from ..solver import SolverOptions, solve
from ..validate import InputError, positive_int

DEFAULT_MAX_ITER = 3


def _check_time_invariant(problem: Any) -> None:
    for cost in (problem.running, problem.terminal):
        for i, t in enumerate(getattr(cost, "terms", [])):
            for attr in ("M_ref", "R_ref", "p_ref"):
                ref = getattr(t, attr, None)
                if ref is not None and np.shape(ref)[0] > 1:  # (K, ...) stacks of references
                    raise InputError("policy", f"MPC needs time-invariant costs; term {i} ({type(t).__name__}) has "
                                     f"{np.shape(ref)[0]} per-node references")


def _window_limits(problem: Problem) -> ControlLimits | None:
    """The plan's control limits as one (m,) bound per input, which every window takes; InputError
    "policy" where they differ between nodes."""
    bounds = problem.control_bounds()
    if bounds is None:
        return None
    lo, hi = bounds
    if not (np.all(lo == lo[0]) and np.all(hi == hi[0])):
        raise InputError("policy", "MPC needs time-invariant control limits (one bound per input); the problem's "
                         "differ between nodes")
    return ControlLimits(lo[0].copy(), hi[0].copy())


class MPC:
    """Receding-horizon re-solves of ``problem`` (see the module docstring).

    Args:
        problem: the plan's :class:`~geoddp.problem.Problem` (not modified).
        horizon: H_mpc, steps per window (default min(100, H)).
        every: re-solve every this many plan steps (>= 1).
        max_iter: iteration cap per re-solve (default 3).
        shrink: end the window at the plan's end (see the module docstring).
        plan: the plan's Result (first warm start; its horizon is the plan's end for ``shrink``).
        options: :class:`SolverOptions` of the re-solves (``max_iter`` and ``verbose`` replaced).
    """

    name = "mpc"
    horizon = None  # runs past the plan

    def __init__(self, problem: Any, *, horizon: int | None = None, every: int = 1, max_iter: int = DEFAULT_MAX_ITER,
                 shrink: bool = False, plan: Result | None = None, options: SolverOptions | None = None) -> None:
        if not isinstance(problem, Problem):
            raise InputError("problem", f"expected the plan's geoddp Problem (its model, costs and horizon), got "
                             f"{type(problem).__name__}")
        _check_time_invariant(problem)
        limits = _window_limits(problem)
        H = int(problem.horizon) if plan is None else plan.horizon
        self.H_mpc = min(100, H) if horizon is None else positive_int(horizon, "mpc.horizon")
        self.every = positive_int(every, "mpc.every")
        if self.every > self.H_mpc:
            raise InputError("mpc.every", f"expected at most the window H_mpc = {self.H_mpc} steps, got {self.every}")
        self.max_iter = positive_int(max_iter, "mpc.max_iter")
        if not isinstance(shrink, (bool, np.bool_)):
            raise InputError("mpc.shrink", f"expected True or False, got {shrink!r}")
        self.shrink, self.plan_horizon = bool(shrink), H
        if options is not None and not isinstance(options, SolverOptions):
            raise InputError("mpc.options", f"expected a geoddp.solver.SolverOptions, got {type(options).__name__}")
        base = options or SolverOptions()
        self.options = copy.copy(base)
        self.options.max_iter, self.options.verbose = self.max_iter, False
        # the window's problem: the plan's model and costs over H_mpc steps (a shrinking window's
        # shorter ones are made when first needed); each re-solve starts it from the measured state
        self._windows: dict[int, Problem] = {}
        self._plan_problem, self._limits = problem, limits
        self.problem = self._window_problem(self.H_mpc)
        m = problem.nu
        U0 = np.zeros((H, m)) if plan is None else np.asarray(plan.controls, dtype=float)
        self._first = np.vstack([U0, np.repeat(U0[-1:], max(0, self.H_mpc - len(U0)), axis=0)])[: self.H_mpc]
        self.reset()

    def reset(self) -> None:
        """Start a new run: the next solve is warm-started from the plan."""
        self._sol: Result | None = None
        self._k_sol = 0
        self.solve_times: list[float] = []
        self.iterations: list[int] = []
        self.windows: list[int] = []

    def _window_problem(self, h: int) -> Problem:
        """The plan's problem over h steps (made once per h; shares the model and the costs)."""
        p = self._windows.get(h)
        if p is None:
            p = self._windows[h] = dataclasses.replace(self._plan_problem, horizon=h, limits=self._limits)
        return p

    def _window(self, k: int) -> int:
        if self.shrink and k < self.plan_horizon:
            return min(self.H_mpc, self.plan_horizon - k)
        return self.H_mpc

    def _warm_start(self, k: int, h: int) -> np.ndarray:
        if self._sol is None:
            U = self._first
        else:
            prev = self._sol.controls[k - self._k_sol:]  # shift by the steps elapsed
            U = np.vstack([prev, np.repeat(prev[-1:] if len(prev) else self._sol.controls[-1:],
                                           max(0, h - len(prev)), axis=0)])
        return np.ascontiguousarray(U[:h])

    def control(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """u at plan step k for the measured state (q, v); re-solves when k is a multiple of ``every``."""
        if self._sol is None or k - self._k_sol >= self.every:
            h = self._window(k)
            U = self._warm_start(k, h)
            p = self._window_problem(h).with_initial_state(q, v)  # validates the state only
            t0 = time.perf_counter()
            self._sol = solve(p, self.options, initial_controls=U)
            self.solve_times.append(time.perf_counter() - t0)
            self.iterations.append(self._sol.iterations)
            self.windows.append(h)
            self._k_sol = k
        j = k - self._k_sol
        s = self._sol
        if j == 0:
            return s.controls[0].copy()
        zeta = self.problem.model.local(s.q[j], s.v[j], q, v)
        return s.controls[j] - s.feedback[j] @ zeta

    def stats(self) -> dict[str, Any]:
        """Per re-solve: ``solve_times_s`` and ``iterations`` (lists), and their summary:
        median / p95 / max solve time (s), mean iterations, and the real-time factor (simulated
        time / time spent solving)."""
        t = np.asarray(self.solve_times)
        if t.size == 0:
            return {}
        sim_time = len(t) * self.every * self.problem.dt
        return {"solves": int(t.size), "solve_times_s": t.tolist(), "iterations": list(self.iterations),
                "solve_median_s": float(np.median(t)), "solve_p95_s": float(np.percentile(t, 95)),
                "solve_max_s": float(t.max()), "iterations_mean": float(np.mean(self.iterations)),
                "iterations_max": int(np.max(self.iterations)), "real_time_factor": float(sim_time / t.sum()),
                "horizon": self.H_mpc, "every": self.every, "max_iter": self.max_iter}
