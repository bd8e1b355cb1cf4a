"""The ``[simulation]`` table of a scene as plain values: :class:`SimulationSpec` (closed-loop simulation).

It lives below :mod:`geoddp.simulate` (floor 4, with the scene readers) so that a scene file can
carry it: the readers validate the table into a SimulationSpec, and :mod:`geoddp.simulate` flies
it. Only the validation is here; nothing simulates. :data:`POLICIES` and :data:`PLANT_KEYS` are
the one home of the policy names and the plant parameters.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..validate import InputError, choice, closest, finite_array, keywords_checked, nonnegative_float, nonnegative_int, positive_int

POLICIES = ("open", "feedback", "mpc")
PLANT_KEYS = ("inertia_scale", "mass_scale", "actuator_gain", "integrator", "substeps")


@keywords_checked
@dataclass(frozen=True)
class SimulationSpec:
    """What to simulate, as plain values (the ``[simulation]`` table of a scene file).

    Attributes:
        samples: Monte Carlo samples N (>= 1).  seed: root seed (>= 0).
        policy: "open" | "feedback" | "mpc".
        compare_open_loop: also fly "open" on the same noise (ignored when policy is "open").
        noise: sigma of the process noise on the velocity per plan step (rad/s, m/s; scalar or (nv,)).
        sensor_noise: sigma on the measured state's tangent (scalar or (nx,)).
        force_noise: sigma of a generalised force held over each step (N m, N; scalar or (nv,)).
        wrench: constant external generalised force (nv,) or None; wrench_start (s),
            wrench_duration (s, None: to the end).
        plant: plant changes, keys of :data:`PLANT_KEYS` (e.g. {"inertia_scale": 1.2}).
        steps: plan steps to simulate (None: H; more only with MPC).
        mpc_horizon (None: min(100, H)), mpc_every, mpc_max_iter, mpc_shrink: MPC's options
            (:class:`geoddp.simulate.MPC`).
        workers: processes for the samples (:func:`geoddp.simulate.monte_carlo`; same numbers).
    """

    samples: int = 1
    seed: int = 0
    policy: str = "feedback"
    compare_open_loop: bool = True
    noise: Any = 0.0
    sensor_noise: Any = 0.0
    force_noise: Any = 0.0
    wrench: Any = None
    wrench_start: float = 0.0
    wrench_duration: float | None = None
    plant: dict = field(default_factory=dict)
    steps: int | None = None
    mpc_horizon: int | None = None
    mpc_every: int = 1
    mpc_max_iter: int = 3
    mpc_shrink: bool = False
    workers: int = 1

    def __post_init__(self) -> None:
        put = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731  (frozen dataclass)
        put("samples", positive_int(self.samples, "simulation.samples"))
        put("seed", nonnegative_int(self.seed, "simulation.seed"))
        put("policy", choice(self.policy, "simulation.policy", POLICIES))
        if not isinstance(self.plant, dict):
            raise InputError("simulation.plant", f"expected a table of {', '.join(PLANT_KEYS)}, got {self.plant!r}")
        for k in self.plant:
            if k not in PLANT_KEYS:
                hint = closest(str(k), PLANT_KEYS)
                raise InputError(f"simulation.plant.{k}", "unknown plant parameter" + (f" (did you mean {hint!r}?)" if hint
                                                                                      else "") + f"; known: {', '.join(PLANT_KEYS)}")
        for k in ("compare_open_loop", "mpc_shrink"):
            if not isinstance(getattr(self, k), bool):
                raise InputError(f"simulation.{k}", f"expected true or false, got {getattr(self, k)!r}")
        put("workers", positive_int(self.workers, "simulation.workers"))
        if self.steps is not None:
            put("steps", positive_int(self.steps, "simulation.steps"))
        for k in ("noise", "sensor_noise", "force_noise"):
            a = finite_array(getattr(self, k), f"simulation.{k}")
            if a.ndim > 1 or np.any(a < 0):
                raise InputError(f"simulation.{k}", f"expected a number >= 0 or a list of them, got {a.tolist()}")
        if self.wrench is not None:
            finite_array(self.wrench, "simulation.wrench", (None,))
        nonnegative_float(self.wrench_start, "simulation.wrench_start")
        if self.wrench_duration is not None:
            nonnegative_float(self.wrench_duration, "simulation.wrench_duration")
        if self.mpc_horizon is not None:
            put("mpc_horizon", positive_int(self.mpc_horizon, "simulation.mpc_horizon"))
        put("mpc_every", positive_int(self.mpc_every, "simulation.mpc_every"))
        put("mpc_max_iter", positive_int(self.mpc_max_iter, "simulation.mpc_max_iter"))
        for k, val in self.plant.items():
            name = f"simulation.plant.{k}"
            if k == "integrator":
                if not isinstance(val, str):
                    raise InputError(name, f"expected an integrator name, got {val!r}")
            elif k == "substeps":
                positive_int(val, name)
            else:
                a = finite_array(val, name)
                if a.ndim > 1 or np.any(a <= 0):
                    raise InputError(name, f"expected a positive number or a list of them, got {a.tolist()}")

    @classmethod
    def from_dict(cls, table: dict[str, Any], path: str = "simulation") -> "SimulationSpec":
        """From a ``[simulation]`` table; unknown keys raise InputError naming ``<path>.<key>``."""
        known = [f.name for f in dataclasses.fields(cls)]
        for k in table:
            if k not in known:
                hint = closest(str(k), known)
                raise InputError(f"{path}.{k}", "unknown key" + (f" (did you mean {hint!r}?)" if hint else "")
                                 + f"; known: {', '.join(known)}")
        return cls(**table)

    @property
    def policies(self) -> tuple[str, ...]:
        """The policies flown, open loop first."""
        if self.policy == "open" or not self.compare_open_loop:
            return (self.policy,)
        return ("open", self.policy)


__all__ = ["PLANT_KEYS", "POLICIES", "SimulationSpec"]
