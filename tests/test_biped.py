"""A biped on flat feet: geoddp.scene.legged.talos_walk (Crocoddyl's SimpleBipedGaitProblem walk on
Talos' legs; node for node against Crocoddyl in tests/test_contact6d_crocoddyl.py).

Its schedule (39 nodes, the left foot's landing impulse terminal, 6D soles, Crocoddyl's biped
weights); the built-in scene ``talos_walk`` builds the same problem; a [gait] walk takes two feet
or four; and the exact second-order terms of its nodes (the flat feet's placement tracking, the
wrench cones, the state and CoM terms) against tests/oracle_legged.py's differences of the
analytic Jacobians, every entry, 1e-7 relative, with wrench-cone rows active; the same with one
point foot beside a flat one; the soles' torques and centres of pressure (contact_forces); feet in
local axes refused by the gait costs.
"""
from __future__ import annotations

import copy

import numpy as np
import pinocchio as pin
import pytest

from oracle_legged import fd_second_order_node

from geoddp.problem.contract import Trajectory
from geoddp.problem.legged import GaitCosts, _barrier
from geoddp.scene import LeggedSceneSpec, load_scene, parse_scene
from geoddp.scene.legged import TALOS_FEET, load_robot, talos_walk
from geoddp.validate import InputError

pytest.importorskip("example_robot_data", reason="example-robot-data not installed: the 'robots' extra")


@pytest.fixture(scope="module")
def robot():
    return load_robot("talos_legs")


@pytest.fixture(scope="module")
def walk(robot):
    return talos_walk(robot)


def test_the_walk_schedule(walk, robot):
    """Crocoddyl's walk: 4 + 15 + 4 + 15 contact nodes, the right foot's landing impulse at node 19,
    the left foot's landing the terminal node; both soles 6D contacts; Crocoddyl's biped weights."""
    rf, lf = (int(robot.model.getFrameId(f)) for f in TALOS_FEET)
    kinds = [n.kind for n in walk.nodes]
    assert walk.horizon == 39 and walk.nu == 12 and kinds.index("impulse") == 19 and kinds.count("impulse") == 1
    assert walk.nodes[19].feet == (rf,) and walk.terminal_node.kind == "impulse" and walk.terminal_node.feet == (lf,)
    assert all(n.feet == (lf,) and n.swing[0][0] == rf for n in walk.nodes[4:19])
    assert all(n.feet == (rf,) and n.swing[0][0] == lf for n in walk.nodes[24:39])
    assert walk.dyn.contact_kinds == {rf: "6d", lf: "6d"} and walk.dyn.gains == (0.0, 30.0) and walk.dt == 0.03
    assert walk.costs == GaitCosts.biped() and walk.costs.bounds == 0.0 and walk.costs.impulse_foot == 1e8
    assert walk.describe()["contact_schedule"]["feet"] == list(TALOS_FEET)


def test_contact_forces_of_flat_feet(walk):
    """contact_forces along the quasi-static rollout: each sole's force and torque are its node's
    (world-aligned), the forces sum to m (a_com - g), the centre of pressure is (-tau_y, tau_x) / f_z;
    the description carries the legs' visual geometry (talos_legs is not its URDF's model)."""
    from geoddp.problem.legged_forces import contact_forces

    traj = walk.trajectory(walk.quasi_static_controls())
    c = contact_forces(walk, traj.q, traj.v, traj.u)
    assert c.feet == TALOS_FEET and c.torques.shape == c.forces.shape == (walk.horizon, 2, 3)
    ev = walk.node(2, traj.q[2], traj.v[2], traj.u[2])[0]
    assert np.array_equal(np.concatenate([c.forces[2, 0], c.torques[2, 0], c.forces[2, 1], c.torques[2, 1]]), ev.forces)
    assert np.abs(c.total - c.momentum_change).max() < 1e-9 * c.mass * 9.81
    on = c.active[:, 0]
    cop = np.stack([-c.torques[on, 0, 1], c.torques[on, 0, 0]], axis=-1) / c.forces[on, 0, 2][:, None]
    assert np.array_equal(c.cop[on, 0], cop) and np.all(np.isnan(c.cop[~on, 0]))
    desc = walk.describe()
    assert "urdf_xml" not in desc and len(desc["geometry_objects"]) > 0


