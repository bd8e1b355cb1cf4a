"""The entry point from a scene: :func:`simulate_scene` flies a :class:`~geoddp.scene.simulation.SimulationSpec`
(the ``[simulation]`` table's plain values).

``simulate_scene(scene, spec)`` loads (or takes) a scene, solves its plan once (the problem is
built once per scene spec: :func:`geoddp.solve_scene`), and runs :func:`~.monte_carlo.monte_carlo`
with the spec's policies, plant and disturbances. It is pure apart from the clock: the same
scene and spec give the same statistics (timings aside) on every machine. The CLI's
``geoddp simulate`` and sweeps call it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ..scene.simulation import SimulationSpec
from ..validate import InputError
from .disturbance import Disturbances
from .montecarlo import MonteCarloResult, monte_carlo


def disturbances(sim: SimulationSpec) -> Disturbances:
    """The spec's disturbances."""
    return Disturbances(velocity_noise=sim.noise, force_noise=sim.force_noise, sensor_noise=sim.sensor_noise,
                        wrench=sim.wrench, wrench_start=sim.wrench_start, wrench_duration=sim.wrench_duration)


def mpc_options(sim: SimulationSpec) -> dict[str, Any]:
    """The spec's :class:`~.mpc.MPC` options (empty unless MPC is flown)."""
    if "mpc" not in sim.policies:
        return {}
    return {"horizon": sim.mpc_horizon, "every": sim.mpc_every, "max_iter": sim.mpc_max_iter, "shrink": sim.mpc_shrink}


def simulate_scene(scene: Any, simulation: SimulationSpec | dict | None = None) -> MonteCarloResult:
    """Solve ``scene``'s plan and fly it per ``simulation``.

    Args:
        scene: a scene file path, a built-in scene's name or a spec from :func:`geoddp.scene.load_scene`.
        simulation: a :class:`SimulationSpec`, a dict of its fields (a ``[simulation]`` table) or
            None: the scene's ``[simulation]`` table if it has one, else the defaults (one
            noiseless sample, feedback beside open loop).

    Returns:
        :class:`~.montecarlo.MonteCarloResult`; ``.statistics()`` is a flat dict of floats
        (``"feedback.attitude_rad.mean"``, ``"plan_cost"``, ...), ``.table()`` the Markdown table.
    """
    import os

    from ..scene.solve import built_problem, solve_scene
    from ..scene import load_scene

    spec = load_scene(scene) if isinstance(scene, (str, os.PathLike, Path)) else scene
    if simulation is None:  # the scene's [simulation] table, else the defaults
        sim = getattr(spec, "simulation", None) or SimulationSpec()
    elif isinstance(simulation, dict):
        sim = SimulationSpec.from_dict(simulation)
    elif isinstance(simulation, SimulationSpec):
        sim = simulation
    else:
        raise InputError("simulation", f"expected a SimulationSpec, a dict or None, got {type(simulation).__name__}")
    if getattr(spec, "has_constraints", False) and "mpc" in sim.policies:
        # the MPC re-solves would drop the constraints (they solve the unconstrained problem)
        raise InputError("[simulation].policy", '"mpc" re-solves a scene with [[constraints]] without them; '
                         'fly its plan with "open" and "feedback"', getattr(spec, "source", None))
    plan = solve_scene(spec, verbose=False)
    problem = built_problem(spec)
    # a constrained scene's plan flies on its (unconstrained) problem's model and costs
    problem = getattr(problem, "problem", problem) if getattr(spec, "has_constraints", False) else problem
    return monte_carlo(plan, problem, samples=sim.samples, seed=sim.seed, policies=sim.policies, plant=sim.plant,
                       disturbances=disturbances(sim), steps=sim.steps, workers=sim.workers, **mpc_options(sim))
