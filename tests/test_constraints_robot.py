"""The UR5 constrained reach (built-in scene ``ur5_constraints``, the gallery's
examples/ur5_constraints.py): velocity limits tighter than the unconstrained plan's speeds, a
sphere on the unconstrained tool path, an exact terminal tool pose. The solve is a KKT point with
every constraint met to 1e-8, recomputed here from the trajectory with Pinocchio; each constraint
binds (the unconstrained plan breaks it); the replay draws the sphere and the target pose.

Requires example-robot-data (the ``test`` extra).
"""
from __future__ import annotations

import example_robot_data  # noqa: F401  (required)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import load_scene, solve_scene
from geoddp.constraints import STATUS_KKT
from geoddp.scene import build_problem
from geoddp.viz.constraint_shapes import CONSTRAINTS
from geoddp.viz.html import decode_commands, render_html

TOL = 1e-8


@pytest.fixture(scope="module")
def solved():
    spec = load_scene("ur5_constraints")
    return spec, solve_scene(spec, verbose=False), solve_scene("ur5_reach", verbose=False)


def _tool(spec, Q):
    model = build_problem(spec).problem.model.pin_model
    data = model.createData()
    fid = model.getFrameId("tool0")
    out = []
    for q in Q:
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[fid].copy())
    return model, out


def test_the_constrained_reach_is_a_feasible_kkt_point(solved):
    spec, r, _ = solved
    rep, opt = r.extra["constraints"], r.extra["optimality"]
    assert r.status == STATUS_KKT and r.converged
    assert rep["constraint_tol"] == TOL and rep["max_violation"] <= TOL
    assert {it["name"]: it["max_violation"] <= TOL for it in rep["items"]} == \
        {"joint_limits": True, "obstacle": True, "tool_pose": True}
    # KKT: feasibility, complementarity |lambda c| and the Lagrangian's gradient norm
    assert opt["constraint_violation"] <= TOL and opt["complementarity"] <= TOL
    assert opt["lagrangian_stationarity"] < 1e-6 and opt["hessian_positive_definite"]
    # inequality multipliers are >= 0, and zero where the constraint is slack by more than the tolerance
    for it in rep["items"]:
        if not it["equality"]:
            lam, c = np.asarray(it["multipliers"]), np.asarray(it["values"])
            assert lam.min() >= 0.0 and np.all(lam[c < -1e-6] == 0.0)


def test_each_constraint_holds_on_the_trajectory_and_binds(solved):
    spec, r, free = solved
    (sphere,) = [c for c in spec.constraints if c.type == "frame_sphere_keep_out"]
    (limits,) = [c for c in spec.constraints if c.type == "joint_limits"]
    (pose,) = [c for c in spec.terminal_constraints if c.type == "frame_placement"]
    model, frames = _tool(spec, r.q)
    _, free_frames = _tool(spec, free.q)
    # the obstacle: tool0 outside the sphere at k = 1..H; the unconstrained plan passes through it
    dist = np.array([np.linalg.norm(M.translation - sphere.centre) for M in frames])
    free_dist = np.array([np.linalg.norm(M.translation - sphere.centre) for M in free_frames])
    assert dist[1:].min() >= sphere.radius - TOL and free_dist.min() < 0.5 * sphere.radius
    assert dist[1:].min() <= sphere.radius + 1e-6  # and touches it
    # velocity limits hold and bind; the unconstrained plan exceeds them
    for joint, (lo, hi) in limits.velocity.items():
        iv = model.joints[model.getJointId(joint)].idx_v
        assert r.v[:, iv].min() >= lo - TOL and r.v[:, iv].max() <= hi + TOL
        assert max(r.v[:, iv].max() - hi, lo - r.v[:, iv].min()) > -1e-6
        assert np.abs(free.v[:, iv]).max() > hi + 0.1
    # the URDF's position limits
    assert np.all(r.q >= model.lowerPositionLimit - TOL) and np.all(r.q <= model.upperPositionLimit + TOL)
    # the final pose exactly (log6 to the tolerance per row); the weighted plan misses it by mm
    err = pin.log6(pin.SE3(pose.placement).actInv(frames[-1])).vector
    free_err = pin.log6(pin.SE3(pose.placement).actInv(free_frames[-1])).vector
    assert np.abs(err).max() <= TOL and np.abs(free_err).max() > 1e-3


def test_the_replay_draws_the_obstacle_and_the_target_pose(solved):
    spec, r, _ = solved
    (sphere,) = [c for c in spec.constraints if c.type == "frame_sphere_keep_out"]
    prefix = f"/meshcat/{CONSTRAINTS}/"
    cmds = decode_commands(render_html(r))
    objects = {c["path"][len(prefix):]: c["object"] for c in cmds if c["type"] == "set_object"
               and c["path"].startswith(prefix)}
    assert objects["1_obstacle"]["geometries"][0]["radius"] == sphere.radius
    assert {"2_tool_pose/x", "2_tool_pose/y", "2_tool_pose/z"} <= set(objects)
    assert not any(k.startswith("0_") for k in objects)  # joint limits have no shape


def test_python_solve_without_a_start_begins_where_the_scene_does(solved):
    """``solve(ConstrainedProblem)`` with no initial controls starts from the unconstrained
    problem's default (quasi-static torques), as the scene does: the same solve, bit for bit, not
    a fall from zero torques (which ends elsewhere, or infeasible)."""
    from geoddp import solve
    from geoddp.scene import initial_controls
    from geoddp.scene.build import solver_options

    spec, r, _ = solved
    cp = build_problem(spec)
    U0 = initial_controls(spec)
    assert np.array_equal(cp.quasi_static_controls(), U0) and np.abs(U0).max() > 1.0
    assert np.array_equal(cp.augmented([], []).quasi_static_controls(), U0)
    r2 = solve(cp, solver_options(spec))
    assert r2.status == STATUS_KKT and r2.cost == r.cost and np.array_equal(r2.controls, r.controls)