def test_builtin_scene_is_talos_walk(walk, robot):
    """``talos_walk`` (scene file) builds talos_walk(): the same nodes bit for bit, dynamics, costs
    and J on random controls."""
    spec = load_scene("talos_walk")
    assert isinstance(spec, LeggedSceneSpec) and spec.horizon == 39 and spec.num_inputs == 12
    ours = spec.build(robot)
    for x, y in zip(ours.nodes + [ours.terminal_node], walk.nodes + [walk.terminal_node]):
        assert (x.kind, x.feet, x.com is None) == (y.kind, y.feet, y.com is None)
        assert x.com is None or np.array_equal(x.com, y.com)
        assert all(f == g and np.array_equal(p, q) for (f, p), (g, q) in zip(x.swing, y.swing))
    assert len(ours.nodes) == len(walk.nodes) and ours.dt == walk.dt and ours.dyn.gains == walk.dyn.gains
    assert ours.dyn.contact_kinds == walk.dyn.contact_kinds and ours.costs == walk.costs
    assert np.array_equal(ours.q0, walk.q0) and np.array_equal(ours.q_ref, walk.q_ref)
    U = walk.quasi_static_controls() + np.random.default_rng(0).standard_normal((walk.horizon, walk.nu))
    assert ours.trajectory_cost(ours.trajectory(U)) == walk.trajectory_cost(walk.trajectory(U))


def test_scene_keys_of_a_biped():
    """[contact].kind takes "3d" or "6d"; a walk takes two feet or four, a trot four; [costs] of
    flat feet start from Crocoddyl's biped weights."""
    base = tomllib_scene()
    bad = copy.deepcopy(base)
    bad["contact"]["kind"] = "6D"
    with pytest.raises(InputError, match=r"\[contact\]\.kind"):
        parse_scene(bad)
    bad = copy.deepcopy(base)
    bad["gait"]["type"] = "trot"
    with pytest.raises(InputError, match=r"\[model\]\.feet"):
        parse_scene(bad)
    bad = copy.deepcopy(base)
    bad["model"]["feet"] = base["model"]["feet"][:1]
    with pytest.raises(InputError, match=r"\[model\]\.feet"):
        parse_scene(bad)
    spec = parse_scene({**base, "costs": {"foot": 1e5}})
    assert spec.foot_kind == "6d" and dict(spec.costs) == {"foot": 1e5}


def tomllib_scene() -> dict:
    import tomllib

    from geoddp import data

    return tomllib.loads((data.scene_dir() / "legged" / "talos_walk.toml").read_text())


# ------------------------------------------------------------------ exact second order
def nominal(problem, k, rng):
    """A trajectory whose node k is at a random state near the posture with random controls
    (quasi-static plus noise; zero at an impulse node), node k + 1 its image."""
    m = problem.model
    q = pin.integrate(m, problem.q0, 0.05 * rng.standard_normal(m.nv))
    v = 0.3 * rng.standard_normal(m.nv)
    H = problem.horizon
    u = np.zeros(problem.nu)
    if k < H and not problem.impulse_rows[k]:
        u = problem.dyn.quasi_static(q, problem.nodes[k].feet) + 20.0 * rng.standard_normal(problem.nu)
    Q, V, U = np.tile(problem.q0, (H + 1, 1)), np.zeros((H + 1, m.nv)), np.zeros((H, problem.nu))
    Q[k], V[k] = q, v
    if k < H:
        ev = problem.node(k, q, v, u)[0]
        U[k], Q[k + 1], V[k + 1] = u, ev.q_next, ev.v_next
    return Trajectory(Q, V, U)


def active_cone_rows(problem, k, traj) -> int:
    ev = problem.node(k, traj.q[k], traj.v[k], traj.u[k])[0]
    return sum(int(_barrier(A @ ev.forces[rows], lb, ub)[1].sum()) for rows, (A, lb, ub) in problem._cones(
        problem.nodes[k].feet))


@pytest.mark.parametrize("k,what", [(2, "double support"), (10, "right foot swinging"), (30, "left foot swinging"),
                                    (19, "right foot landing"), (39, "terminal: left foot landing")])
