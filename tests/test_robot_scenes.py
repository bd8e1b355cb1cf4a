"""Scene keys for real robots (issue 14, item 1): ``[model] robot = "ur5"`` or ``urdf`` +
``package_dirs`` (+ ``srdf``), ``[initial] q = "standing"`` or ``{posture, joints}``; every bad
input names its key path.

Requires example-robot-data (the ``test`` extra).
"""
from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import example_robot_data  # noqa: F401  (required)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import solve_scene
from geoddp.models import robots
from geoddp.scene import build_problem, load_scene
from geoddp.validate import InputError

UR5 = """
[model]
kind = "multibody"
{model}
root = "fixed"

[initial]
{initial}

[horizon]
dt = 0.05
steps = 10
integrator = "semi_implicit"

[[running_costs]]
type = "control"
reference = "hover"
weight = 1e-3

[[terminal_costs]]
type = "frame_placement"
frame = "{frame}"
translation = [0.3, 0.35, 0.25]
axis = [1.0, 0.0, 0.0]
angle_deg = 180.0
weight = 1e2

[solver]
initial_controls = "hover"
"""
ROBOT_Q = 'q = { posture = "neutral", joints = { shoulder_lift_joint = -1.2, elbow_joint = 1.4 } }'


def scene(tmp_path: Path, model: str = 'robot = "ur5"', initial: str = ROBOT_Q, frame: str = "tool0",
          name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(UR5.format(model=model, initial=initial, frame=frame))
    return p


def error(path: Path) -> InputError:
    with pytest.raises(InputError) as info:
        load_scene(path)
    return info.value


def test_robot_by_name_and_by_urdf_path_give_the_same_problem(tmp_path):
    spec = robots.find("ur5")
    by_name = load_scene(scene(tmp_path))
    share = spec.package_dirs[0]
    by_path = load_scene(scene(tmp_path, f'urdf = "{spec.urdf}"\npackage_dirs = ["{share}"]', name="p.toml"))
    assert by_name.robot == "ur5" and by_path.robot is None
    assert by_name.urdf == by_path.urdf == spec.urdf and by_name.package_dirs == by_path.package_dirs == (share,)
    q = np.zeros(6)
    q[1:3] = -1.2, 1.4
    np.testing.assert_array_equal(by_name.q0, q)
    np.testing.assert_array_equal(by_path.q0, q)
    a, b = build_problem(by_name), build_problem(by_path)
    assert (a.model.nq, a.model.nv, a.nu) == (b.model.nq, b.model.nv, b.nu) == (6, 6, 6)
    U = np.tile(pin.computeGeneralizedGravity(a.model.pin_model, a.model.pin_model.createData(), q), (10, 1))
    assert a.total_cost(U) == b.total_cost(U)
    # the replay finds the meshes through the description's package_dirs
    assert a.describe()["package_dirs"] == [share]


def test_named_posture_and_joints_on_top(tmp_path):
    spec = robots.find("solo12")
    text = f"""
[model]
kind = "multibody"
robot = "solo12"
gravity = false

[initial]
q = {{ posture = "standing", joints = {{ FL_KFE = -1.0 }} }}

[horizon]
dt = 0.05
steps = 4

[[terminal_costs]]
type = "state_regularisation"
q_reference = "initial"
q_weight = 1.0
"""
    p = tmp_path / "solo.toml"
    p.write_text(text)
    s = load_scene(p)
    assert s.root == "free_flyer"  # the robot's own root
    mb = spec.multibody(dt=0.05)
    want = robots.postures(mb.pin_model, spec.srdf)["standing"].copy()
    want[9] = -1.0
    np.testing.assert_array_equal(s.q0, want)
    p.write_text(text.replace('{ posture = "standing", joints = { FL_KFE = -1.0 } }', '"standing"'))
    np.testing.assert_array_equal(load_scene(p).q0[:7], [0, 0, 0.235, 0, 0, 0, 1])


def test_a_urdf_with_its_own_srdf(tmp_path):
    spec = robots.find("solo12")
    p = tmp_path / "s.toml"
    p.write_text(f"""
[model]
kind = "multibody"
urdf = "{spec.urdf}"
srdf = "{spec.srdf}"
package_dirs = "{spec.package_dirs[0]}"
gravity = false
[initial]
q = "straight_standing"
[horizon]
dt = 0.05
steps = 4
[[terminal_costs]]
type = "state_regularisation"
q_weight = 1.0
""")
    s = load_scene(p)
    assert s.root == "free_flyer" and s.q0[7] == 0.0 and s.q0[8] == 0.8


@pytest.mark.parametrize("model, initial, frame, key, detail", [
    ('robot = "ur_5"', ROBOT_Q, "tool0", "[model].robot", "did you mean 'ur5'"),
    ('robot = "ur5"\nurdf = "x.urdf"', ROBOT_Q, "tool0", "[model]", "exactly one of robot"),
    ("gravity = true", ROBOT_Q, "tool0", "[model]", "got neither"),
    ('robot = "ur5"', 'q = "standing"', "tool0", "[initial].q", "postures: neutral"),
    ('robot = "ur5"', 'q = { posture = "neutral", joints = { elbow = 1.0 } }', "tool0", "[initial].q.joints.elbow",
     "did you mean 'elbow_joint'"),
    ('robot = "ur5"', 'q = { posture = "nuetral" }', "tool0", "[initial].q.posture", "did you mean 'neutral'"),
    ('robot = "ur5"', 'q = { pose = "neutral" }', "tool0", "[initial].q.pose", ""),
    ('robot = "ur5"', ROBOT_Q, "tool_0", "terminal_costs[0].frame", "tool0"),
    ('robot = "ur5"\npackage_dirs = "nowhere"', ROBOT_Q, "tool0", "[model].package_dirs", "expected an existing directory"),
    ('robot = "ur5"\nsrdf = "gone.srdf"', ROBOT_Q, "tool0", "[model].srdf", "expected an existing SRDF file"),
])
def test_bad_robot_keys_name_their_key_path(tmp_path, model, initial, frame, key, detail):
    e = error(scene(tmp_path, model, initial, frame))
    assert e.parameter == key and detail in e.detail, (e.parameter, e.detail)


ONE_LINK = """<robot name="one">
  <link name="base"/>
  <link name="arm">
    <inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://{package}/meshes/arm.stl"/></geometry></visual>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
</robot>
"""
ONE_LINK_SCENE = """
[model]
kind = "multibody"
urdf = "urdf/one.urdf"
root = "fixed"
{extra}
[horizon]
dt = 0.1
steps = 3
[[terminal_costs]]
type = "state_regularisation"
q_weight = 1.0
"""


def test_package_uri_resolving_nowhere_names_package_dirs(tmp_path, monkeypatch):
    """A URDF naming package://nowhere_pkg/...: found in none of package_dirs, the URDF's folder,
    its parent and grandparent, example-robot-data, ROS_PACKAGE_PATH (emptied here): the error
    names [model].package_dirs and lists where it looked. The same URDF next to its package loads."""
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    (tmp_path / "urdf").mkdir()
    (tmp_path / "urdf" / "one.urdf").write_text(ONE_LINK.format(package="nowhere_pkg"))
    (tmp_path / "pkgs").mkdir()
    p = tmp_path / "s.toml"
    p.write_text(ONE_LINK_SCENE.format(extra='package_dirs = "pkgs"'))
    e = error(p)
    assert e.parameter == "[model].package_dirs"
    assert "expected a directory holding package 'nowhere_pkg'" in e.detail
    assert str(tmp_path / "pkgs") in e.detail and str(tmp_path / "urdf") in e.detail
    p.write_text(ONE_LINK_SCENE.format(extra=""))
    assert error(p).parameter == "[model].package_dirs"  # without package_dirs too: the defaults found nothing
    # the package found (its mesh file missing: not an error for the solve)
    (tmp_path / "pkgs" / "nowhere_pkg" / "meshes").mkdir(parents=True)
    p.write_text(ONE_LINK_SCENE.format(extra='package_dirs = "pkgs"'))
    assert load_scene(p).package_dirs == (str(tmp_path / "pkgs"),)


def test_a_robot_urdf_named_by_path_finds_its_meshes_without_package_dirs(tmp_path):
    """A scene naming example-robot-data's URDF by path and no package_dirs (as scenes written
    before these keys did) still loads: its package is found where the replay finds it."""
    spec = robots.find("ur5")
    s = load_scene(scene(tmp_path, f'urdf = "{spec.urdf}"'))
    assert s.package_dirs == () and robots.check_meshes(spec.urdf) == []


def test_missing_mesh_in_a_scene_leaves_the_solve_unchanged(tmp_path):
    spec = robots.find("ur5")
    forearm = "package://example-robot-data/robots/ur_description/meshes/ur5/visual/forearm.dae"
    (tmp_path / "ur5.urdf").write_text(spec.urdf.read_text().replace(forearm, forearm.replace("forearm", "gone")))
    share = spec.package_dirs[0]
    a = solve_scene(load_scene(scene(tmp_path, f'urdf = "ur5.urdf"\npackage_dirs = "{share}"')), verbose=False)
    b = solve_scene(load_scene(scene(tmp_path, name="b.toml")), verbose=False)
    assert a.cost == b.cost and np.array_equal(a.controls, b.controls)
    from geoddp.viz.model import load_visual_model

    with pytest.warns(UserWarning, match="gone.dae' not found"):
        assert load_visual_model(a.multibody).geometry.ngeoms == 6
