"""Scene files with [[constraints]] and [[terminal_constraints]]: both kinds read them into
constraint objects, bad tables are refused with the key path named (and the closest key, frame or
joint suggested), the built-in keep-out scene runs from the command line."""
from __future__ import annotations

import copy
import json
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from geoddp import data
from geoddp import solve_scene
from geoddp.constraints import (STATUS_KKT, ConstrainedProblem, FrameHalfspace, FramePlacementConstraint,
                                FrameSphereKeepOut, JointLimits, PointingKeepOut, StateConstraint)
from geoddp.scene import build_problem, load_scene, parse_scene
from geoddp.validate import InputError

SAT = tomllib.loads((data.scene_dir() / "satellite_paper.toml").read_text())
ARM = tomllib.loads((data.scene_dir() / "multibody" / "space_manipulator.toml").read_text())
ARM["model"]["urdf"] = str(data.urdf_path("space_manipulator.urdf"))  # parsed from a dict: no scene folder

CONE = {"type": "pointing_keep_out", "body_axis": [1.0, 0.0, 0.0], "world_direction": [0.849, 0.482, 0.215],
        "min_angle_deg": 20.0}


def _with(scene: dict, constraints=(), terminal=(), **solver) -> dict:
    d = copy.deepcopy(scene)
    if constraints:
        d["constraints"] = list(constraints)
    if terminal:
        d["terminal_constraints"] = list(terminal)
    d.setdefault("solver", {}).update(solver)
    return d


def test_the_builtin_keep_out_scene():
    spec = load_scene("satellite_keep_out")
    assert spec.kind == "satellite" and spec.constraint_tol == 1e-8 and not spec.terminal_constraints
    (cone,) = spec.constraints
    assert isinstance(cone, PointingKeepOut) and cone.name == "sun_keep_out" and cone.frame == "bus"
    np.testing.assert_allclose(cone.world_direction, np.array([0.849, 0.482, 0.215]) / np.linalg.norm([0.849, 0.482,
                                                                                                      0.215]),
                               rtol=0, atol=1e-16)
    assert cone.min_angle_deg == 20.0
    # the translation to the general schema carries them, and the built problem is constrained
    assert spec.general().constraints == spec.constraints
    cp = build_problem(spec)
    assert isinstance(cp, ConstrainedProblem) and cp.options.constraint_tol == 1e-8
    # the paper's problem underneath, unchanged
    assert load_scene("satellite_paper").has_constraints is False
    # a scene read twice is one scene (constraints compare by value)
    assert load_scene("satellite_keep_out") == spec
    assert spec.with_overrides(constraints=(PointingKeepOut([1, 0, 0], [0, 0, 1], 20.0),)) != spec


def test_satellite_scene_tables_of_every_kind_it_can_take():
    spec = parse_scene(_with(SAT, [CONE, {"type": "joint_limits", "velocity": {"root_joint": [-0.6, 0.6]}},
                                   {"type": "frame_halfspace", "frame": "bus", "normal": [0, 0, 2.0], "offset": -1.0}],
                             [{"type": "state", "v": [0.0, 0.0, 0.0], "name": "at_rest"}], constraint_tol=1e-7))
    kinds = [type(c) for c in spec.constraints + spec.terminal_constraints]
    assert kinds == [PointingKeepOut, JointLimits, FrameHalfspace, StateConstraint]
    assert spec.constraint_tol == 1e-7 and spec.terminal_constraints[0].name == "at_rest"
    half = spec.constraints[2]
    np.testing.assert_array_equal(half.normal, [0.0, 0.0, 1.0])  # normalised, and the offset with it
    assert half.offset == -0.5
    cp = build_problem(spec)
    assert [p.bound.rows for p in cp.placed] == [1, 6, 1, 3]  # 3 rates x (upper, lower); the terminal rates


def test_multibody_scene_tables():
    spec = parse_scene(_with(ARM, [
        {"type": "joint_limits", "joints": {"elbow": [-0.2, 0.9]}, "velocity": {"shoulder_yaw": [-1.0, 1.0]}},
        {"type": "frame_sphere_keep_out", "frame": "ee", "centre": [1.8, 0.3, 0.4], "radius": 0.1},
        {"type": "pointing_keep_out", "frame": "ee", "body_axis": [1, 0, 0], "world_direction": [0, 0, -1],
         "min_angle_deg": 10.0}],
        [{"type": "frame_placement", "frame": "ee", "at_configuration": [0, 0, 0, 0, 0, 0, 1, 0.6, -0.5, 0.8]},
         {"type": "frame_placement", "frame": "ee", "translation": [2.0, 1.0, 1.0], "axis": [0, 0, 1],
          "angle_deg": 30.0, "name": "explicit"}]))
    assert [c.type for c in spec.constraints] == ["joint_limits", "frame_sphere_keep_out", "pointing_keep_out"]
    a, b = spec.terminal_constraints
    assert isinstance(a, FramePlacementConstraint) and a.placement.shape == (4, 4) and b.name == "explicit"
    np.testing.assert_allclose(b.placement[:3, 3], [2.0, 1.0, 1.0])
    assert isinstance(spec.constraints[1], FrameSphereKeepOut)
    cp = build_problem(spec)
    assert [p.nodes.size for p in cp.placed] == [150, 150, 150, 1, 1]


