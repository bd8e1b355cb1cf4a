"""Real robots by name and pin.Models handed over in Python (issue 14, items 1 and 2).

* ``Multibody.from_model``: an unedited ``pin.Model`` solves exactly as its URDF does (J and
  controls to 1e-12); a payload added in code raises the control effort by what gravity says;
  a reduced model (``pin.buildReducedModel``) solves and its replay draws every visual where
  Pinocchio places it, also after a JSON round trip; frame typos get a did-you-mean list.
* ``geoddp.models.robots``: load by name == load by path == the Pinocchio-built model (nq, nv,
  inertias, frames); SRDF postures and joint mappings; every bad input names its parameter;
  a missing mesh leaves the solve unchanged and the replay draws the rest and names it.

Requires example-robot-data (the ``test`` extra): imported at module top so a missing install
fails here instead of skipping.
"""
from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import example_robot_data  # noqa: F401  (required: see the module docstring)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import viz
from geoddp.models import robots
from geoddp.models.multibody import Multibody, root_of
from geoddp.costs.multibody import ControlRegularisation, FramePlacement, MultibodyCostSum, StateRegularisation
from geoddp.problem import Problem
from geoddp import Result
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError
from geoddp.viz.html import decode_commands
from geoddp.viz.model import load_visual_model, placements_at
from geoddp.viz.scene import ROBOT, SHAPE

Q0 = np.array([0.0, -1.2, 1.4, -1.6, -1.57, 0.0])  # UR5 start (rad)
DQ = np.array([0.6, -0.4, 0.5, 0.4, 0.5, -0.6])  # the target pose is tool0's at Q0 + DQ
H, DT = 40, 0.025  # 1 s


def reach_problem(mb: Multibody, q0: np.ndarray = Q0, frame: str = "tool0") -> Problem:
    """UR5-style reach: tool0 to the pose it has at the URDF model's Q0 + DQ; running posture,
    velocity and torque regularisation (about zero: the effort includes holding against gravity)."""
    pm = mb.pin_model
    nv = pm.nv
    ref = robots.find("ur5").multibody(dt=DT).pin_model  # the target is the same for every variant
    d = ref.createData()
    pin.framesForwardKinematics(ref, d, Q0 + DQ)
    M = d.oMf[ref.getFrameId("tool0")].copy()
    run = MultibodyCostSum([StateRegularisation(pm, q0, W=np.r_[np.full(nv, 1e-3), np.full(nv, 1e-2)]),
                            ControlRegularisation(np.zeros(mb.nu), W=np.full(mb.nu, 1e-4))], model=pm)
    term = MultibodyCostSum([FramePlacement(pm, frame, M, W=np.full(6, 1e3)),
                             StateRegularisation(pm, q0, W=np.r_[np.zeros(nv), np.full(nv, 1e1)])], model=pm, terminal=True)
    return Problem(mb, q0, np.zeros(nv), H, run, term)


def solve_reach(mb: Multibody, q0: np.ndarray = Q0):
    p = reach_problem(mb, q0)
    g = pin.computeGeneralizedGravity(mb.pin_model, mb.pin_model.createData(), q0)
    return solve(p, SolverOptions(verbose=False), initial_controls=np.tile(mb.actuation.T @ g, (H, 1)))


@pytest.fixture(scope="module")
def ur5_models():
    """(model, visual geometry) of the UR5 as pin.buildModelsFromUrdf builds them."""
    return robots.find("ur5").pin_models()


@pytest.fixture(scope="module")
def ur5_solution():
    return solve_reach(Multibody(robots.find("ur5").urdf, root="fixed", dt=DT, integrator="semi_implicit"))


# ------------------------------------------------------------------ item 2: a pin.Model in
def test_unedited_model_solves_exactly_as_its_urdf(ur5_models, ur5_solution):
    model, visual = ur5_models
    r = solve_reach(Multibody.from_model(model, visual, dt=DT, integrator="semi_implicit"))
    assert ur5_solution.converged and r.converged
    assert r.iterations == ur5_solution.iterations
    assert abs(r.cost - ur5_solution.cost) <= 1e-12 * abs(ur5_solution.cost)
    np.testing.assert_allclose(r.controls, ur5_solution.controls, rtol=0, atol=1e-9)


