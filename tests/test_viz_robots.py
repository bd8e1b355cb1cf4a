"""Real robots from example-robot-data (UR5, Panda) in the replay: their DAE meshes drawn as
Pinocchio builds them, the HTML page self-contained, and headless Chromium showing the robot at
the first, middle and last frame, moving, with the end effector's target triad visible.

Requires example-robot-data (and its Python loaders, example_robot_data): imported at module
top on purpose, so a missing install fails here instead of skipping.
Set GEODDP_WRITE_FIGURES=1 to write docs/figures/replay_ur5.png and replay_panda.png (the middle
frame) from these screenshots.
"""
from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import example_robot_data  # noqa: F401  (required: see the module docstring)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import viz
from geoddp.viz.html import STATUS_ID, decode_commands
from geoddp.viz.model import example_robot_data_dir, load_visual_model
from geoddp.viz.scene import BACKGROUND_RGB, ROBOT, SHAPE, TARGETS
from viz_fixtures import OFFLINE_FLAG, changed_fraction, chromium_or_skip, run_chromium, screenshot
from viz_meshes import drawn_triangles, quantisation_step, smooth_path, trajectory_result

BACKGROUND_U8 = np.round(255 * np.asarray(BACKGROUND_RGB)).astype(int)
FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
H, DT = 40, 0.05  # 2 s

# name: (URDF below example-robot-data's package directory, q0, q1, end-effector frame)
ROBOTS = {
    "ur5": ("example-robot-data/robots/ur_description/urdf/ur5_robot.urdf",
            [0.0, -1.0, 1.2, -0.2, 1.57, 0.0], [2.2, -1.9, 0.6, 0.3, 1.0, 0.5], "tool0"),
    "panda": ("example-robot-data/robots/panda_description/urdf/panda.urdf",
              [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02],
              [1.8, 0.3, 0.2, -1.6, 0.3, 2.2, 0.2, 0.02, 0.02], "panda_hand"),
}

# Measured (800 x 600, headless Chromium as in viz_fixtures), first / middle / last frame (#t=):
# share of the central half differing from the background: UR5 11.0 % / 9.3 % / 11.5 % (10.6 /
# 9.2 / 11.1 % before compact meshes: meshcat's merge of a DAE node with several materials drew
# nothing of it, the UR5's dark joint housings), Panda 32.0 % / 25.1 % / 16.5 %; strongly red
# pixels (the target triad's x axis, drawn over the robot): UR5 591 at each frame, Panda 154 / 157
# / 160; pixels changed first -> middle and middle -> last: UR5 3.4 % and 3.3 %, Panda 9.3 % and
# 6.3 %. Thresholds sit at about half the smallest measured value.
MIN_DRAWN = {"ur5": 0.045, "panda": 0.08}
MIN_RED = 70
MIN_MOVED = 0.015
# The pages' sizes (MB) as measured: UR5 2.5, Panda 4.2 (9.8 and 15.1 with the DAE files' text
# embedded, before compact meshes).
MAX_PAGE_MB = 5.0


def robot_result(name: str):
    rel, q0, q1, frame = ROBOTS[name]
    urdf = Path(example_robot_data_dir()) / rel
    model = pin.buildModelFromUrdf(str(urdf))
    Q = smooth_path(model, np.array(q0), np.array(q1), H)
    data = model.createData()
    pin.framesForwardKinematics(model, data, Q[-1])
    target = data.oMf[model.getFrameId(frame)].homogeneous
    result = trajectory_result(urdf, Q, DT, extra={"frame_targets": [{"frame": frame, "placement": target.tolist()}]})
    return result, frame


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def robot(request):
    result, frame = robot_result(request.param)
    return request.param, result, frame


def test_package_dir_is_example_robot_datas():
    share = example_robot_data_dir()
    robots = example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf")
    assert Path(share) == Path(robots).resolve().parents[1]


