"""One recorder of the iterates: appends once per accepted step (line-search steps and saddle
escapes alike), so every history has one entry per iterate or per step."""
from __future__ import annotations

import time

import numpy as np


class History:
    """cost/grad/time (and controls) per iterate; reg/step/expansion per accepted step.

    The gradient of an iterate is known only after its linearisation, one call after the step
    that reached it: :meth:`gradient` fills it once (later calls at the same iterate are ignored).
    """

    def __init__(self, J0: float, U0: np.ndarray, t_start: float, record_controls: bool) -> None:
        self.t_start = t_start
        self.cost = [J0]
        self.grad: list[float] = []
        self.reg: list[float] = []
        self.step: list[float] = []
        self.expansion: list[str] = []
        self.time = [time.perf_counter() - t_start]
        self.controls = [U0.copy()] if record_controls else None

    def needs_gradient(self) -> bool:
        """True while the current iterate's gradient norm is not recorded yet."""
        return len(self.grad) < len(self.cost)

    def gradient(self, gnorm: float) -> None:
        """Record ||dJ/dU|| at the current iterate (once)."""
        if self.needs_gradient():
            self.grad.append(gnorm)

    def accept(self, J: float, reg: float, step: float, expansion: str, U: np.ndarray) -> None:
        """Record an accepted step to a new iterate with cost J and controls U (H, m)."""
        self.cost.append(J)
        self.time.append(time.perf_counter() - self.t_start)
        self.reg.append(reg)
        self.step.append(step)
        self.expansion.append(expansion)
        if self.controls is not None:
            self.controls.append(U.copy())

    def arrays(self) -> dict:
        """The Result's history fields."""
        return dict(
            cost_history=np.array(self.cost), grad_norm_history=np.array(self.grad),
            reg_history=np.array(self.reg), step_history=np.array(self.step),
            expansion_history=self.expansion, time_history=np.array(self.time),
            control_history=np.array(self.controls) if self.controls is not None else None,
        )
