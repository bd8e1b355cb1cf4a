"""The replay draws a constrained solve's constraints: the keep-out cone (apex at the frame's
origin, axis along the direction, half-angle the constraint's), obstacle spheres, half-space
patches and terminal poses, read from the page's meshcat commands; a solve without constraints
draws none, and a cone on a moving frame follows it keyframe by keyframe."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from geoddp import viz  # noqa: F401  (first: silences meshcat's import warning)
from geoddp import solve_scene
from geoddp.constraints import (ConstrainedProblem, FrameHalfspace, FramePlacementConstraint, FrameSphereKeepOut,
                                PointingKeepOut, solve_constrained)
from geoddp.problem import paper_problem
from geoddp.scene.builtin import space_manipulator
from geoddp.solver import SolverOptions, solve
from geoddp.viz.constraint_shapes import CONSTRAINTS, KEEP_OUT_COLOR, KEEP_OUT_OPACITY
from geoddp.viz.html import decode_commands, render_html
from viz_fixtures import keyframes

D = np.array([0.849, 0.482, 0.215]) / np.linalg.norm([0.849, 0.482, 0.215])
PREFIX = f"/meshcat/{CONSTRAINTS}/"


def _objects(cmds):
    return {c["path"][len(PREFIX):]: c["object"] for c in cmds if c["type"] == "set_object"
            and c["path"].startswith(PREFIX)}


def _transforms(cmds):
    return {c["path"][len(PREFIX):]: np.asarray(c["matrix"], dtype=float).reshape(4, 4).T
            for c in cmds if c["type"] == "set_transform" and c["path"].startswith(PREFIX)}


def _geometry(obj):
    (geom,), (mat,) = obj["geometries"], obj["materials"]
    return geom, mat


@pytest.fixture(scope="module")
def keep_out():
    return solve_scene("satellite_keep_out", verbose=False, expansion="second")


def test_the_satellite_cone_is_drawn_at_the_body_along_the_direction(keep_out):
    cmds = decode_commands(render_html(keep_out))
    objects, transforms = _objects(cmds), _transforms(cmds)
    assert set(objects) == {"0_sun_keep_out"}
    geom, mat = _geometry(objects["0_sun_keep_out"])
    assert geom["type"] == "CylinderGeometry" and geom["radiusTop"] == 0.0
    # slant length L: height L cos(20 deg), base radius L sin(20 deg)
    assert geom["radiusBottom"] / geom["height"] == pytest.approx(np.tan(np.radians(20.0)), rel=1e-12)
    assert mat["color"] == KEEP_OUT_COLOR and mat["opacity"] == KEEP_OUT_OPACITY and mat["transparent"]
    T = transforms["0_sun_keep_out"]
    R, p = T[:3, :3], T[:3, 3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    # three.js's tip at +y h/2 is the apex, at the satellite's centre (the world origin); the base
    # lies along +d
    np.testing.assert_allclose(R @ np.array([0.0, -1.0, 0.0]), D, atol=1e-12)
    np.testing.assert_allclose(p + R @ np.array([0.0, 0.5 * geom["height"], 0.0]), np.zeros(3), atol=1e-12)
    # the cone does not move (the apex is the satellite's centre at every node): no keyframes
    anim = [c for c in cmds if c["type"] == "set_animation"][-1]
    assert not any(CONSTRAINTS in e["path"] for e in anim["animations"])


def test_an_unconstrained_result_draws_no_constraints():
    cmds = decode_commands(render_html(solve(paper_problem(), SolverOptions(verbose=False))))
    assert not any(c["path"].startswith(PREFIX) for c in cmds if "path" in c)


def test_obstacles_half_spaces_poses_and_a_moving_cone_on_a_multibody():
    p = space_manipulator(horizon=10, dt=0.1)
    pm = p.model.pin_model
    target = pin.SE3(pin.exp3(np.array([0.0, 0.0, 0.3])), np.array([0.4, 0.2, 0.1]))
    cp = ConstrainedProblem(p, [PointingKeepOut([1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 120.0, frame="ee", name="cone"),
                                FrameSphereKeepOut("ee", [0.3, -0.2, 0.1], 0.15, name="ball"),
                                FrameHalfspace("ee", [0.0, 0.0, 2.0], -1.0, name="floor")],
                            [FramePlacementConstraint("ee", target, name="goal")])
    r = solve_constrained(cp, SolverOptions(verbose=False, max_iter=3))
    cmds = decode_commands(render_html(r))
    objects, transforms = _objects(cmds), _transforms(cmds)
    assert {"0_cone", "1_ball", "2_floor"} <= set(objects)
    assert {k.split("/")[0] for k in objects} == {"0_cone", "1_ball", "2_floor", "3_goal"}
    # the sphere: its radius at its centre
    geom, mat = _geometry(objects["1_ball"])
    assert geom["type"] == "SphereGeometry" and geom["radius"] == 0.15 and mat["color"] == KEEP_OUT_COLOR
    np.testing.assert_allclose(transforms["1_ball"][:3, 3], [0.3, -0.2, 0.1], atol=1e-15)
    # the plane n.p = offset with n = e_z (normalised) and offset -1 / 2: a thin box with z along n
    geom, _ = _geometry(objects["2_floor"])
    assert geom["type"] == "BoxGeometry" and geom["depth"] == pytest.approx(1e-3 * geom["width"], rel=1e-12)
    T = transforms["2_floor"]
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, 1.0], atol=1e-12)
    assert T[2, 3] == pytest.approx(-0.5, abs=1e-12)
    # the terminal pose: a triad at the target placement
    np.testing.assert_allclose(transforms["3_goal"], target.homogeneous, atol=1e-12)
    assert {"3_goal/x", "3_goal/y", "3_goal/z", "3_goal/origin"} <= set(objects)
    # a 120-degree cone is drawn as its boundary, the 60-degree cone around -d
    geom, _ = _geometry(objects["0_cone"])
    assert geom["radiusBottom"] / geom["height"] == pytest.approx(np.tan(np.radians(60.0)), rel=1e-12)
    R = transforms["0_cone"][:3, :3]
    np.testing.assert_allclose(R @ np.array([0.0, -1.0, 0.0]), [0.0, 0.0, -1.0], atol=1e-12)
    # the cone's apex follows the frame "ee": one keyframe per node, the apex at oMf(q_k).translation
    anim = [c for c in cmds if c["type"] == "set_animation"][-1]
    (clip,) = [e["clip"] for e in anim["animations"] if e["path"] == PREFIX + "0_cone"]
    keys = keyframes(clip)
    assert keys.shape == (r.q.shape[0], 4, 4)
    np.testing.assert_allclose(keys[:, :3, :3], np.broadcast_to(R, (keys.shape[0], 3, 3)), atol=1e-12)
    positions = keys[:, :3, 3]
    data = pm.createData()
    fid = pm.getFrameId("ee")
    h = geom["height"]
    for k in (0, 4, 10):
        pin.framesForwardKinematics(pm, data, r.q[k])
        np.testing.assert_allclose(positions[k], data.oMf[fid].translation + 0.5 * h * np.array([0.0, 0.0, -1.0]),
                                   atol=1e-12)
    assert np.ptp(positions, axis=0).max() > 1e-3
