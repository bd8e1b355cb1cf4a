"""Fly a plan: simulate a Result on a plant, with noise and model error, open loop, with the DDP
gains or with MPC; Monte Carlo statistics (closed-loop simulation).

    plant.py        Plant: the plan's model with changed parameters, integrator and substeps
    disturbance.py  Disturbances: process, force and sensor noise, external wrenches (seeded)
    policy.py       OpenLoop, Feedback (u = u_k - K_k zeta on the group)
    mpc.py          MPC: receding horizon, warm start by shifting, the problem built once
    errors.py       terminal, tracking and effort measures
    run.py          simulate(): one run -> SimulationResult
    montecarlo.py   monte_carlo(): N seeded samples -> MonteCarloResult (distribution table)
    scene.py        simulate_scene(): the entry point of the CLI and sweeps

SimulationSpec (the ``[simulation]`` table's values), POLICIES and PLANT_KEYS live in
:mod:`geoddp.scene.simulation`, below the scene readers that hold them; re-exported here.
"""
from __future__ import annotations

from .disturbance import Disturbances
from .montecarlo import MonteCarloResult, monte_carlo
from .mpc import MPC
from .plant import PLANT_KEYS, Plant, plant_from
from .policy import Feedback, OpenLoop
from .run import POLICIES, SimulationResult, simulate
from ..scene.simulation import SimulationSpec
from .scene import simulate_scene

__all__ = ["Disturbances", "Feedback", "MPC", "MonteCarloResult", "OpenLoop", "PLANT_KEYS", "POLICIES", "Plant",
           "SimulationResult", "SimulationSpec", "monte_carlo", "plant_from", "simulate", "simulate_scene"]
