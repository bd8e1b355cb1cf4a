"""Mesh visuals in the replay (STL and OBJ files written by the test), package_dirs, missing meshes,
the collision option and the mesh-size limit, the camera framing the whole trajectory, frame-target
triads and the trail. The real robots (DAE meshes of example-robot-data) are in test_viz_robots.py."""
from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geoddp import viz  # first: silences meshcat's import warning
from geoddp.validate import InputError
from geoddp.viz import meshcat_replay
from geoddp.viz.html import STATUS_ID, decode_commands, render_html
from geoddp.viz.model import load_visual_model, package_dirs, placements_at, trajectory_box
from geoddp.viz.scene import BACKGROUND_RGB, ROBOT, SHAPE, TARGETS, TRAIL, TRIAD_COLORS, camera_view
from viz_fixtures import OFFLINE_FLAG, changed_fraction, chromium_or_skip, run_chromium, screenshot
from viz_meshes import CUBE_F, CUBE_V, drawn_triangles, mesh_arm, smooth_path, trajectory_result

H, DT = 20, 0.05
BACKGROUND_U8 = np.round(255 * np.asarray(BACKGROUND_RGB)).astype(int)
Q0, Q1 = np.array([0.0, 0.0]), np.array([2.0, -1.0])


@pytest.fixture()
def arm(tmp_path):
    """(URDF path, Result) of the mesh arm swinging from Q0 to Q1, with a target for its tool."""
    urdf = mesh_arm(tmp_path)
    model = pin.buildModelFromUrdf(str(urdf))
    return urdf, trajectory_result(urdf, smooth_path(model, Q0, Q1, H), DT)


def objects_of(cmds: list[dict]) -> dict[str, dict]:
    return {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}


def transforms_of(cmds: list[dict]) -> dict[str, np.ndarray]:
    """Last set_transform of every path, as a (4, 4) matrix (meshcat sends column-major)."""
    return {c["path"]: np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds if c["type"] == "set_transform"}


def clip_transforms(cmds: list[dict], name: str) -> np.ndarray:
    """(n_keys, 4, 4) keyframes of node robot/<name>."""
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    (clip,) = [a["clip"] for a in anim["animations"] if a["path"] == f"/meshcat/{ROBOT}/{name}"]
    tracks = {t["name"]: t["keys"] for t in clip["tracks"]}
    out = np.tile(np.eye(4), (len(tracks[".position"]), 1, 1))
    for k, (p, q) in enumerate(zip(tracks[".position"], tracks[".quaternion"])):
        x, y, z, w = q["value"]
        out[k, :3, :3] = pin.Quaternion(w, x, y, z).toRotationMatrix()
        out[k, :3, 3] = p["value"]
    return out


def reference_geometry(urdf: Path, kind=pin.GeometryType.VISUAL) -> tuple[pin.Model, pin.GeometryModel]:
    """The model and geometry built here by Pinocchio directly (not by the viewer's loader)."""
    model = pin.buildModelFromUrdf(str(urdf))
    return model, pin.buildGeomFromUrdf(model, str(urdf), kind, package_dirs=[str(urdf.parents[2]), str(urdf.parent)])


# ----------------------------------------------------------------------------- meshes drawn


