"""Contact and impulse node models against Crocoddyl's, node for node on its ANYmal gaits.

geoddp's anymal_walk / anymal_trot / anymal_jump against the problems Crocoddyl's SimpleQuadrupedalGaitProblem
builds (a fresh instance per problem, as its example quadrupedal_gaits_fwddyn.py's first gait):
the same node kinds and feet, and at random states and controls the same next state (1e-12), the
same node cost (1e-10 relative) and the same quasi-static controls. Needs the bench environment
(crocoddyl 3.2.1 + pin 4.0.0, example-robot-data); skipped without crocoddyl unless
GEODDP_REQUIRE_CROCODDYL=1 (CI).
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

from geoddp.models.contact import friction_cone  # noqa: E402
from geoddp.scene.legged import FEET, GAITS, anymal_gait, load_anymal  # noqa: E402


@pytest.fixture(scope="module")
def robot():
    return load_anymal()


def crocoddyl_problem(robot, gait):
    q0 = robot.model.referenceConfigurations["standing"].copy()
    x0 = np.concatenate([q0, np.zeros(robot.model.nv)])
    builder = SimpleQuadrupedalGaitProblem(robot.model, *FEET)  # fresh: its first (half) step
    make = {"walk": builder.createWalkingProblem, "trot": builder.createTrottingProblem,
            "jump": builder.createJumpingProblem}[gait]
    return make(x0, *[list(a) if isinstance(a, tuple) else a for a in GAITS[gait]])  # it edits the jump's length


def random_state(model, q0, rng):
    q = pin.integrate(model, q0, 0.1 * rng.standard_normal(model.nv))
    return q, 0.5 * rng.standard_normal(model.nv)


def test_friction_cone_is_crocoddyls():
    cone = crocoddyl.FrictionCone(np.eye(3), 0.7, 4, False)
    A, lb, ub = friction_cone(0.7, 4)
    assert np.array_equal(A, cone.A) and np.array_equal(lb, cone.lb) and np.array_equal(ub, cone.ub)


@pytest.mark.parametrize("gait", ["walk", "trot", "jump"])
def test_nodes_match_crocoddyl(robot, gait):
    croc = crocoddyl_problem(robot, gait)
    ours = anymal_gait(gait, robot)
    model = robot.model
    assert ours.horizon == croc.T
    rng = np.random.default_rng(7)
    worst_x, worst_c, kinds = 0.0, 0.0, []
    for k, cm in enumerate(croc.runningModels):
        node = ours.nodes[k]
        impulse = isinstance(cm, crocoddyl.ActionModelImpulseFwdDynamics)
        kinds.append(node.kind)
        assert (node.kind == "impulse") == impulse, k
        contacts = cm.impulses if impulse else cm.differential.contacts
        names = sorted(contacts.active_set if hasattr(contacts, "active_set") else contacts.active)
        assert names == sorted(model.frames[f].name + ("_impulse" if impulse else "_contact") for f in node.feet), k
        for _ in range(3):
            q, v = random_state(model, ours.q0, rng)
            u = 20.0 * rng.standard_normal(ours.nu)
            data = cm.createData()
            cm.calc(data, np.concatenate([q, v]), np.zeros(0) if impulse else u)
            ev, cost, *_ = ours.node(k, q, v, np.zeros(ours.nu) if impulse else u)
            x_ours = np.concatenate([ev.q_next, ev.v_next])
            worst_x = max(worst_x, np.max(np.abs(x_ours - data.xnext)))
            worst_c = max(worst_c, abs(cost - data.cost) / max(abs(data.cost), 1.0))
    assert worst_x < 1e-12, worst_x
    assert worst_c < 1e-10, worst_c
    assert kinds.count("impulse") == {"walk": 4, "trot": 2, "jump": 1}[gait]
    # terminal node: Crocoddyl's calc(x) of its four-foot support model
    tm = croc.terminalModel
    for _ in range(3):
        q, v = random_state(model, ours.q0, rng)
        data = tm.createData()
        tm.calc(data, np.concatenate([q, v]))
        cost = ours.node(ours.horizon, q, v, None)[1]
        assert abs(cost - data.cost) <= 1e-10 * max(abs(data.cost), 1.0)


@pytest.mark.parametrize("gait", ["walk", "trot", "jump"])
def test_quasi_static_controls_are_crocoddyls(robot, gait):
    croc = crocoddyl_problem(robot, gait)
    ours = anymal_gait(gait, robot)
    x0 = np.concatenate([ours.q0, ours.v0])
    us = croc.quasiStatic([x0] * croc.T)
    U = ours.quasi_static_controls()
    for k in range(croc.T):
        expect = np.zeros(ours.nu) if ours.impulse_rows[k] else us[k]
        assert np.allclose(U[k], expect, rtol=0, atol=1e-9), k


@pytest.mark.parametrize("gait", ["walk", "trot", "jump"])
def test_rollouts_match(robot, gait):
    """A whole rollout from the quasi-static start: every transition and the total cost are
    Crocoddyl's (its problem's calc at geoddp's states)."""
    croc = crocoddyl_problem(robot, gait)
    ours = anymal_gait(gait, robot)
    traj = ours.trajectory(ours.quasi_static_controls())
    xs = [np.concatenate([q, v]) for q, v in zip(traj.q, traj.v)]
    us = [np.zeros(0) if ours.impulse_rows[k] else traj.u[k] for k in range(ours.horizon)]
    J = croc.calc(xs, us)
    assert abs(J - ours.trajectory_cost(traj)) <= 1e-10 * abs(J)
    for k, d in enumerate(croc.runningDatas):
        assert np.max(np.abs(d.xnext - xs[k + 1])) < 1e-10, k


@pytest.mark.parametrize(("gait", "expansion"), [("walk", "first"), ("trot", "first")])
def test_geoddp_solution_in_crocoddyls_problem(gait, expansion):
    """geoddp (first order, from the quasi-static start) converges; Crocoddyl's problem costs its
    trajectory at geoddp's J* (1e-6 relative) with every transition consistent with Crocoddyl's
    node models (1e-6); and that J* is at most FDDP's from the example's start (round-off aside)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import legged_vs_fddp as bench

    ours, theirs = bench.geoddp(gait, expansion), bench.fddp(gait)
    assert ours["converged"] and theirs["converged"]
    assert abs(ours["J_crocoddyl"] - ours["J"]) <= 1e-6 * ours["J"]
    assert ours["max_gap"] < 1e-6
    assert ours["J"] <= theirs["J"] * (1 + 1e-12), (ours["J"], theirs["J"])
