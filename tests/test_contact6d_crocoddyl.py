"""6D (flat-foot) contact and impulse nodes against Crocoddyl's, on Talos' legs as its biped
examples build them: DifferentialActionModelContactFwdDynamics with ContactModel6D (LOCAL_WORLD_ALIGNED
and LOCAL, Baumgarte gains (0, 30) as SimpleBipedGaitProblem's and with a position gain) under
IntegratedActionModelEuler, and ActionModelImpulseFwdDynamics with ImpulseModel6D: the same next
state (1e-12) and contact forces at random states and controls, the same quasi-static controls.
And the biped walk (geoddp.scene.legged.talos_walk, Crocoddyl's SimpleBipedGaitProblem walk): the
wrench cone, every node (kind, feet, next state 1e-12, cost 1e-10), the terminal node, rollouts'
costs, and geoddp's solution at FDDP's J* (1e-9).
Needs the bench environment (crocoddyl 3.2.1 + pin 4.0.0, example-robot-data); skipped without
crocoddyl unless GEODDP_REQUIRE_CROCODDYL=1 (CI)."""
import os

import numpy as np
import pinocchio as pin
import pytest

if os.environ.get("GEODDP_REQUIRE_CROCODDYL") == "1":
    import crocoddyl
else:
    crocoddyl = pytest.importorskip("crocoddyl", reason="crocoddyl not installed: install the 'bench' extra")
import example_robot_data  # noqa: E402

from geoddp.models.contact import ContactDynamics  # noqa: E402

FRAMES = {"6d": pin.LOCAL_WORLD_ALIGNED, "6d_local": pin.LOCAL}
DT = 0.03


@pytest.fixture(scope="module")
def talos():
    model = example_robot_data.load("talos_legs").model
    return model, (int(model.getFrameId("right_sole_link")), int(model.getFrameId("left_sole_link")))


def random_state(model, rng):
    q = pin.integrate(model, model.referenceConfigurations["half_sitting"], 0.1 * rng.standard_normal(model.nv))
    return q, 0.5 * rng.standard_normal(model.nv)


def crocoddyl_contact_node(model, feet, kind, gains):
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    contacts = crocoddyl.ContactModelMultiple(state, actuation.nu)
    for f in feet:
        contacts.addContact(model.frames[f].name + "_contact", crocoddyl.ContactModel6D(
            state, f, pin.SE3.Identity(), FRAMES[kind], actuation.nu, np.array(gains)))
    dam = crocoddyl.DifferentialActionModelContactFwdDynamics(
        state, actuation, contacts, crocoddyl.CostModelSum(state, actuation.nu), 0.0, True)
    return crocoddyl.IntegratedActionModelEuler(dam, DT)


def crocoddyl_impulse_node(model, feet, kind):
    state = crocoddyl.StateMultibody(model)
    impulses = crocoddyl.ImpulseModelMultiple(state)
    for f in feet:
        impulses.addImpulse(model.frames[f].name + "_impulse", crocoddyl.ImpulseModel6D(state, f, FRAMES[kind]))
    node = crocoddyl.ActionModelImpulseFwdDynamics(state, impulses, crocoddyl.CostModelSum(state, 0))
    node.JMinvJt_damping, node.r_coeff = 1e-12, 0.0
    return node


@pytest.mark.parametrize("kind", ["6d", "6d_local"])
@pytest.mark.parametrize("gains", [(0.0, 30.0), (20.0, 30.0)])
@pytest.mark.parametrize("nfeet", [0, 1, 2])
def test_contact_node_is_crocoddyls(talos, kind, gains, nfeet):
    model, both = talos
    feet = both[:nfeet]
    dyn = ContactDynamics(model, DT, gains=gains, contact_kinds={f: kind for f in both})
    node = crocoddyl_contact_node(model, feet, kind, gains)
    data = node.createData()
    rng = np.random.default_rng(nfeet + 10 * (kind == "6d_local") + int(gains[0]))
    worst_x, worst_f = 0.0, 0.0
    for _ in range(10):
        q, v = random_state(model, rng)
        u = 20.0 * rng.standard_normal(dyn.nu)
        node.calc(data, np.concatenate([q, v]), u)
        ev = dyn.contact(q, v, u, feet)
        worst_x = max(worst_x, np.max(np.abs(np.concatenate([ev.q_next, ev.v_next]) - data.xnext)))
        contacts = data.differential.multibody.contacts.contacts
        for i, f in enumerate(feet):
            theirs = contacts[model.frames[f].name + "_contact"].f.vector
            worst_f = max(worst_f, np.max(np.abs(ev.forces[6 * i:6 * i + 6] - theirs)) / max(np.max(np.abs(theirs)), 1.0))
    assert worst_x < 1e-12, worst_x
    assert worst_f < 1e-12, worst_f