@pytest.mark.parametrize("scene, constraints, terminal, path, detail", [
    (SAT, [{"body_axis": [1, 0, 0]}], [], "constraints[0].type", "missing required key"),
    (SAT, [{**CONE, "type": "pointing_keepout"}], [], "constraints[0].type", "did you mean 'pointing_keep_out'"),
    (SAT, [{**CONE, "min_angle_deg": 200.0}], [], "constraints[0].min_angle_deg", "(0, 180)"),
    (SAT, [{**CONE, "min_angle": 20.0}], [], "constraints[0].min_angle", "did you mean 'min_angle_deg'"),
    (SAT, [{k: v for k, v in CONE.items() if k != "world_direction"}], [], "constraints[0].world_direction",
     "missing required key"),
    (SAT, [{**CONE, "body_axis": [0, 0, 0]}], [], "constraints[0].body_axis", "non-zero"),
    (SAT, [CONE, {**CONE, "frame": "buss"}], [], "constraints[1].frame", "did you mean 'bus'"),
    (SAT, [{"type": "joint_limits", "joints": {"root_joint": [-1, 1]}}], [], "constraints[0].joints.root_joint",
     "spherical"),
    (SAT, [], [{"type": "state", "q": [0, 0, 0, 2.0]}], "terminal_constraints[0].q", "unit quaternions"),
    (SAT, [{"type": "state", "v": [0, 0, 0]}], [], "constraints[0].type", "put it in [[terminal_constraints]]"),
    (SAT, [CONE, {"type": "frame_halfspace", "frame": "bus", "normal": [0, 0, 1]}], [], "constraints[1].offset",
     "missing required key"),
    (ARM, [{"type": "joint_limits", "joints": {"elbw": [-1, 1]}}], [], "constraints[0].joints.elbw",
     "did you mean 'elbow'"),
    (ARM, [{"type": "joint_limits", "joints": {"elbow": [1.0, -1.0]}}], [], "constraints[0].joints.elbow",
     "contradictory"),
    (ARM, [{"type": "joint_limits", "joints": {"elbow": [-1.0]}}], [], "constraints[0].joints.elbow", "pair"),
    (ARM, [{"type": "joint_limits", "joints": {"root_joint": [-1.0, 1.0]}}], [], "constraints[0].joints.root_joint",
     "free flyer"),
    (ARM, [{"type": "joint_limits"}], [], "constraints[0].joints", "at least one of"),
    (ARM, [{**CONE}], [], "constraints[0].frame", "has no default body"),
    (ARM, [{"type": "frame_sphere_keep_out", "frame": "ee", "centre": [0, 0, 0], "radius": -0.1}], [],
     "constraints[0].radius", "> 0"),
    (ARM, [], [{"type": "frame_placement", "frame": "ee", "translation": [1, 0, 0]}],
     "terminal_constraints[0]", "exactly one rotation form"),
    (ARM, [], [{"type": "state", "q": [0.0] * 9}], "terminal_constraints[0].q", "shape (10,)"),
    (ARM, [{"type": "frame_halfspace", "frame": "ee", "normal": [0, 0, 1], "offset": 0.1, "radius": 1}], [],
     "constraints[0].radius", "allowed keys"),
])
def test_bad_constraint_tables_are_refused_naming_the_key(scene, constraints, terminal, path, detail):
    with pytest.raises(InputError) as info:
        parse_scene(_with(scene, constraints, terminal), "scene.toml")
    assert info.value.parameter == path, info.value
    assert detail in info.value.detail, info.value
    assert info.value.source == "scene.toml"


def test_bad_constraint_tolerance_and_arrays():
    with pytest.raises(InputError) as info:
        parse_scene(_with(SAT, [CONE], constraint_tol=-1e-8))
    assert info.value.parameter == "[solver].constraint_tol"
    d = _with(SAT)
    d["constraints"] = {"type": "pointing_keep_out"}  # [constraints], not [[constraints]]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "constraints" and "array of tables" in info.value.detail
    d = _with(SAT)
    d["constraint"] = [CONE]
    with pytest.raises(InputError) as info:
        parse_scene(d)
    assert info.value.parameter == "constraint" and "[[constraints]]" in info.value.detail


def test_solve_scene_routes_a_constrained_scene_to_the_outer_loop():
    r = solve_scene("satellite_keep_out", verbose=False, expansion="second")
    assert r.status == STATUS_KKT and r.extra["scene"] == "satellite_keep_out"
    assert r.extra["constraints"]["max_violation"] <= 1e-8


def test_geoddp_run_satellite_keep_out(tmp_path):
    out = tmp_path / "keep_out.json"
    proc = subprocess.run([sys.executable, "-m", "geoddp.cli", "run", "satellite_keep_out", "--quiet", "--json",
                           str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "constraint 'sun_keep_out' (pointing_keep_out, path): max violation = " in proc.stdout
    assert "status: converged: KKT point" in proc.stdout
    d = json.loads(out.read_text())
    assert d["converged"] is True and d["constraints"]["max_violation"] <= 1e-8
    assert d["cost"] == pytest.approx(908.7470197, rel=1e-8)


def test_simulate_flies_a_constrained_plan_but_refuses_mpc():
    """The plan of a constrained scene flies open loop and with its feedback; MPC would re-solve
    without the constraints, so it is refused, naming the key."""
    from geoddp.simulate import simulate_scene

    mc = simulate_scene("satellite_keep_out", {"policy": "feedback"})
    assert mc.statistics()["plan_cost"] == pytest.approx(908.7470197, rel=1e-8)
    with pytest.raises(InputError) as info:
        simulate_scene("satellite_keep_out", {"policy": "mpc"})
    assert info.value.parameter == "[simulation].policy" and "constraints" in info.value.detail