def test_heavier_payload_needs_more_effort(ur5_models, ur5_solution):
    """A 3 kg sphere 0.1 m out on the last link, added in code: the optimal torques grow by
    about the payload's gravity torque (the arm holds it for the whole second), and the solve of
    the original model is untouched by the edit (the model was copied)."""
    model, visual = ur5_models
    heavy = pin.Model(model)
    j = heavy.getJointId("wrist_3_joint")
    heavy.appendBodyToJoint(j, pin.Inertia.FromSphere(3.0, 0.03), pin.SE3(np.eye(3), np.array([0.0, 0.1, 0.0])))
    light_mb = Multibody.from_model(model, visual, dt=DT, integrator="semi_implicit")
    heavy_mb = Multibody.from_model(heavy, visual, dt=DT, integrator="semi_implicit")
    heavy.inertias[j] = pin.Inertia.Zero()  # edits after the hand-over change nothing
    r = solve_reach(heavy_mb)
    light = ur5_solution
    assert r.converged
    effort_light, effort_heavy = float(np.sum(light.controls**2)), float(np.sum(r.controls**2))
    # measured: 26334 -> 51170 (N m)^2 (x 1.94)
    assert effort_heavy > 1.5 * effort_light, (effort_light, effort_heavy)
    # the mean extra torque of the lift joints is the extra gravity torque along the two paths
    def gravity(mb, Q):
        return np.array([pin.computeGeneralizedGravity(mb.pin_model, mb.pin_model.createData(), q) for q in Q[:H]])
    g_extra = np.mean(gravity(heavy_mb, r.configurations) - gravity(light_mb, light.configurations), axis=0)
    du = np.mean(r.controls - light.controls, axis=0)
    assert np.abs(g_extra[1:3]).min() > 1.0  # N m: shoulder lift and elbow carry the payload
    # measured: du (-6.56, -5.26) N m, gravity (-6.71, -5.12) N m (2.7 % apart)
    np.testing.assert_allclose(du[1:3], g_extra[1:3], rtol=0.05)
    assert abs(solve_reach(light_mb).cost - light.cost) <= 1e-12 * light.cost


def test_reduced_model_solves_and_its_replay_draws_it(ur5_models, tmp_path):
    """Wrist 2 and 3 locked: a 4-joint arm. It solves (to the best pose it can reach), and the
    replay rebuilt from the Result (also after a JSON round trip) draws all seven meshes exactly
    where Pinocchio's reduced geometry model puts them."""
    model, visual = ur5_models
    q_lock = Q0.copy()
    locked = [model.getJointId(n) for n in ("wrist_2_joint", "wrist_3_joint")]
    red, (gred,) = pin.buildReducedModel(model, [visual], locked, q_lock)
    mb = Multibody.from_model(red, gred, dt=DT, integrator="semi_implicit")
    assert (mb.nq, mb.nv, mb.root) == (4, 4, "fixed")
    r = solve_reach(mb, Q0[:4])
    assert r.converged and r.configurations.shape == (H + 1, 4)
    J0 = reach_problem(mb, Q0[:4]).total_cost(np.tile(pin.computeGeneralizedGravity(red, red.createData(), Q0[:4]), (H, 1)))
    assert r.cost < 0.5 * J0
    back = Result.read_json(r.write_json(tmp_path / "reduced.json"))
    for res in (r, back):
        vm = load_visual_model(res.multibody)
        assert vm.model == red and vm.geometry.ngeoms == gred.ngeoms == 7
        P = placements_at(vm, res.configurations[[0, H]])
        data, gdata = red.createData(), pin.GeometryData(gred)
        for row, q in zip(P, res.configurations[[0, H]]):
            pin.forwardKinematics(red, data, q)
            pin.updateGeometryPlacements(red, data, gred, gdata)
            want = np.array([gdata.oMg[i].homogeneous for i in range(gred.ngeoms)])
            np.testing.assert_allclose(row, want, rtol=0, atol=1e-12)
    cmds = decode_commands(viz.html.render_html(back))
    drawn = {c["path"] for c in cmds if c["type"] == "set_object" and c["path"].endswith("/" + SHAPE)}
    assert drawn == {f"/meshcat/{ROBOT}/{o.name}/{SHAPE}" for o in gred.geometryObjects}


def test_model_without_geometry_replays_from_its_urdf(ur5_models):
    model, _ = ur5_models
    mb = Multibody.from_model(model, dt=DT, urdf=robots.find("ur5").urdf)
    vm = load_visual_model(mb.description())
    assert vm.geometry.ngeoms == 7 and vm.missing == ()
    bare = Multibody.from_model(model, dt=DT)
    with pytest.warns(UserWarning, match="without a visual geometry model or URDF"):
        assert load_visual_model(bare.description()).geometry.ngeoms == 0