def test_meshes_are_drawn_with_type_file_scale_colour_and_placement(arm):
    """Each mesh object is drawn from its file: the binary STL as compact geometry whose triangles,
    decoded from the command, are the file's (the unit cube's corners sit exactly on the uint16
    grid), the OBJ as meshcat's mesh geometry carrying the file's text; its URDF scale sits on
    robot/<name>/shape, its colour is the URDF material's, and its keyframes are oMg from
    Pinocchio's own GeometryModel (buildGeomFromUrdf) to 1e-12."""
    urdf, result = arm
    cmds = decode_commands(render_html(result))
    objects, transforms = objects_of(cmds), transforms_of(cmds)
    model, gmodel = reference_geometry(urdf)
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    expected = {"base_0": ("stl", 0xFF8000), "arm_0": ("obj", 0x009999), "hand_0": ("stl", 0xE6E6E6)}
    assert {o.name for o in gmodel.geometryObjects} == set(expected)
    for obj in gmodel.geometryObjects:
        fmt, color = expected[obj.name]
        node = f"/meshcat/{ROBOT}/{obj.name}/{SHAPE}"
        if fmt == "stl":
            np.testing.assert_array_equal(drawn_triangles(objects[node]), CUBE_V[CUBE_F])
        else:
            (geom,) = objects[node]["geometries"]
            assert geom["type"] == "_meshfile" and geom["format"] == fmt
            assert geom["data"].encode() == Path(obj.meshPath).read_bytes()
        assert objects[node]["materials"][0]["color"] == color
        np.testing.assert_array_equal(transforms[node], np.diag([*obj.meshScale, 1.0]))
        T = clip_transforms(cmds, obj.name)
        assert T.shape == (H + 1, 4, 4)
        for k in range(H + 1):
            pin.forwardKinematics(model, data, result.configurations[k])
            pin.updateGeometryPlacements(model, data, gmodel, gdata)
            assert np.abs(T[k] - gdata.oMg[gmodel.getGeometryId(obj.name)].homogeneous).max() < 1e-12
    # the arm's mesh is placed off its joint: (0.5, 0, 0) and rx(0.2) in the link frame
    arm_T = clip_transforms(cmds, "arm_0")[0]
    np.testing.assert_allclose(arm_T[:3, 3], [0.5, 0.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(arm_T[:3, :3], pin.rpy.rpyToMatrix(0.2, 0.0, 0.0), atol=1e-12)


def test_package_dirs_default_and_given(arm, tmp_path):
    """package:// and relative mesh paths resolve through Pinocchio in the description's
    package_dirs, after which the URDF's directory and its two parents are searched."""
    urdf, result = arm
    dirs = package_dirs(result.multibody)
    assert dirs[:3] == (str(urdf.parent), str(urdf.parents[1]), str(urdf.parents[2]))
    # the URDF text alone (no path): the meshes are found only through package_dirs
    xml_only = {"urdf_xml": urdf.read_text(), "root": "fixed"}
    with pytest.warns(UserWarning) as caught:
        bare = load_visual_model(xml_only)
    assert sorted(str(w.message).split(" not found")[0] for w in caught) == [
        "mesh file '../meshes/arm.obj'", "mesh file 'package://mesh_pkg/meshes/base.stl'"]
    assert bare.names == () and set(bare.missing) == {"../meshes/arm.obj", "package://mesh_pkg/meshes/base.stl"}
    given = load_visual_model({**xml_only, "package_dirs": [str(urdf.parents[2]), str(urdf.parent)]})
    assert given.names == ("base_0", "arm_0", "hand_0") and given.missing == ()
    assert given.package_dirs[:2] == (str(urdf.parents[2]), str(urdf.parent))
    with pytest.raises(InputError, match=r"^result\.multibody\.package_dirs: expected a path or a list of paths"):
        load_visual_model({**xml_only, "package_dirs": [3]})


def test_missing_mesh_warns_naming_the_file_and_draws_the_rest(arm, tmp_path):
    urdf, result = arm
    broken = urdf.with_name("broken.urdf")
    broken.write_text(urdf.read_text().replace("../meshes/arm.obj", "../meshes/gone.obj"))
    result.multibody["urdf"] = str(broken)
    with pytest.warns(UserWarning, match=r"mesh file '\.\./meshes/gone\.obj' not found .*the rest of the model is"):
        cmds = decode_commands(render_html(result))
    drawn = {p.split("/")[3] for p in objects_of(cmds) if p.startswith(f"/meshcat/{ROBOT}/")}
    assert drawn == {"base_0", "hand_0"}  # names as Pinocchio gives them in the full URDF
    # the rest is placed as in the intact model
    model, gmodel = reference_geometry(urdf)
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    pin.forwardKinematics(model, data, result.configurations[-1])
    pin.updateGeometryPlacements(model, data, gmodel, gdata)
    np.testing.assert_allclose(clip_transforms(cmds, "hand_0")[-1], gdata.oMg[gmodel.getGeometryId("hand_0")].homogeneous,
                               rtol=0, atol=1e-12)


def test_missing_mesh_in_the_live_replay_warns_too(arm, tmp_path, monkeypatch):
    """The live path goes through the same loader: the warning comes before any server starts."""
    urdf, result = arm
    broken = urdf.with_name("broken.urdf")
    broken.write_text(urdf.read_text().replace("package://mesh_pkg/meshes/base.stl", "package://nowhere/x.stl"))
    result.multibody["urdf"] = str(broken)
    recorder = viz.html._RecordingWindow()
    import meshcat

    with pytest.warns(UserWarning, match=r"mesh file 'package://nowhere/x\.stl' not found") as caught:
        viz.replay(result, vis=meshcat.Visualizer(window=recorder))
    assert len([w for w in caught if "not found" in str(w.message)]) == 1  # the model is loaded once
    paths = {json.dumps(p) for p in (decode_commands_raw(recorder.commands))}
    assert any("arm_0" in p for p in paths) and not any("base_0" in p or "hand_0" in p for p in paths)


def decode_commands_raw(blobs: list[bytes]) -> list[str]:
    import umsgpack

    return [c["path"] for c in map(umsgpack.unpackb, blobs) if c["type"] == "set_object"]


# ----------------------------------------------------------------------------- collision and size


def test_collision_option_draws_the_collision_geometry(arm):
    urdf, result = arm
    cmds = decode_commands(render_html(result, geometry="collision"))
    objects = objects_of(cmds)
    robot = {p.split("/")[3]: o for p, o in objects.items() if p.startswith(f"/meshcat/{ROBOT}/")}
    assert set(robot) == {"base_0", "arm_0"}  # the hand has no <collision>
    assert [robot[n]["geometries"][0]["type"] for n in ("base_0", "arm_0")] == ["BoxGeometry", "BoxGeometry"]
    assert [robot["arm_0"]["geometries"][0][k] for k in ("width", "height", "depth")] == [1.0, 0.1, 0.1]
    model, gmodel = reference_geometry(urdf, pin.GeometryType.COLLISION)
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    pin.forwardKinematics(model, data, result.configurations[H])
    pin.updateGeometryPlacements(model, data, gmodel, gdata)
    np.testing.assert_allclose(clip_transforms(cmds, "arm_0")[H], gdata.oMg[gmodel.getGeometryId("arm_0")].homogeneous,
                               rtol=0, atol=1e-12)
    with pytest.raises(InputError, match=r"^geometry: expected one of \('visual', 'collision'\)"):
        render_html(result, geometry="visuals")


def test_mesh_size_limit_message_and_the_ways_out(arm, tmp_path):
    """Above max_mesh_mb the export is refused, naming max_mesh_mb, with the size, the
    collision geometry's size and the options; nothing is written. Below it, or with None, or
    with geometry='collision', the page is written."""
    urdf, result = arm
    pkg = urdf.parents[1]
    size = 2 * (pkg / "meshes" / "base.stl").stat().st_size + (pkg / "meshes" / "arm.obj").stat().st_size
    limit = 0.5 * size / 1e6
    out = tmp_path / "big.html"
    with pytest.raises(InputError, match=(r"^max_mesh_mb: expected at most %g MB of mesh data to embed, got %.1f MB "
                                          r"\(visual meshes\): pass geometry='collision' to draw the collision geometry "
                                          r"instead \(0\.0 MB\), or raise max_mesh_mb \(None: no limit\)$")
                       % (limit, size / 1e6)):
        viz.export_html(result, out, max_mesh_mb=limit)
    assert not out.exists()
    with pytest.raises(InputError, match=r"^max_mesh_mb: expected at most"):
        viz.replay(result, max_mesh_mb=limit)  # refused before any server starts
    assert viz.export_html(result, out, max_mesh_mb=1.01 * size / 1e6).exists()
    assert viz.export_html(result, out, max_mesh_mb=None).exists()
    assert viz.export_html(result, out, geometry="collision", max_mesh_mb=limit).exists()
    with pytest.raises(InputError, match=r"^max_mesh_mb: expected a positive number of megabytes or None"):
        viz.export_html(result, out, max_mesh_mb=0)


# ----------------------------------------------------------------------------- camera, trail, targets


def test_camera_frames_every_vertex_of_every_frame(arm):
    """The orbit centre is the centre of the box of all drawn vertices over all frames (the
    scene root is moved by -centre) and the camera is far enough out for the sphere about it that
    holds every vertex at every frame to fit the 75 deg field of view."""
    urdf, result = arm
    cmds = decode_commands(render_html(result))
    model, gmodel = reference_geometry(urdf)
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    pts = []
    for q in result.configurations:
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gmodel, gdata)
        for i, obj in enumerate(gmodel.geometryObjects):
            V = np.asarray(obj.geometry.vertices())  # coal's vertices, the URDF scale applied
            M = gdata.oMg[i]
            pts.append(V @ M.rotation.T + M.translation)
    pts = np.vstack(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    # trajectory_box holds every vertex of every frame, and is tight for these boxy meshes
    visual = load_visual_model(result.multibody)
    blo, bhi = trajectory_box(visual, placements_at(visual, result.configurations))
    assert np.all(blo <= lo + 1e-12) and np.all(bhi >= hi - 1e-12)
    # the first frame alone would not do: the arm sweeps 2 rad
    first = pts[: len(pts) // (H + 1)]
    assert np.ptp(pts, axis=0)[1] > np.ptp(first, axis=0)[1] + 0.5
    root = transforms_of(cmds)["/meshcat"]
    centre = -root[:3, 3]
    np.testing.assert_allclose(root[:3, :3], np.eye(3), atol=0)
    (cam,) = [c for c in cmds if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"]
    x, y, z = cam["value"]
    offset = np.array([x, -z, y])  # meshcat's y-up camera frame back to world (z up)
    assert np.linalg.norm(centre - 0.5 * (first.min(axis=0) + first.max(axis=0))) > 0.2  # not the first frame's centre
    radius = np.linalg.norm(pts - centre, axis=1).max()
    assert np.linalg.norm(offset) * np.sin(np.radians(37.5)) >= radius
    target, position, r = camera_view(pts)
    # the scene's own radius includes the trail/targets (none here) and the box corners: >= radius
    assert np.linalg.norm(offset) >= np.linalg.norm(position - target) - 1e-9


def test_trail_points_are_the_frame_positions(arm):
    """Trail beads sit at oMf[tool].translation of every q_k to 1e-12 (their transforms carry
    float64); the line's vertices are the same points in float32, as three.js takes them."""
    urdf, result = arm
    cmds = decode_commands(render_html(result, trail="tool"))
    transforms, objects = transforms_of(cmds), objects_of(cmds)
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId("tool")
    expected = []
    for q in result.configurations:
        pin.framesForwardKinematics(model, data, q)
        expected.append(data.oMf[fid].translation.copy())
    expected = np.array(expected)
    beads = np.array([transforms[f"/meshcat/{TRAIL}/beads/{k}"][:3, 3] for k in range(H + 1)])
    assert np.abs(beads - expected).max() < 1e-12
    line = objects[f"/meshcat/{TRAIL}/line"]
    assert line["object"]["type"] == "Line"
    arr = line["geometries"][0]["data"]["attributes"]["position"]
    verts = np.frombuffer(arr["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(verts, expected, rtol=0, atol=1e-6)
    # the root trail of a fixed-base arm is the first joint's placement: (0, 0, 0.2) throughout
    root = transforms_of(decode_commands(render_html(result, trail="root")))
    np.testing.assert_allclose(root[f"/meshcat/{TRAIL}/beads/{H}"][:3, 3], [0.0, 0.0, 0.2], atol=1e-12)
    with pytest.raises(InputError, match=r"^trail: expected 'root' or a frame name of the model, got 'tol'; did you mean 'tool'"):
        render_html(result, trail="tol")


def test_frame_target_triad_at_the_placement(arm):
    """A target placement in Result.extra or in the model description is drawn as a triad
    (x, y, z = red, green, blue) at exactly that placement, whose points the camera frames."""
    urdf, result = arm
    M = pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.2, 0.3), np.array([0.3, 2.5, 1.0])).homogeneous
    result.extra["frame_targets"] = [{"frame": "tool", "placement": M.tolist()}]
    result.multibody["frame_targets"] = [{"frame": "arm", "position": [0.0, 0.0, -1.5]}]
    cmds = decode_commands(render_html(result))
    transforms, objects = transforms_of(cmds), objects_of(cmds)
    np.testing.assert_array_equal(transforms[f"/meshcat/{TARGETS}/1_tool"], M)
    np.testing.assert_array_equal(transforms[f"/meshcat/{TARGETS}/0_arm"][:3, 3], [0.0, 0.0, -1.5])
    colours = [objects[f"/meshcat/{TARGETS}/1_tool/{a}"]["materials"][0]["color"] for a in "xyz"]
    assert colours == list(TRIAD_COLORS)
    # the x axis cylinder (three.js: along y) is turned onto x and moved half its length out
    Tx = transforms[f"/meshcat/{TARGETS}/1_tool/x"]
    length = objects[f"/meshcat/{TARGETS}/1_tool/x"]["geometries"][0]["height"]
    np.testing.assert_allclose(Tx[:3, :3] @ [0, 1, 0], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(Tx[:3, 3], [length / 2, 0, 0], atol=1e-15)
    # the camera frames the targets too: both are inside the view sphere
    centre = -transforms["/meshcat"][:3, 3]
    (cam,) = [c for c in cmds if c["type"] == "set_property" and c["path"] == "/Cameras/default/rotated/<object>"]
    reach = np.linalg.norm(cam["value"]) * np.sin(np.radians(37.5))
    tips = [M[:3, 3] + length * M[:3, i] for i in range(3)] + [np.array([0.0, 0.0, -1.5 + length])]
    for p in [M[:3, 3], np.array([0.0, 0.0, -1.5])] + tips:
        assert np.linalg.norm(p - centre) <= reach


@pytest.mark.parametrize("entry, match", [
    ({"placement": np.eye(4).tolist()}, r"^result\.extra\.frame_targets\[0\]: expected a dict with a 'frame' name"),
    ({"frame": "tool", "placement": [[1, 0], [0, 1]]}, r"^result\.extra\.frame_targets\[0\]\.placement: expected a \(4, 4\)"),
    ({"frame": "tool", "position": [1, 2]}, r"^result\.extra\.frame_targets\[0\]\.position: expected a \(3,\) position"),
    ({"frame": "tool", "position": [1, 2, np.nan]}, r"^result\.extra\.frame_targets\[0\]: expected finite values"),
    ({"frame": "tool"}, r"^result\.extra\.frame_targets\[0\]: expected 'placement' \(4, 4\) or 'position' \(3,\)"),
])
def test_bad_frame_targets_name_the_entry(arm, entry, match):
    urdf, result = arm
    result.extra["frame_targets"] = [entry]
    with pytest.raises(InputError, match=match):
        render_html(result)


# ----------------------------------------------------------------------------- the page offline


def test_page_embeds_the_meshes_and_renders_them_offline(arm, tmp_path):
    """The HTML carries the mesh files (no reference to them on disk) and, with the network cut,
    Chromium draws the arm: orange base and teal arm pixels at t = 0, different pixels at t_f;
    the animation controls are there and #t= seeks."""
    urdf, result = arm
    page = viz.export_html(result, tmp_path / "arm.html", trail="tool")
    text = page.read_text()
    assert "mesh_pkg" not in text and "arm.obj" not in text  # data, not paths
    obj_text = (urdf.parents[1] / "meshes" / "arm.obj").read_text()
    cmds = decode_commands(text)
    assert any(c["type"] == "set_object" and c["object"]["geometries"][0].get("data") == obj_text
               for c in cmds if c["path"].endswith("arm_0/" + SHAPE))
    chromium_or_skip()
    url = page.resolve().as_uri()
    dom = run_chromium(url + "#t=0.5", "--dump-dom", OFFLINE_FLAG).stdout
    status = json.loads(re.search(r'<pre id="%s"[^>]*>(.*?)</pre>' % STATUS_ID, dom, flags=re.DOTALL).group(1))
    assert status["loaded"] is True and status["seek"] == 0.5
    assert status["controls"] == ["play", "pause", "reset", "time", "timeScale"]
    shots = {t: screenshot(url + f"#t={t}", tmp_path / f"arm_{t}.png", OFFLINE_FLAG) for t in (0.0, H * DT)}
    for t, img in shots.items():
        assert np.abs(img[-5, 5].astype(int) - BACKGROUND_U8).max() <= 3
        r, g, b = (img[..., i].astype(int) for i in range(3))
        orange = np.mean((r > 150) & (g > 50) & (g < 150) & (b < 60))
        teal = np.mean((r < 60) & (g > 70) & (b > 70) & (np.abs(g - b) < 30))
        assert changed_fraction(img, BACKGROUND_U8) > 0.03, t
        assert orange > 0.002 and teal > 0.002, (t, orange, teal)
    moved = np.mean(np.abs(shots[0.0].astype(int) - shots[H * DT].astype(int)).max(axis=2) > 12)
    assert moved > 0.01, moved


def test_bad_options_fail_before_any_server(arm, monkeypatch):
    import subprocess

    urdf, result = arm
    started = []

    class Recording(subprocess.Popen):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            started.append(self)

    monkeypatch.setattr(meshcat_replay.subprocess, "Popen", Recording)
    for kwargs, match in (({"trail": "nope"}, r"^trail:"), ({"geometry": "both"}, r"^geometry:"),
                          ({"trail": 3}, r"^trail: expected None, 'root' or a frame name")):
        with pytest.raises(InputError, match=match):
            viz.replay(result, **kwargs)
    assert started == []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        render_html(result)  # an intact model: no warning


def test_one_body_mesh_model_has_a_mesh_ghost(tmp_path):
    """A free-flying body whose only visual is an STL mesh: its ghost is the same mesh (the file's
    triangles), uniformly ghost-coloured and translucent, 3 % larger, at the final position with
    the target rotation."""
    from geoddp.viz.scene import GHOST, GHOST_COLOR, GHOST_INFLATE
    from viz_meshes import write_stl

    write_stl(tmp_path / "hull.stl")
    urdf = tmp_path / "probe.urdf"
    urdf.write_text("""<robot name="probe"><link name="body">
      <inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><mesh filename="hull.stl" scale="1.0 0.5 0.25"/></geometry></visual></link></robot>""")
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    q1 = pin.SE3ToXYZQUAT(pin.SE3(pin.exp3(np.array([0.0, 0.0, 1.0])), np.array([2.0, 0.0, 0.0])))
    result = trajectory_result(urdf, smooth_path(model, pin.neutral(model), q1, 10), root="free_flyer")
    R_d = pin.exp3(np.array([0.0, 0.0, np.pi / 2]))
    result.target_rotation = R_d
    cmds = decode_commands(render_html(result))
    objects, transforms = objects_of(cmds), transforms_of(cmds)
    node = f"/meshcat/{GHOST}/body_0/{SHAPE}"
    np.testing.assert_array_equal(drawn_triangles(objects[node]), CUBE_V[CUBE_F])
    np.testing.assert_array_equal(drawn_triangles(objects[f"/meshcat/{ROBOT}/body_0/{SHAPE}"]), CUBE_V[CUBE_F])
    mat = objects[node]["materials"][0]
    assert mat["color"] == GHOST_COLOR and mat["transparent"] is True and mat["opacity"] < 1
    np.testing.assert_allclose(transforms[node], np.diag([GHOST_INFLATE, 0.5 * GHOST_INFLATE, 0.25 * GHOST_INFLATE, 1.0]), atol=1e-15)
    ghost = transforms[f"/meshcat/{GHOST}/body_0"]
    np.testing.assert_allclose(ghost[:3, :3], R_d, atol=1e-12)
    np.testing.assert_allclose(ghost[:3, 3], [2.0, 0.0, 0.0], atol=1e-12)
