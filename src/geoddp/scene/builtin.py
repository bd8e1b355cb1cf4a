"""The three built-in multibody scenes (spacecraft docking, space manipulator, quadrotor), as problem builders.

Each scene is defined once, in its built-in scene file ``geoddp/data/scenes/multibody/<name>.toml``
(package data, :mod:`geoddp.data`; ``examples/multibody/`` in the repository): URDF, actuation,
initial state, costs, time grid. The builders here load that file and may change the integrator,
the time step and the horizon. Running costs are applied per step without a dt factor (the paper's
convention; divide Crocoddyl's running weights by dt to compare).

* :func:`spacecraft_docking`: a 500 kg free flyer on SE(3) with six bidirectional body-fixed
  thrusters reorients by 90 degrees and docks at the origin at rest.
* :func:`space_manipulator`: a free-floating base (unactuated) with a 3-joint arm brings its end
  effector to a target pose while keeping the base still (running base-velocity penalty).
* :func:`quadrotor`: a 1.5 kg "+" quadrotor (four rotors, gravity on) flies to a hover pose.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import data
from ..models.actuation import hover_inputs
from ..problem import Problem
from ..validate import choice
from .build import build_problem
from .load import load_scene
from .multibody import MultibodySceneSpec

NAMES = ("quadrotor", "space_manipulator", "spacecraft_docking")


def scene_path(name: str) -> Path:
    """Path of the scene file of built-in scene ``name`` (one of :data:`NAMES`)."""
    return data.scene_path(choice(name, "scene", NAMES))


def scene_spec(name: str, integrator: str | None = None, dt: float | None = None,
               horizon: int | None = None) -> MultibodySceneSpec:
    """The validated spec of built-in scene ``name``, with the integrator, time step (s) and
    horizon (steps) of its file unless given."""
    spec = load_scene(scene_path(name))
    over = {k: val for k, val in (("integrator", integrator), ("dt", dt), ("horizon", horizon)) if val is not None}
    return spec.with_overrides(**over)


def spacecraft_docking(integrator: str | None = None, dt: float | None = None, horizon: int | None = None) -> Problem:
    """Reorient by 90 deg about z and dock at the origin at rest, from 4.3 m away and tilted 50 deg
    (file: semi-implicit Euler, dt = 0.05 s, H = 200)."""
    return build_problem(scene_spec("spacecraft_docking", integrator, dt, horizon))


def space_manipulator(integrator: str | None = None, dt: float | None = None, horizon: int | None = None) -> Problem:
    """Bring the end effector to the pose it has at arm angles (0.6, -0.5, 0.8) with the base at
    rest at the origin, while the free-floating base (no thrusters) is kept still (file:
    semi-implicit Euler, dt = 0.02 s, H = 150)."""
    return build_problem(scene_spec("space_manipulator", integrator, dt, horizon))


def quadrotor(integrator: str | None = None, dt: float | None = None, horizon: int | None = None) -> Problem:
    """Fly from hover at (0, 0, 1) m to hover at (2, 1, 2) m, yawed 45 deg, in 3 s; rotor thrusts
    regularised about the hover thrust m g / 4 (file: semi-implicit Euler, dt = 0.02 s, H = 150)."""
    return build_problem(scene_spec("quadrotor", integrator, dt, horizon))


def hover_controls(problem: Problem) -> np.ndarray:
    """(H, m) inputs balancing gravity at the initial configuration (for the quadrotor, the rotor
    thrusts m g / 4 in N): the natural initial guess (zero thrust would start from free fall).
    The same inputs as ``initial_controls = "hover"`` in a scene file."""
    u = hover_inputs(problem.model.pin_model, problem.model.actuation, problem.q0)
    return np.tile(u, (problem.horizon, 1))