def test_from_model_bad_input_names_the_parameter(ur5_models):
    model, visual = ur5_models
    with pytest.raises(InputError, match=r"^model: expected a pinocchio.Model, got str"):
        Multibody.from_model("ur5.urdf", dt=DT)
    with pytest.raises(InputError, match=r"^geometry: expected a pinocchio.GeometryModel"):
        Multibody.from_model(model, model, dt=DT)
    with pytest.raises(InputError, match=r"^root: expected the model's own root 'fixed'.*JointModelFreeFlyer"):
        Multibody.from_model(model, root="free_flyer", dt=DT)
    red = pin.buildReducedModel(model, [1, 2, 3, 4], Q0)
    with pytest.raises(InputError, match=r"^geometry: object 'forearm_link_0' hangs on joint 3, but the model has 3 joints"):
        Multibody.from_model(red, visual, dt=DT)
    massless = pin.Model(model)
    massless.inertias[6] = pin.Inertia.Zero()
    with pytest.raises(InputError, match=r"^model: .*wrist_3"):
        Multibody.from_model(massless, dt=DT)
    with pytest.raises(InputError, match=r"^dt: "):
        Multibody.from_model(model, dt=-1.0)


def test_frame_typo_gets_a_did_you_mean_list(ur5_models):
    model, _ = ur5_models
    mb = Multibody.from_model(model, dt=DT)
    with pytest.raises(InputError, match=r"^FramePlacement.frame_name: .*model 'ur5', got 'tool'; did you mean 'tool0'\?$"):
        FramePlacement(mb.pin_model, "tool", pin.SE3.Identity())
    with pytest.raises(InputError, match=r"^FramePlacement.frame_name: .*got 'wrist3_link'; did you mean 'wrist_3_link', '\w+', '\w+'\?$"):
        FramePlacement(mb.pin_model, "wrist3_link", pin.SE3.Identity())


def test_root_of_a_built_model():
    spec = robots.find("solo12")
    assert root_of(pin.buildModelFromUrdf(str(spec.urdf), pin.JointModelFreeFlyer())) == "free_flyer"
    assert root_of(pin.buildModelFromUrdf(str(spec.urdf), pin.JointModelSpherical())) == "spherical"
    assert root_of(pin.buildModelFromUrdf(str(spec.urdf))) == "fixed"


# ------------------------------------------------------------------ item 1: robots by name
def _same_model(a: pin.Model, b: pin.Model) -> None:
    assert (a.nq, a.nv, a.njoints) == (b.nq, b.nv, b.njoints)
    assert list(a.names) == list(b.names)
    for i in range(a.njoints):
        assert a.inertias[i].isApprox(b.inertias[i], 1e-14), a.names[i]
        assert a.jointPlacements[i].isApprox(b.jointPlacements[i], 1e-14)
    assert [f.name for f in a.frames] == [f.name for f in b.frames]
    for fa, fb in zip(a.frames, b.frames):
        assert fa.parentJoint == fb.parentJoint and fa.placement.isApprox(fb.placement, 1e-14)
    np.testing.assert_array_equal(a.gravity.vector, b.gravity.vector)


@pytest.mark.parametrize("name, root, nq, nv", [("ur5", "fixed", 6, 6), ("panda", "fixed", 9, 9),
                                                ("solo12", "free_flyer", 19, 18), ("hector", "free_flyer", 7, 6)])
def test_load_by_name_equals_load_by_path(name, root, nq, nv):
    by_name = robots.load(name, dt=DT)
    spec = robots.find(name)
    assert spec.root == root and by_name.root == root
    by_path = Multibody(spec.urdf, root=root, dt=DT)
    rj = pin.JointModelFreeFlyer() if root == "free_flyer" else None
    pinned = pin.buildModelFromUrdf(str(spec.urdf), *([rj] if rj else []))
    assert (by_name.nq, by_name.nv) == (nq, nv)
    _same_model(by_name.pin_model, by_path.pin_model)
    _same_model(by_name.pin_model, pinned)
    _same_model(Multibody.from_model(spec.pin_models()[0], dt=DT).pin_model, pinned)
    assert by_name.description()["package_dirs"] == list(spec.package_dirs)


def test_unknown_robot_did_you_mean():
    with pytest.raises(InputError, match=r"^robot: expected a robot of example-robot-data, got 'ur_5'; did you mean 'ur5'.*known robots: .*solo12"):
        robots.find("ur_5")
    with pytest.raises(InputError, match=r"^robot: .*got 3;"):
        robots.find(3)