@pytest.mark.parametrize("kind", ["6d", "6d_local"])
@pytest.mark.parametrize("nfeet", [1, 2])
def test_impulse_node_is_crocoddyls(talos, kind, nfeet):
    model, both = talos
    feet = both[:nfeet]
    dyn = ContactDynamics(model, DT, contact_kinds={f: kind for f in both})
    node = crocoddyl_impulse_node(model, feet, kind)
    data = node.createData()
    rng = np.random.default_rng(nfeet + 5)
    worst_x, worst_f = 0.0, 0.0
    for _ in range(10):
        q, v = random_state(model, rng)
        node.calc(data, np.concatenate([q, v]), np.zeros(0))
        ev = dyn.impulse(q, v, feet)
        worst_x = max(worst_x, np.max(np.abs(np.concatenate([ev.q_next, ev.v_next]) - data.xnext)))
        impulses = data.multibody.impulses.impulses
        for i, f in enumerate(feet):
            theirs = impulses[model.frames[f].name + "_impulse"].f.vector
            worst_f = max(worst_f, np.max(np.abs(ev.forces[6 * i:6 * i + 6] - theirs)) / max(np.max(np.abs(theirs)), 1.0))
    assert worst_x < 1e-12, worst_x
    assert worst_f < 1e-12, worst_f


def test_mixed_feet_are_crocoddyls(talos):
    """A 6D right foot and a 3D left foot (ContactModel3D, LOCAL_WORLD_ALIGNED) in one node."""
    model, (rf, lf) = talos
    dyn = ContactDynamics(model, DT, gains=(0.0, 30.0), contact_kinds={rf: "6d"})
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    contacts = crocoddyl.ContactModelMultiple(state, actuation.nu)
    contacts.addContact("r", crocoddyl.ContactModel6D(state, rf, pin.SE3.Identity(), pin.LOCAL_WORLD_ALIGNED,
                                                      actuation.nu, np.array([0.0, 30.0])))
    contacts.addContact("s", crocoddyl.ContactModel3D(state, lf, np.zeros(3), pin.LOCAL_WORLD_ALIGNED,
                                                      actuation.nu, np.array([0.0, 30.0])))
    node = crocoddyl.IntegratedActionModelEuler(crocoddyl.DifferentialActionModelContactFwdDynamics(
        state, actuation, contacts, crocoddyl.CostModelSum(state, actuation.nu), 0.0, True), DT)
    data = node.createData()
    rng = np.random.default_rng(2)
    worst = 0.0
    for _ in range(10):
        q, v = random_state(model, rng)
        u = 20.0 * rng.standard_normal(dyn.nu)
        node.calc(data, np.concatenate([q, v]), u)
        ev = dyn.contact(q, v, u, (rf, lf))
        worst = max(worst, np.max(np.abs(np.concatenate([ev.q_next, ev.v_next]) - data.xnext)))
        assert ev.forces.shape == (9,)
    assert worst < 1e-12, worst


@pytest.mark.parametrize("nfeet", [1, 2])
def test_quasi_static_controls_are_crocoddyls(talos, nfeet):
    model, both = talos
    feet = both[:nfeet]
    dyn = ContactDynamics(model, DT, gains=(0.0, 30.0), contact_kinds={f: "6d" for f in both})
    node = crocoddyl_contact_node(model, feet, "6d", (0.0, 30.0))
    q = model.referenceConfigurations["half_sitting"].copy()
    x = np.concatenate([q, np.zeros(model.nv)])
    theirs = node.quasiStatic(node.createData(), x)
    assert np.max(np.abs(dyn.quasi_static(q, feet) - theirs)) < 1e-9


# ------------------------------------------------------------------ the biped walk, node for node
@pytest.fixture(scope="module")
def walk(talos):
    from crocoddyl.utils.biped import SimpleBipedGaitProblem

    from geoddp.scene.legged import talos_walk

    model = talos[0]
    robot = example_robot_data.load("talos_legs")
    q0 = model.referenceConfigurations["half_sitting"].copy()
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    croc = SimpleBipedGaitProblem(robot.model, "right_sole_link", "left_sole_link").createWalkingProblem(
        x0, 0.6, 0.1, 0.03, 15, 4)  # Crocoddyl's example bipedal_gaits_fwddyn.py, a fresh instance
    return talos_walk(robot), croc, x0


def test_wrench_cone_is_crocoddyls():
    from geoddp.models.contact import wrench_cone

    cone = crocoddyl.WrenchCone(np.eye(3), 0.7, np.array([0.1, 0.05]))
    A, lb, ub = wrench_cone(0.7, (0.1, 0.05))
    assert np.max(np.abs(A - cone.A)) == 0.0 and np.array_equal(lb, cone.lb) and np.array_equal(ub, cone.ub)