def test_dae_meshes_drawn_as_pinocchio_builds_them(robot):
    """Every visual of the robot as loaded by example_robot_data.load is drawn from its DAE file as
    compact geometry: its triangles, decoded from the command, are those Pinocchio (coal) loads
    from the same file (every vertex within one quantisation step of one of coal's and back; as
    many triangles, up to the few degenerate ones coal drops), in the file's own materials (no URDF
    material); its scale sits on the shape node, its keyframes are oMg from the loader's own
    GeometryModel to 1e-12."""
    from scipy.spatial import cKDTree

    name, result, frame = robot
    wrapper = example_robot_data.load(name)
    gmodel, model = wrapper.visual_model, wrapper.model
    cmds = decode_commands(viz.html.render_html(result))
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    transforms = {c["path"]: np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds if c["type"] == "set_transform"}
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    clips = {a["path"].rsplit("/", 1)[-1]: a["clip"] for a in anim["animations"]}
    assert set(clips) == {o.name for o in gmodel.geometryObjects}
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    worst = 0.0
    colours = set()
    for obj in gmodel.geometryObjects:
        node = f"/meshcat/{ROBOT}/{obj.name}/{SHAPE}"
        drawn = drawn_triangles(objects[node])
        coal_mesh = obj.geometry
        V = np.asarray(coal_mesh.vertices()) / np.asarray(obj.meshScale)  # (n, 3), scale applied by coal
        P = drawn.reshape(-1, 3)
        step = quantisation_step(objects[node])
        assert cKDTree(V).query(P)[0].max() <= step and cKDTree(P).query(V)[0].max() <= step, obj.name
        assert coal_mesh.num_tris <= len(drawn) <= coal_mesh.num_tris * 1.001 + 1, (obj.name, len(drawn), coal_mesh.num_tris)
        mats = objects[node]["materials"]
        assert mats and all(m["type"] == "MeshPhongMaterial" for m in mats)
        colours |= {m["color"] for m in mats}
        np.testing.assert_array_equal(transforms[node], np.diag([*obj.meshScale, 1.0]))
        tracks = {t["name"]: t["keys"] for t in clips[obj.name]["tracks"]}
        for k in (0, H // 2, H):
            pin.forwardKinematics(model, data, result.configurations[k])
            pin.updateGeometryPlacements(model, data, gmodel, gdata)
            M = gdata.oMg[gmodel.getGeometryId(obj.name)]
            x, y, z, w = tracks[".quaternion"][k]["value"]
            R = pin.Quaternion(w, x, y, z).toRotationMatrix()
            worst = max(worst, np.abs(R - M.rotation).max(), np.abs(np.array(tracks[".position"][k]["value"]) - M.translation).max())
    assert worst < 1e-12, worst
    assert len(colours) >= 3  # the files' own colours (the UR5's blue caps and dark housings, the Panda's white and grey)


def test_collision_geometry_is_far_smaller(robot):
    """The way out of the size limit: the collision meshes (STL) are at most a tenth of the visual
    ones for both robots."""
    name, result, frame = robot
    from geoddp.viz.model import mesh_bytes

    visual = mesh_bytes(load_visual_model(result.multibody))
    collision = mesh_bytes(load_visual_model(result.multibody, "collision"))
    assert 5e6 < visual < 20e6 and collision < visual / 10, (visual, collision)
    cmds = decode_commands(viz.html.render_html(result, geometry="collision"))
    kinds = {c["object"]["geometries"][0]["type"] for c in cmds
             if c["type"] == "set_object" and c["path"].startswith(f"/meshcat/{ROBOT}/") and c["object"]["geometries"]}
    assert "BufferGeometry" in kinds  # the STL collision meshes, as compact geometry


def test_page_shows_the_robot_moving_and_its_target(robot, tmp_path):
    name, result, frame = robot
    page = viz.export_html(result, tmp_path / f"{name}.html", trail=frame)
    size_mb = page.stat().st_size / 1e6
    assert size_mb < MAX_PAGE_MB
    print(f"{name}: page {size_mb:.1f} MB")
    text = page.read_text()
    assert "package://" not in text and ".dae" not in text.split("<script>", 1)[0]
    chromium_or_skip()
    url = page.resolve().as_uri()
    dom = run_chromium(url, "--dump-dom", OFFLINE_FLAG).stdout
    status = json.loads(re.search(r'<pre id="%s"[^>]*>(.*?)</pre>' % STATUS_ID, dom, flags=re.DOTALL).group(1))
    assert status["loaded"] is True and status["duration"] == pytest.approx(H * DT)
    assert status["controls"] == ["play", "pause", "reset", "time", "timeScale"]  # any instant reachable
    shots = {}
    for tag, t in (("first", 0.0), ("middle", H * DT / 2), ("last", H * DT)):
        img = screenshot(f"{url}#t={t}", tmp_path / f"{name}_{tag}.png", OFFLINE_FLAG)
        assert np.abs(img[-5, 5].astype(int) - BACKGROUND_U8).max() <= 3
        drawn = changed_fraction(img, BACKGROUND_U8)
        r, g, b = (img[..., i].astype(int) for i in range(3))
        red = int(np.count_nonzero((r > 150) & (g < 80) & (b < 80)))
        print(f"{name} {tag}: drawn {drawn:.1%}, red triad pixels {red}")
        assert drawn > MIN_DRAWN[name], f"{tag}: only {drawn:.1%} of the centre differs from the background"
        assert red > MIN_RED, f"{tag}: the target triad's red axis has {red} pixels"
        shots[tag] = img
    for a, b_ in (("first", "middle"), ("middle", "last")):
        moved = float(np.mean(np.abs(shots[a].astype(int) - shots[b_].astype(int)).max(axis=2) > 12))
        print(f"{name} {a} -> {b_}: {moved:.1%} of the pixels changed")
        assert moved > MIN_MOVED, f"{a} -> {b_}: only {moved:.1%} of the pixels changed"
    # the triad is drawn at the placement the result names
    cmds = decode_commands(text)
    (M,) = [np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds
            if c["type"] == "set_transform" and c["path"] == f"/meshcat/{TARGETS}/0_{frame}"]
    np.testing.assert_array_equal(M, np.asarray(result.extra["frame_targets"][0]["placement"]))
    if os.environ.get("GEODDP_WRITE_FIGURES"):
        FIGURES.mkdir(parents=True, exist_ok=True)
        shutil.copy(tmp_path / f"{name}_middle.png", FIGURES / f"replay_{name}.png")


def test_live_replay_sends_the_meshes():
    """The live loopback viewer gets the same scene: the server holds every UR5 mesh (the DAE
    file's triangles, as compact geometry), the target triad and the trail, and the keyframes of
    the last link."""
    import base64

    import umsgpack

    result, frame = robot_result("ur5")
    vis = viz.replay(result, trail=frame, timeout_s=20)
    proc = vis.window.server_proc
    try:
        blobs = re.findall(r'base64,([A-Za-z0-9+/=]+)"', vis.static_html())
        cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    finally:
        vis.close()
    assert proc.wait(timeout=5) is not None
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    gmodel = example_robot_data.load("ur5").visual_model
    for obj in gmodel.geometryObjects:
        drawn = drawn_triangles(objects[f"/meshcat/{ROBOT}/{obj.name}/{SHAPE}"])
        assert obj.geometry.num_tris <= len(drawn) <= obj.geometry.num_tris * 1.001 + 1
    assert f"/meshcat/{TARGETS}/0_{frame}/x" in objects and "/meshcat/trail/line" in objects
    (anim,) = [c for c in cmds if c["type"] == "set_animation"]
    assert {len(t["keys"]) for a in anim["animations"] for t in a["clip"]["tracks"]} == {H + 1}
