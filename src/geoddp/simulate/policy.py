"""Policies that fly a plan: open loop and the DDP feedback law (MPC: :mod:`.mpc`).

A policy answers ``control(k, q, v) -> u (m,)`` at plan step k for the measured state (q, v) in
the plan's representation; ``reset()`` starts a new run; ``stats()`` returns what it measured
(MPC: solve times). Policies are evaluated once per plan step (the plant holds u over its
substeps).

The feedback law is the one the backward pass computes (paper eq. dustar at the converged
iterate, where the feedforward k vanishes): u_k = u_bar_k - K_k zeta_k, with zeta_k the model's
tangent difference of the measured state from the plan's, :meth:`local(x_bar_k, x)`
(satellite: (log(R_bar_k^T R), Omega - Omega_bar_k); multibody: (difference(q_bar_k, q),
v - v_bar_k)): the same chart the solver's forward pass uses.
"""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from ..solver.result import Result
from ..validate import InputError


class Policy(Protocol):
    """What :func:`geoddp.simulate.simulate` asks of a policy."""

    name: str
    horizon: int | None  # last plan step it can answer (None: any k)

    def reset(self) -> None: ...

    def control(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray: ...

    def stats(self) -> dict[str, Any]: ...


def _check_plan(result: Any, model: Any) -> Result:
    if not isinstance(result, Result):
        raise InputError("result", f"expected a geoddp Result (from geoddp.solver.solve), got {type(result).__name__}")
    H, m = result.controls.shape
    if m != model.nu or result.feedback.shape != (H, m, model.nx):
        raise InputError("result", f"expected a plan of the model (m = {model.nu}, nx = {model.nx}), got controls "
                         f"{result.controls.shape} and gains {result.feedback.shape}")
    return result


class OpenLoop:
    """u_k = u_bar_k: the plan's controls, whatever the state."""

    name = "open"

    def __init__(self, result: Result, model: Any) -> None:
        self.plan = _check_plan(result, model)
        self.horizon = self.plan.horizon

    def reset(self) -> None:
        pass

    def control(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.plan.controls[k]

    def stats(self) -> dict[str, Any]:
        return {}


class Feedback:
    """u_k = u_bar_k - K_k zeta_k, zeta_k = model.local(x_bar_k, x) (see the module docstring).

    Args:
        result: the plan (controls (H, m), gains (H, m, nx), states q, v (H+1, ...)).
        model: the plan's model (its ``local`` is the tangent difference).
    """

    name = "feedback"

    def __init__(self, result: Result, model: Any) -> None:
        self.plan = _check_plan(result, model)
        self.model = model
        self.horizon = self.plan.horizon
        self._q, self._v = np.asarray(self.plan.q), np.asarray(self.plan.v)
        self._u, self._K = np.asarray(self.plan.controls), np.asarray(self.plan.feedback)

    def reset(self) -> None:
        pass

    def control(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        zeta = self.model.local(self._q[k], self._v[k], q, v)
        return self._u[k] - self._K[k] @ zeta

    def stats(self) -> dict[str, Any]:
        return {}
