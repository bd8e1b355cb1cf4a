"""Frozen copy of the Python builders of the three issue-6 scenes as they were before the scenes
moved to examples/multibody/*.toml (git: main at c83fdeb, src/geoddp/multibody_scenes.py).

An independent statement of the same numbers: tests/test_multibody_scene_files.py checks that the
scene files (which geoddp.scene.builtin now loads) build the same problems as this code.
Do not edit to make a test pass; it is the reference.
"""
from __future__ import annotations


import numpy as np
import pinocchio as pin

from geoddp.data import urdf_dir
from geoddp.models.actuation import quadrotor_actuation, thruster_actuation
from geoddp.models.multibody import Multibody
from geoddp.costs.multibody import (
    ControlRegularisation,
    FramePlacement,
    MultibodyCostSum,
    StateRegularisation,
)
from geoddp.problem import Problem

MODELS = urdf_dir()  # the built-in URDFs (package data)


def _velocity_weight(nv: int, w_v, w_q=0.0) -> np.ndarray:
    """(2nv, 2nv) weight of StateRegularisation: w_q on dq, w_v (scalar or (nv,)) on dv."""
    return np.diag(np.concatenate([np.broadcast_to(w_q, nv), np.broadcast_to(w_v, nv)]).astype(float))


def spacecraft_thrusters(lever: float = 0.8) -> np.ndarray:
    """(6, 6) wrench map of six bidirectional thrusters: for each body axis i, two thrusters along
    e_i at +-lever e_(i+1). Their sum is a force along e_i, their difference a torque."""
    positions, directions = [], []
    for i in range(3):
        j = (i + 1) % 3
        for s in (1.0, -1.0):
            positions.append(s * lever * np.eye(3)[j])
            directions.append(np.eye(3)[i])
    return thruster_actuation(np.array(positions), np.array(directions))


def spacecraft_docking(integrator: str = "semi_implicit", dt: float = 0.05, horizon: int = 200) -> Problem:
    """Reorient by 90 deg about z and dock at the origin at rest, from 4.3 m away and tilted 50 deg."""
    model = Multibody(MODELS / "spacecraft.urdf", root="free_flyer", actuation=spacecraft_thrusters(), dt=dt,
                      integrator=integrator, gravity=False)
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    M0 = pin.SE3(pin.exp3(np.radians(50.0) * axis), np.array([-4.0, 1.5, 0.5]))
    q0 = pin.SE3ToXYZQUAT(M0)
    M_dock = pin.SE3(pin.exp3(np.array([0.0, 0.0, np.pi / 2])), np.zeros(3))
    pm = model.pin_model
    running = MultibodyCostSum([ControlRegularisation(np.zeros(model.nu), W=1e-3)], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, "bus", M_dock, W=1e4),
        # arrive at rest: a docking contact tolerates a few mm/s
        StateRegularisation(pm, pin.neutral(pm), np.zeros(model.nv), W=_velocity_weight(model.nv, 1e6)),
    ], model=pm, terminal=True)
    return Problem(model, q0, np.zeros(model.nv), horizon, running, terminal)


def space_manipulator(integrator: str = "semi_implicit", dt: float = 0.02, horizon: int = 150) -> Problem:
    """Bring the end effector to the pose it has at arm angles (0.6, -0.5, 0.8) with the base at
    rest at the origin, while the free-floating base (no thrusters) is kept still."""
    m_arm = 3
    nv = 6 + m_arm
    actuation = np.zeros((nv, m_arm))
    actuation[6:, :] = np.eye(m_arm)  # joint motors only: the base floats
    model = Multibody(MODELS / "space_manipulator.urdf", root="free_flyer", actuation=actuation, dt=dt,
                      integrator=integrator, gravity=False)
    pm = model.pin_model
    q0 = pin.neutral(pm)
    q_goal = q0.copy()
    q_goal[7:] = [0.6, -0.5, 0.8]
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q_goal)
    M_target = data.oMf[pm.getFrameId("ee")].copy()
    base_still = _velocity_weight(nv, np.concatenate([np.full(6, 10.0), np.zeros(m_arm)]))
    running = MultibodyCostSum([
        ControlRegularisation(np.zeros(m_arm), W=1e-2),
        StateRegularisation(pm, q0, np.zeros(nv), W=base_still),
    ], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, "ee", M_target, W=1e3),
        StateRegularisation(pm, q0, np.zeros(nv), W=_velocity_weight(nv, 1e2)),
    ], model=pm, terminal=True)
    return Problem(model, q0, np.zeros(nv), horizon, running, terminal)


def quadrotor(integrator: str = "semi_implicit", dt: float = 0.02, horizon: int = 150) -> Problem:
    """Fly from hover at (0, 0, 1) m to hover at (2, 1, 2) m, yawed 45 deg, in 3 s; rotor thrusts
    regularised about the hover thrust m g / 4."""
    actuation = quadrotor_actuation(arm_length=0.25, torque_coefficient=0.02)
    model = Multibody(MODELS / "quadrotor.urdf", root="free_flyer", actuation=actuation, dt=dt,
                      integrator=integrator, gravity=True)
    pm = model.pin_model
    mass = sum(I.mass for I in pm.inertias)
    hover = np.full(4, mass * 9.81 / 4.0)
    q0 = pin.SE3ToXYZQUAT(pin.SE3(np.eye(3), np.array([0.0, 0.0, 1.0])))
    M_goal = pin.SE3(pin.exp3(np.array([0.0, 0.0, np.pi / 4])), np.array([2.0, 1.0, 2.0]))
    body = pm.frames[pm.getFrameId("body")].name if pm.existFrame("body") else pm.frames[1].name
    running = MultibodyCostSum([ControlRegularisation(hover, W=1e-1)], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, body, M_goal, W=1e3),
        StateRegularisation(pm, pin.neutral(pm), np.zeros(model.nv), W=_velocity_weight(model.nv, 1e2)),
    ], model=pm, terminal=True)
    return Problem(model, q0, np.zeros(model.nv), horizon, running, terminal)


def hover_controls(problem: Problem) -> np.ndarray:
    """(H, 4) rotor thrusts m g / 4 (N): the quadrotor's natural initial guess (zero thrust would
    start from free fall)."""
    pm = problem.model.pin_model
    mass = sum(I.mass for I in pm.inertias)
    return np.full((problem.horizon, problem.nu), mass * 9.81 / problem.nu)