def test_walk_nodes_are_crocoddyls(walk):
    """Every node of the walk: the same kind and feet, the same next state (1e-12) and node cost
    (1e-10 relative) at random states and controls; the terminal node (the last landing impulse's
    calc(x)) and the quasi-static controls."""
    ours, croc, x0 = walk
    model = ours.model
    assert ours.horizon == croc.T == 39
    rng = np.random.default_rng(11)
    worst_x, worst_c = 0.0, 0.0
    for k, cm in enumerate(croc.runningModels):
        node = ours.nodes[k]
        impulse = isinstance(cm, crocoddyl.ActionModelImpulseFwdDynamics)
        assert (node.kind == "impulse") == impulse, k
        contacts = cm.impulses if impulse else cm.differential.contacts
        assert sorted(contacts.active_set) == sorted(
            model.frames[f].name + ("_impulse" if impulse else "_contact") for f in node.feet), k
        data = cm.createData()
        for _ in range(3):
            q, v = random_state(model, rng)
            u = np.zeros(ours.nu) if impulse else 20.0 * rng.standard_normal(ours.nu)
            cm.calc(data, np.concatenate([q, v]), np.zeros(0) if impulse else u)
            ev, cost, *_ = ours.node(k, q, v, u)
            worst_x = max(worst_x, np.max(np.abs(np.concatenate([ev.q_next, ev.v_next]) - data.xnext)))
            worst_c = max(worst_c, abs(cost - data.cost) / max(abs(data.cost), 1.0))
    assert worst_x < 1e-12, worst_x
    assert worst_c < 1e-10, worst_c
    assert [n.kind for n in ours.nodes].count("impulse") == 1 and ours.terminal_node.kind == "impulse"
    tm = croc.terminalModel
    data = tm.createData()
    for _ in range(3):
        q, v = random_state(model, rng)
        tm.calc(data, np.concatenate([q, v]))
        assert abs(ours.node(ours.horizon, q, v, None)[1] - data.cost) <= 1e-10 * abs(data.cost)
    us = croc.quasiStatic([x0] * croc.T)
    U = ours.quasi_static_controls()
    for k in range(croc.T):
        expect = np.zeros(ours.nu) if ours.impulse_rows[k] else us[k]
        assert np.max(np.abs(U[k] - expect)) < 1e-9, k


@pytest.mark.parametrize("noise", [0.0, 0.05, 0.1])
def test_walk_trajectory_cost_is_crocoddyls(walk, noise):
    """geoddp's rollout of random controls (quasi-static plus noise, N m) costed by Crocoddyl's
    problem (larger noise makes the open-loop walk fall and diverge): the same J (1e-9 relative), every transition Crocoddyl's (1e-9 relative)."""
    ours, croc, _ = walk
    rng = np.random.default_rng(int(100 * noise))
    U = ours.quasi_static_controls() + noise * rng.standard_normal((ours.horizon, ours.nu))
    traj = ours.trajectory(ours.check_controls(U))
    xs = [np.concatenate([a, b]) for a, b in zip(traj.q, traj.v)]
    J = croc.calc(xs, [np.zeros(0) if ours.impulse_rows[k] else traj.u[k] for k in range(ours.horizon)])
    assert np.isfinite(J) and abs(J - ours.trajectory_cost(traj)) <= 1e-9 * abs(J), (J, ours.trajectory_cost(traj))
    for k, d in enumerate(croc.runningDatas):
        assert np.max(np.abs(d.xnext - xs[k + 1])) <= 1e-9 * max(1.0, np.max(np.abs(xs[k + 1]))), k


def test_walk_solution_matches_fddp(walk):
    """geoddp's first expansion from the quasi-static start converges; Crocoddyl's problem costs its
    trajectory at its J* (1e-9 relative) with every transition consistent (1e-9), and that J* is
    FDDP's from the example's start (xs = [x0] * (T + 1)) to 1e-9 relative."""
    from geoddp.solver import SolverOptions, solve

    ours, croc, x0 = walk
    res = solve(ours, SolverOptions(expansion="first"))
    assert res.converged
    xs = [np.concatenate([a, b]) for a, b in zip(res.q, res.v)]
    J = croc.calc(xs, [np.zeros(0) if ours.impulse_rows[k] else res.controls[k] for k in range(ours.horizon)])
    assert abs(J - res.cost) <= 1e-9 * res.cost
    assert max(np.max(np.abs(d.xnext - xs[k + 1])) for k, d in enumerate(croc.runningDatas)) < 1e-9
    solver = crocoddyl.SolverFDDP(croc)
    assert solver.solve([x0] * (croc.T + 1), croc.quasiStatic([x0] * croc.T), 200, False)
    assert abs(res.cost - solver.cost) <= 1e-9 * solver.cost, (res.cost, solver.cost)