def test_second_order_terms_against_the_differences(walk, k, what):
    """T (the KKT system differentiated twice through the Euler step) and the cost Hessian (the
    placement residual's log6 curvature, the CoM's, the state differences', the wrench cones'
    through the forces' second derivatives) against the differences of the analytic Jacobians."""
    traj = nominal(walk, k, np.random.default_rng(7 + k))
    if k < walk.horizon and not walk.impulse_rows[k]:
        assert active_cone_rows(walk, k, traj) > 0, what  # the wrench cones' curvature is exercised
    T, Hc = walk.second_order_node(k, traj)
    Tf, Hf = fd_second_order_node(walk, k, traj)
    if T is not None:
        err = np.max(np.abs(T - Tf)) / np.max(np.abs(Tf))
        assert err < 1e-7, (what, err)
    err = np.max(np.abs(Hc - Hf)) / np.max(np.abs(Hf))
    assert err < 1e-7, (what, err)


def test_feet_in_local_axes_refused(walk):
    """The gait costs read a flat foot's wrench in world-aligned axes: a schedule on "6d_local"
    feet is refused, naming the contact kinds."""
    from geoddp.models.contact import ContactDynamics
    from geoddp.problem.legged import ContactProblem

    local = {f: "6d_local" for f in walk.dyn.contact_kinds}
    dyn = ContactDynamics(walk.model, walk.dt, gains=(0.0, 30.0), contact_kinds=local)
    with pytest.raises(InputError, match="contact_kinds"):
        ContactProblem(dyn, walk.nodes, walk.terminal_node, walk.q0, walk.v0, (walk.q_ref, walk.v_ref), walk.costs)


@pytest.mark.parametrize("k", [2, 10, 30])
def test_mixed_feet_second_order(walk, k):
    """A point foot beside a flat one (the right sole 6D, the left a 3D point): each foot's rows of
    the forces get its own cone and its tracking its own residual; the exact second order against
    the differences (1e-7)."""
    from geoddp.models.contact import ContactDynamics
    from geoddp.problem.legged import ContactProblem

    rf, lf = walk.dyn.contact_kinds
    dyn = ContactDynamics(walk.model, walk.dt, gains=(0.0, 30.0), contact_kinds={rf: "6d", lf: "3d"})
    mixed = ContactProblem(dyn, walk.nodes, walk.terminal_node, walk.q0, walk.v0, (walk.q_ref, walk.v_ref), walk.costs)
    traj = nominal(mixed, k, np.random.default_rng(3 + k))
    assert active_cone_rows(mixed, k, traj) > 0
    T, Hc = mixed.second_order_node(k, traj)
    Tf, Hf = fd_second_order_node(mixed, k, traj)
    assert np.max(np.abs(T - Tf)) / np.max(np.abs(Tf)) < 1e-7
    assert np.max(np.abs(Hc - Hf)) / np.max(np.abs(Hf)) < 1e-7


def test_friction_cone_constraint_on_flat_feet(walk):
    """A FrictionCone hard constraint on the soles reads each foot's force, the first 3 of its 6
    rows (not the first foot's torque): its values and its augmented terms at a double-support node
    are those of the node's forces."""
    from geoddp.constraints import ConstrainedProblem, FrictionCone

    cp = ConstrainedProblem(walk, [FrictionCone(mu=0.5, min_normal_force=5.0)])
    traj = walk.trajectory(walk.quasi_static_controls())
    c = cp.values(traj)[0]
    placed = cp.placed[0]
    k = 2
    ev = walk.node(k, traj.q[k], traj.v[k], traj.u[k])[0]
    pairs = np.flatnonzero(placed.nodes == k)
    assert placed.slots[pairs].tolist() == [0, 1]
    for j, start in zip(pairs, (0, 6)):
        assert np.array_equal(c[j], placed.bound.value(ev.forces[None, start:start + 3])[0])
    lam = np.where(np.arange(c.size).reshape(c.shape) % 2 == 0, 1.0, 0.0)
    aug = cp.augmented([lam], [0.3]).problem
    assert [s for *_, s in aug._force_at[k]] == [0, 6]
    val = aug.node(k, traj.q[k], traj.v[k], traj.u[k])[1] - walk.node(k, traj.q[k], traj.v[k], traj.u[k])[1]
    t = lam[pairs] + 0.3 * c[pairs]
    expect = float(np.sum(np.maximum(t, 0.0) ** 2 - lam[pairs] ** 2) / 0.6)
    assert val == pytest.approx(expect, rel=1e-12)
