"""The entry point from a scene: :class:`SimulationSpec` (plain values) and :func:`simulate_scene`.

``simulate_scene(scene, spec)`` loads (or takes) a scene, solves its plan once (the problem is
built once per scene spec: :func:`geoddp.api.solve_scene`), and runs :func:`~.monte_carlo.monte_carlo`
with the spec's policies, plant and disturbances. It is pure apart from the clock: the same
scene and spec give the same statistics (timings aside) on every machine. The CLI's
``geoddp simulate`` and sweeps call it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..validate import InputError, choice, closest, nonnegative_int, positive_int
from .disturbance import Disturbances
from .montecarlo import MonteCarloResult, monte_carlo
from .plant import PLANT_KEYS
from .run import POLICIES


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
        plant: plant changes, keys of :data:`~.plant.PLANT_KEYS` (e.g. {"inertia_scale": 1.2}).
        steps: plan steps to simulate (None: H; more only with MPC).
        mpc_horizon (None: min(100, H)), mpc_every, mpc_max_iter, mpc_shrink: MPC's options
            (:class:`~.mpc.MPC`).
        workers: processes for the samples (:func:`~.montecarlo.monte_carlo`; same numbers).
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

    def disturbances(self) -> Disturbances:
        return Disturbances(velocity_noise=self.noise, force_noise=self.force_noise, sensor_noise=self.sensor_noise,
                            wrench=self.wrench, wrench_start=self.wrench_start, wrench_duration=self.wrench_duration)

    def mpc_options(self) -> dict[str, Any]:
        if "mpc" not in self.policies:
            return {}
        return {"horizon": self.mpc_horizon, "every": self.mpc_every, "max_iter": self.mpc_max_iter,
                "shrink": self.mpc_shrink}


def simulate_scene(scene: Any, simulation: SimulationSpec | dict | None = None) -> MonteCarloResult:
    """Solve ``scene``'s plan and fly it per ``simulation``.

    Args:
        scene: a scene file path, a built-in scene's name or a spec from :func:`geoddp.scene.load_scene`.
        simulation: a :class:`SimulationSpec`, a dict of its fields (a ``[simulation]`` table) or
            None (one noiseless sample, feedback beside open loop).

    Returns:
        :class:`~.montecarlo.MonteCarloResult`; ``.statistics()`` is a flat dict of floats
        (``"feedback.attitude_rad.mean"``, ``"plan_cost"``, ...), ``.table()`` the Markdown table.
    """
    import os

    from ..api import _built_problem, solve_scene
    from ..scene import load_scene

    if simulation is None:
        sim = SimulationSpec()
    elif isinstance(simulation, dict):
        sim = SimulationSpec.from_dict(simulation)
    elif isinstance(simulation, SimulationSpec):
        sim = simulation
    else:
        raise InputError("simulation", f"expected a SimulationSpec, a dict or None, got {type(simulation).__name__}")
    spec = load_scene(scene) if isinstance(scene, (str, os.PathLike, Path)) else scene
    plan = solve_scene(spec, verbose=False)
    problem = _built_problem(spec)
    return monte_carlo(plan, problem, samples=sim.samples, seed=sim.seed, policies=sim.policies, plant=sim.plant,
                       disturbances=sim.disturbances(), steps=sim.steps, workers=sim.workers, **sim.mpc_options())