def test_srdf_postures_and_joint_mapping():
    spec = robots.find("solo12")
    mb = spec.multibody(dt=DT)
    named = spec.postures(mb.pin_model)
    assert set(named) == {"neutral", "standing", "straight_standing"} and spec.default_posture == "standing"
    q = robots.configuration(mb.pin_model, named, "standing")
    # solo.srdf's standing: base 0.235 m up, legs (0.1, 0.8, -1.6) with hip signs per leg
    np.testing.assert_array_equal(q[:7], [0, 0, 0.235, 0, 0, 0, 1])
    np.testing.assert_array_equal(q[7:10], [0.1, 0.8, -1.6])
    q2 = robots.configuration(mb.pin_model, named, "standing", {"FL_KFE": -1.0, "root_joint": [0, 0, 1, 0, 0, 0, 1]})
    assert q2[9] == -1.0 and q2[2] == 1.0 and np.array_equal(np.delete(q2, [2, 9]), np.delete(q, [2, 9]))
    panda = robots.find("panda")
    pm = panda.multibody(dt=DT).pin_model
    np.testing.assert_allclose(robots.configuration(pm, panda.postures(pm), "default")[:7],
                               [0, -0.785, 0, -2.356, 0, 1.571, 0.785], atol=1e-3)


def test_posture_and_joint_errors_name_the_parameter():
    spec = robots.find("solo12")
    pm = spec.multibody(dt=DT).pin_model
    named = spec.postures(pm)
    with pytest.raises(InputError, match=r"^initial.q: expected a named posture, got 'standin'; did you mean 'standing'.*postures: neutral, standing, straight_standing"):
        robots.configuration(pm, named, "standin")
    with pytest.raises(InputError, match=r"^initial.joints.FL_KNEE: expected a joint name of the model, got 'FL_KNEE'; did you mean 'FL_KFE'"):
        robots.configuration(pm, named, "standing", {"FL_KNEE": 1.0})
    with pytest.raises(InputError, match=r"^initial.joints.FL_KFE: expected a finite number"):
        robots.configuration(pm, named, "standing", {"FL_KFE": "bent"})
    with pytest.raises(InputError, match=r"^initial.joints.root_joint: expected the 7 coordinates"):
        robots.configuration(pm, named, "standing", {"root_joint": [0, 0, 1]})
    with pytest.raises(InputError, match=r"^initial.q: expected unit quaternions"):
        robots.configuration(pm, named, "standing", {"root_joint": [0, 0, 1, 0, 0, 0, 2]})


def test_package_uri_resolving_nowhere_names_package_dirs(tmp_path):
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    (tmp_path / "pkg" / "meshes" / "a.stl").write_text("solid a\nendsolid a\n")
    assert robots.resolve_mesh("package://pkg/meshes/a.stl", [str(tmp_path)]) == tmp_path / "pkg" / "meshes" / "a.stl"
    assert robots.resolve_mesh("package://pkg/meshes/gone.stl", [str(tmp_path)]) is None  # package found: a missing mesh
    with pytest.raises(InputError, match=r"^package_dirs: expected a directory holding package 'nowhere' \(for 'package://nowhere/x.stl'\), got none among \['/"):
        robots.resolve_mesh("package://nowhere/x.stl", [str(tmp_path)])
    with pytest.raises(InputError, match=r"^\[model\].package_dirs: "):
        robots.resolve_mesh("package://nowhere/x.stl", [], parameter="[model].package_dirs")
    # file:// and relative paths, as Pinocchio resolves them
    assert robots.resolve_mesh(f"file://{tmp_path}/pkg/meshes/a.stl") == tmp_path / "pkg" / "meshes" / "a.stl"
    assert robots.resolve_mesh("meshes/a.stl", base_dir=tmp_path / "pkg") == tmp_path / "pkg" / "meshes" / "a.stl"


def test_a_robot_found_before_is_found_again_only_while_its_files_are_there(tmp_path):
    """find() remembers where a robot was found on this sys.path, and looks again when its URDF
    is no longer there."""
    import sys

    spec = robots.find("ur5")
    assert robots.find("ur5") is spec
    stale = dataclasses.replace(spec, urdf=tmp_path / "gone.urdf")
    robots._FOUND[("ur5", tuple(sys.path))] = stale
    again = robots.find("ur5")
    assert again is not stale and again == spec and again.urdf.is_file()
    with pytest.raises(InputError, match="^robot: expected a robot of example-robot-data"):
        robots.find("ur55")  # a refused name is refused every time
    with pytest.raises(InputError, match="^robot: expected a robot of example-robot-data"):
        robots.find("ur55")


