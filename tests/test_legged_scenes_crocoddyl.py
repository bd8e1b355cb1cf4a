"""Legged scene files against Crocoddyl's SimpleQuadrupedalGaitProblem, node for node.

Crocoddyl's pace and bound (createPacingProblem, createBoundingProblem: gaits geoddp has no Python
builder for), written as [[phases]] scene files, are its problems: the same node kinds and feet,
and at random states and controls the same next state (1e-12) and node cost (1e-10 relative),
the terminal node's cost too. The built-in scene files anymal_walk, anymal_trot and anymal_jump
roll out as Crocoddyl's problems do: every transition (1e-10) and the total cost (1e-10
relative) from the quasi-static start. Needs the bench environment (crocoddyl 3.2.1 + pin
4.0.0, example-robot-data); skipped without crocoddyl unless GEODDP_REQUIRE_CROCODDYL=1 (CI).
"""
import os

import numpy as np
import pinocchio as pin
import pytest

if os.environ.get("GEODDP_REQUIRE_CROCODDYL") == "1":
    import crocoddyl
else:
    crocoddyl = pytest.importorskip("crocoddyl", reason="crocoddyl not installed: install the 'bench' extra")
from crocoddyl.utils.quadruped import SimpleQuadrupedalGaitProblem  # noqa: E402

from geoddp.scene import load_scene, parse_scene  # noqa: E402
from geoddp.scene.legged import FEET, GAITS, load_anymal  # noqa: E402

LF, RF, LH, RH = FEET
LENGTH, HEIGHT, DT, KNOTS, SUPPORT = 0.15, 0.1, 0.01, 25, 5  # Crocoddyl's example: pacing and bounding


@pytest.fixture(scope="module")
def robot():
    return load_anymal()


def _phase(contacts, knots, length=None):
    t = {"contacts": list(contacts), "knots": knots}
    if length is not None:
        t.update(step_length=length, step_height=HEIGHT)
    return t


# Crocoddyl's first pace (a fresh instance: half steps of the right feet) and its bound
PHASES = {
    "pace": [_phase(FEET, SUPPORT), _phase((LF, LH), KNOTS, 0.5 * LENGTH), _phase(FEET, SUPPORT),
             _phase((RF, RH), KNOTS, LENGTH)],
    "bound": [_phase(FEET, SUPPORT), _phase((LH, RH), KNOTS, LENGTH), _phase(FEET, SUPPORT),
              _phase((LF, RF), KNOTS, LENGTH)],
}


def crocoddyl_problem(robot, gait):
    x0 = np.concatenate([robot.model.referenceConfigurations["standing"].copy(), np.zeros(robot.model.nv)])
    builder = SimpleQuadrupedalGaitProblem(robot.model, *FEET)
    if gait in GAITS:
        make = {"walk": builder.createWalkingProblem, "trot": builder.createTrottingProblem,
                "jump": builder.createJumpingProblem}[gait]
        return make(x0, *[list(a) if isinstance(a, tuple) else a for a in GAITS[gait]])
    make = {"pace": builder.createPacingProblem, "bound": builder.createBoundingProblem}[gait]
    return make(x0, LENGTH, HEIGHT, DT, KNOTS, SUPPORT)


@pytest.mark.parametrize("gait", ["pace", "bound"])
def test_phases_are_crocoddyls_gait(robot, gait):
    scene = {"model": {"kind": "legged", "robot": "anymal", "feet": list(FEET)}, "contact": {"dt": DT},
             "phases": PHASES[gait]}
    ours = parse_scene(scene).build(robot)
    croc = crocoddyl_problem(robot, gait)
    model = robot.model
    assert ours.horizon == croc.T == 2 * SUPPORT + 2 * (KNOTS + 1)
    rng = np.random.default_rng(11)
    worst_x, worst_c = 0.0, 0.0
    for k, cm in enumerate(croc.runningModels):
        node = ours.nodes[k]
        impulse = isinstance(cm, crocoddyl.ActionModelImpulseFwdDynamics)
        assert (node.kind == "impulse") == impulse, k
        contacts = cm.impulses if impulse else cm.differential.contacts
        names = sorted(contacts.active_set if hasattr(contacts, "active_set") else contacts.active)
        assert names == sorted(model.frames[f].name + ("_impulse" if impulse else "_contact") for f in node.feet), k
        for _ in range(2):
            q = pin.integrate(model, ours.q0, 0.1 * rng.standard_normal(model.nv))
            v = 0.5 * rng.standard_normal(model.nv)
            u = 20.0 * rng.standard_normal(ours.nu)
            data = cm.createData()
            cm.calc(data, np.concatenate([q, v]), np.zeros(0) if impulse else u)
            ev, cost, *_ = ours.node(k, q, v, np.zeros(ours.nu) if impulse else u)
            worst_x = max(worst_x, np.max(np.abs(np.concatenate([ev.q_next, ev.v_next]) - data.xnext)))
            worst_c = max(worst_c, abs(cost - data.cost) / max(abs(data.cost), 1.0))
    assert worst_x < 1e-12, worst_x
    assert worst_c < 1e-10, worst_c
    assert int(ours.impulse_rows.sum()) == 2
    tm = croc.terminalModel
    q = pin.integrate(model, ours.q0, 0.1 * rng.standard_normal(model.nv))
    v = 0.5 * rng.standard_normal(model.nv)
    data = tm.createData()
    tm.calc(data, np.concatenate([q, v]))
    assert abs(ours.node(ours.horizon, q, v, None)[1] - data.cost) <= 1e-10 * max(abs(data.cost), 1.0)


@pytest.mark.parametrize("gait", ["walk", "trot", "jump"])
def test_builtin_scene_rolls_out_as_crocoddyls_problem(robot, gait):
    ours = load_scene(f"anymal_{gait}").build(robot)
    croc = crocoddyl_problem(robot, gait)
    traj = ours.trajectory(ours.quasi_static_controls())
    xs = [np.concatenate([q, v]) for q, v in zip(traj.q, traj.v)]
    us = [np.zeros(0) if ours.impulse_rows[k] else traj.u[k] for k in range(ours.horizon)]
    J = croc.calc(xs, us)
    assert abs(J - ours.trajectory_cost(traj)) <= 1e-10 * abs(J)
    for k, d in enumerate(croc.runningDatas):
        assert np.max(np.abs(d.xnext - xs[k + 1])) < 1e-10, k
