"""Built-in legged scenes: Crocoddyl's ANYmal gaits (its example quadrupedal_gaits_fwddyn.py).

* :func:`anymal_walk`: step length 0.25 m, height 0.15 m, dt 0.01 s, 25 step knots, 2 support knots.
* :func:`anymal_trot`: 0.15 m, 0.1 m, 0.01 s, 25, 2.
* :func:`anymal_jump`: jump height 0.15 m, length (0, 0.3, 0) m, dt 0.01 s, 10 ground knots, 20
  flying knots.

ANYmal comes from example-robot-data (``pip install example-robot-data``), posture "standing";
the problems are those Crocoddyl's ``SimpleQuadrupedalGaitProblem`` builds from a fresh instance,
node for node (contact nodes with Baumgarte gains (0, 50), impulse nodes at touch-down, the same
costs and weights: :mod:`geoddp.problem.legged`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..models.contact import ContactDynamics
from ..problem.legged import ContactProblem, QuadrupedGait
from ..validate import InputError

FEET = ("LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT")
GAITS = {"walk": (0.25, 0.15, 0.01, 25, 2), "trot": (0.15, 0.1, 0.01, 25, 2),
         "jump": (0.15, (0.0, 0.3, 0.0), 0.01, 10, 20)}  # jump: height, length (3,), dt, ground, flying knots


def load_anymal():
    """example-robot-data's ANYmal (a RobotWrapper); InputError naming ``example_robot_data`` if
    the package is missing."""
    try:
        import example_robot_data
    except ImportError:
        raise InputError("example_robot_data", "the ANYmal scenes need example-robot-data: pip install example-robot-data") from None
    return example_robot_data.load("anymal")


def anymal_gait(gait: str, robot=None) -> ContactProblem:
    """The ContactProblem of Crocoddyl's ANYmal ``gait`` ("walk", "trot" or "jump") from "standing" at rest."""
    if gait not in GAITS:
        raise InputError("gait", f"expected one of {tuple(GAITS)}, got {gait!r}")
    robot = robot or load_anymal()
    model = robot.model
    q0 = model.referenceConfigurations["standing"].copy()
    v0 = np.zeros(model.nv)
    builder = QuadrupedGait(model, FEET)
    if gait == "jump":
        height, length, dt, ground, flying = GAITS[gait]
        nodes, terminal = builder.jump(q0, height, length, ground, flying)
    else:
        length, height, dt, knots, support = GAITS[gait]
        nodes, terminal = getattr(builder, gait)(q0, length, height, knots, support)
    urdf = Path(robot.urdf) if getattr(robot, "urdf", None) else None
    desc = {"kind": "multibody", "root": "free_flyer", "nq": model.nq, "nv": model.nv, "dt": dt,
            "integrator": "semi_implicit", "pin_model": model.saveToString()}
    if urdf is not None and urdf.is_file():
        desc.update(urdf=str(urdf), urdf_xml=urdf.read_text())
    return ContactProblem(ContactDynamics(model, dt, gains=(0.0, 50.0)), nodes, terminal, q0, v0,
                          (q0.copy(), v0.copy()), description=desc)


def anymal_walk(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal walk: 0.25 m steps, 0.15 m high, dt 0.01 s, 25 + 2 knots (H = 108: 4 impulse nodes)."""
    return anymal_gait("walk", robot)


def anymal_trot(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal trot: 0.15 m steps, 0.1 m high, dt 0.01 s, 25 + 2 knots (H = 56: 2 impulse nodes)."""
    return anymal_gait("trot", robot)


def anymal_jump(robot=None) -> ContactProblem:
    """Crocoddyl's ANYmal jump: 0.3 m sideways (y), CoM apex 0.15 m up, dt 0.01 s, 10 ground knots,
    20 + 20 flying knots, the landing impulse (H = 60: 1 impulse node)."""
    return anymal_gait("jump", robot)