def test_meshes_found_before_are_checked_again_on_disk(tmp_path, monkeypatch):
    """check_meshes remembers where a URDF's meshes were all found (a sweep checks one robot per
    case) but still sees each file: one removed since is reported missing, one restored is found
    again, and a changed search path or URDF is resolved anew."""
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    for name in ("a.stl", "b.stl"):
        (tmp_path / "pkg" / "meshes" / name).write_text("solid a\nendsolid a\n")
    urdf = tmp_path / "two.urdf"
    mesh = '<visual><geometry><mesh filename="package://pkg/meshes/{}"/></geometry></visual>'
    urdf.write_text(f'<robot name="two"><link name="a">{mesh.format("a.stl")}</link>'
                    f'<link name="b">{mesh.format("b.stl")}</link></robot>')
    resolved = []
    real = robots.resolve_mesh
    monkeypatch.setattr(robots, "resolve_mesh", lambda *a: resolved.append(a[0]) or real(*a))
    assert robots.check_meshes(urdf, [str(tmp_path)]) == [] and len(resolved) == 2
    assert robots.check_meshes(urdf, [str(tmp_path)]) == [] and len(resolved) == 2  # found again, not resolved
    (tmp_path / "pkg" / "meshes" / "b.stl").rename(tmp_path / "b.stl")
    assert robots.check_meshes(urdf, [str(tmp_path)]) == ["package://pkg/meshes/b.stl"]
    assert robots.check_meshes(urdf, [str(tmp_path)]) == ["package://pkg/meshes/b.stl"]  # a miss is never kept
    (tmp_path / "b.stl").rename(tmp_path / "pkg" / "meshes" / "b.stl")
    assert robots.check_meshes(urdf, [str(tmp_path)]) == []
    n = len(resolved)
    other = tmp_path / "other"
    (other / "pkg" / "meshes").mkdir(parents=True)
    assert robots.check_meshes(urdf, [str(other), str(tmp_path)]) == [] and len(resolved) == n + 2  # new search path
    urdf.write_text(f'<robot name="two"><link name="a">{mesh.format("a.stl")}</link></robot>')
    assert robots.check_meshes(urdf, [str(tmp_path)]) == [] and len(resolved) == n + 3  # new URDF text


def test_missing_mesh_leaves_the_solve_unchanged_and_the_replay_names_it(tmp_path, ur5_solution):
    """The UR5 URDF with its forearm mesh renamed to a file that does not exist (its package
    does): the model, and so the solve, is the same to the last bit; the replay warns naming the
    file and draws the six other meshes."""
    spec = robots.find("ur5")
    text = spec.urdf.read_text()
    forearm = "package://example-robot-data/robots/ur_description/meshes/ur5/visual/forearm.dae"
    gone = forearm.replace("forearm.dae", "gone.dae")
    assert text.count(forearm) == 1
    urdf = tmp_path / "ur5_missing.urdf"
    urdf.write_text(text.replace(forearm, gone))
    assert robots.check_meshes(urdf, spec.package_dirs) == [gone]
    mb = Multibody(urdf, root="fixed", dt=DT, integrator="semi_implicit", package_dirs=spec.package_dirs)
    r = solve_reach(mb)
    assert r.cost == ur5_solution.cost and np.array_equal(r.controls, ur5_solution.controls)
    with pytest.warns(UserWarning, match=r"mesh file '%s' not found .*the rest of the model is" % gone):
        vm = load_visual_model(r.multibody)
    assert vm.missing == (gone,) and vm.geometry.ngeoms == 6 and "forearm_link_0" not in vm.names
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmds = decode_commands(viz.html.render_html(r))
    assert len([c for c in cmds if c["type"] == "set_object" and c["path"].endswith("/" + SHAPE)]) == 6


def test_load_takes_package_dirs_before_the_robots_own(tmp_path):
    """robots.load(..., package_dirs=...) searches the user's folders first, then the robot's (it
    had raised TypeError: package_dirs given twice); a value that is no folder list is named."""
    spec = robots.find("ur5")
    ur5 = robots.load("ur5", dt=0.01, package_dirs=[str(tmp_path)])
    assert ur5.package_dirs == (str(tmp_path), *spec.package_dirs)
    assert robots.load("ur5", dt=0.01, package_dirs=str(tmp_path)).package_dirs == ur5.package_dirs
    with pytest.raises(InputError, match="expected a path or a list of paths, got 5") as e:
        robots.load("ur5", dt=0.01, package_dirs=5)
    assert e.value.parameter == "package_dirs"
