"""Full-model replay of multibody results: every URDF visual animated by forward kinematics,
in the static HTML export (checked in headless Chromium) and in the live loopback viewer."""
from __future__ import annotations

import base64
import json
import re
import subprocess
import warnings

import numpy as np
import pinocchio as pin
import pytest

from geoddp import viz  # first: silences meshcat's import warning
from geoddp.data import urdf_dir
from geoddp.scene.builtin import space_manipulator
from geoddp import Result
from geoddp.validate import InputError
from geoddp.viz import meshcat_replay
from geoddp.viz.html import STATUS_ID, decode_commands, record_scene
from geoddp.viz.model import load_visual_model, visual_placements

MODELS = urdf_dir()  # the built-in URDFs (package data)
from geoddp.viz.scene import BACKGROUND_RGB, GHOST, ROBOT, SHAPE, TARGETS
import umsgpack  # noqa: E402

from viz_fixtures import OFFLINE_FLAG, changed_fraction, chromium_or_skip, keyframes, multibody_result, run_chromium, screenshot

H, DT = 20, 0.05
BACKGROUND_U8 = np.round(255 * np.asarray(BACKGROUND_RGB)).astype(int)
MANIPULATOR_OBJECTS = {"base_0", "shoulder_0", "upper_arm_0", "forearm_0", "ee_0"}


@pytest.fixture(scope="module")
def manip() -> Result:
    return multibody_result("space_manipulator", horizon=H, dt=DT, max_iter=2)


@pytest.fixture(scope="module")
def docking() -> Result:
    return multibody_result("spacecraft_docking", horizon=10, dt=0.2, max_iter=2)


def animation_clips(cmds: list[dict]) -> dict[str, dict]:
    """Node name under /meshcat/robot -> its clip, from the (last) set_animation command."""
    anims = [c for c in cmds if c["type"] == "set_animation"]
    assert anims, "no set_animation command"
    prefix = f"/meshcat/{ROBOT}/"
    return {a["path"][len(prefix):]: a["clip"] for a in anims[-1]["animations"] if a["path"].startswith(prefix)}


def scene_of(result: Result) -> str:
    """The recorded meshcat commands as canonical JSON, uuids numbered by first appearance
    (meshcat draws fresh uuids for every object)."""
    text = json.dumps([umsgpack.unpackb(c) for c in record_scene(result)], sort_keys=True)
    ids: dict[str, str] = {}
    return re.sub(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}",
                  lambda m: ids.setdefault(m.group(0), f"uuid-{len(ids)}"), text)


# ----------------------------------------------------------------------------- (a) placements


def test_animation_placements_equal_forward_kinematics(manip):
    """Every keyframe of every object equals oMg(q_k) computed here from the solver's own model
    (not the viewer's rebuilt one), to 1e-12; and the arm really moves."""
    solver_model = space_manipulator(horizon=H, dt=DT).model.pin_model
    gmodel = pin.buildGeomFromUrdf(solver_model, str(MODELS / "space_manipulator.urdf"), pin.GeometryType.VISUAL)
    data, gdata = solver_model.createData(), pin.GeometryData(gmodel)
    clips = animation_clips(decode_commands(viz.html.render_html(manip)))
    assert set(clips) == MANIPULATOR_OBJECTS
    Q = manip.configurations
    assert Q.shape == (H + 1, 10)
    assert np.ptp(Q[:, 7:], axis=0).min() > 0.1  # every arm joint moves by more than 0.1 rad
    worst = 0.0
    for name, clip in clips.items():
        assert clip["fps"] == pytest.approx(1.0 / DT)
        T = keyframes(clip)
        assert T.shape[0] == H + 1
        gid = gmodel.getGeometryId(name)
        for k in range(H + 1):
            pin.forwardKinematics(solver_model, data, Q[k])
            pin.updateGeometryPlacements(solver_model, data, gmodel, gdata)
            worst = max(worst, np.abs(T[k] - gdata.oMg[gid].homogeneous).max())
    assert worst < 1e-12, worst


def test_end_effector_and_arm_links_follow_their_frames(manip):
    """Frame-level check by a different route (framesForwardKinematics, hand-written URDF
    offsets): the end-effector sphere sits at oMf[ee], the upper-arm cylinder at
    oMf[upper_arm] * (Ry(pi/2), 0.5 m along x), the base box at the free-flyer's XYZQUAT."""
    model = space_manipulator(horizon=H, dt=DT).model.pin_model
    data = model.createData()
    T = {n: keyframes(c) for n, c in animation_clips(decode_commands(viz.html.render_html(manip))).items()}
    arm_offset = pin.SE3(pin.exp3(np.array([0.0, np.pi / 2, 0.0])), np.array([0.5, 0.0, 0.0]))
    for k in (0, 1, H // 2, H - 1, H):
        q = manip.configurations[k]
        pin.framesForwardKinematics(model, data, q)
        assert np.abs(T["ee_0"][k] - data.oMf[model.getFrameId("ee")].homogeneous).max() < 1e-12
        expected_arm = (data.oMf[model.getFrameId("upper_arm")] * arm_offset).homogeneous
        assert np.abs(T["upper_arm_0"][k] - expected_arm).max() < 1e-12
        assert np.abs(T["base_0"][k] - pin.XYZQUATToSE3(q[:7]).homogeneous).max() < 1e-12
    # the end effector ends where the last configuration puts it, and it travelled
    assert np.linalg.norm(T["ee_0"][-1][:3, 3] - T["ee_0"][0][:3, 3]) > 0.05


def test_root_translation_is_replayed(docking):
    """The spacecraft starts 4.3 m from the dock: the bus keyframes carry that translation."""
    clips = animation_clips(decode_commands(viz.html.render_html(docking)))
    assert set(clips) == {"bus_0", "bus_1", "bus_2", "bus_3"}  # bus, two panels, docking port
    bus = keyframes(clips["bus_0"])
    np.testing.assert_allclose(bus[:, :3, 3], docking.configurations[:, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(bus[0, :3, 3], [-4.0, 1.5, 0.5], atol=1e-12)
    # the right-hand panel is 1.9 m along the bus's own y axis at every frame
    panel = keyframes(clips["bus_1"])
    np.testing.assert_allclose(panel[:, :3, 3], bus[:, :3, 3] + 1.9 * bus[:, :3, 1], atol=1e-12)


def test_one_body_free_flyer_has_a_ghost_at_the_target_rotation(docking):
    """The docking spacecraft (one body, free-flyer root): the ghost is the whole model at the final
    position with the bus's rotation set to the target (90 deg about z), static (not animated)."""
    cmds = decode_commands(viz.html.render_html(docking))
    ghost = {c["path"][len(f"/meshcat/{GHOST}/"):]: np.asarray(c["matrix"]).reshape(4, 4).T
             for c in cmds if c["type"] == "set_transform" and c["path"].startswith(f"/meshcat/{GHOST}/")
             and not c["path"].endswith("/" + SHAPE)}
    assert set(ghost) == {"bus_0", "bus_1", "bus_2", "bus_3"}
    R_d = pin.exp3(np.array([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(docking.target_rotation, R_d, atol=1e-15)
    np.testing.assert_allclose(ghost["bus_0"][:3, :3], R_d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ghost["bus_0"][:3, 3], docking.configurations[-1, :3], rtol=0, atol=1e-12)
    # panel 1.9 m along the target's y axis, i.e. along world -x
    np.testing.assert_allclose(ghost["bus_1"][:3, 3], docking.configurations[-1, :3] + [-1.9, 0.0, 0.0], atol=1e-12)
    anims = [c for c in cmds if c["type"] == "set_animation"]
    assert not any(GHOST in a["path"] for a in anims[-1]["animations"])


def test_shapes_have_urdf_sizes_and_colours(manip):
    cmds = decode_commands(viz.html.render_html(manip))
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    forearm = objects[f"/meshcat/{ROBOT}/forearm_0/{SHAPE}"]
    (geom,) = forearm["geometries"]
    assert geom["type"] == "CylinderGeometry" and geom["height"] == 1.0 and geom["radiusTop"] == 0.05
    base = objects[f"/meshcat/{ROBOT}/base_0/{SHAPE}"]
    assert [base["geometries"][0][k] for k in ("width", "height", "depth")] == [1.2, 1.0, 1.2]
    assert base["materials"][0]["color"] == (round(0.78 * 255) << 16) | (round(0.63 * 255) << 8) | round(0.40 * 255)
    # the manipulator's own objects and the triad of its terminal frame target (the end
    # effector's placement, from the problem's description), and no ghost: its target_rotation
    # is the end effector's, not the root's (geoddp.viz.model.ghost_configuration)
    triad = {p for p in objects if p.startswith(f"/meshcat/{TARGETS}/")}
    (target,) = manip.multibody["frame_targets"]
    assert triad == {f"/meshcat/{TARGETS}/0_{target['frame']}/{a}" for a in ("x", "y", "z", "origin")}
    M = [np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds
         if c["type"] == "set_transform" and c["path"] == f"/meshcat/{TARGETS}/0_{target['frame']}"]
    np.testing.assert_array_equal(M[0], np.asarray(target["placement"]))
    assert set(objects) - triad == {f"/meshcat/{ROBOT}/{n}/{SHAPE}" for n in MANIPULATOR_OBJECTS}
    assert not any(c["path"].startswith(f"/meshcat/{GHOST}") for c in cmds if c["type"] in ("set_object", "set_transform"))


def test_visual_placements_shape_and_fk_route(manip):
    vm = load_visual_model(manip.multibody)
    assert set(vm.names) == MANIPULATOR_OBJECTS and (vm.model.nq, vm.model.nv) == (10, 9)
    P = visual_placements(manip, vm)
    assert P.shape == (H + 1, 5, 4, 4)
    np.testing.assert_allclose(P[:, :, 3], np.tile([0.0, 0.0, 0.0, 1.0], (H + 1, 5, 1)), atol=0)


# ----------------------------------------------------------------------------- (b) HTML export


def test_html_frame_count_and_render_in_chromium(manip, tmp_path):
    page = viz.export_html(manip, tmp_path / "manip.html")
    text = page.read_text()
    assert viz.animation_frame_count(text) == H + 1
    chromium_or_skip()
    url = page.resolve().as_uri()
    dom = run_chromium(url, "--dump-dom", OFFLINE_FLAG).stdout
    m = re.search(r'<pre id="%s"[^>]*>(.*?)</pre>' % STATUS_ID, dom, flags=re.DOTALL)
    assert m, "status element missing from the dumped DOM"
    status = json.loads(m.group(1))
    assert status["loaded"] is True
    # one clip per visual object, each with H+1 position and H+1 quaternion keys
    assert status["frames"] == [[H + 1, H + 1]] * len(MANIPULATOR_OBJECTS)
    assert status["duration"] == pytest.approx(H * DT)

    img = screenshot(url, tmp_path / "manip.png", OFFLINE_FLAG)
    corner = img[-5, 5]
    assert np.abs(corner.astype(int) - BACKGROUND_U8).max() <= 3, f"background {corner} is not the scene's"
    fraction = changed_fraction(img, BACKGROUND_U8)
    assert fraction > 0.03, f"only {fraction:.1%} of the centre differs from the background"
    # the red end-effector sphere is on screen (lit red: R high, G and B low)
    r, g, b = (img[..., i].astype(int) for i in range(3))
    assert np.count_nonzero((r > 120) & (g < 80) & (b < 80)) > 20


# ----------------------------------------------------------------------------- (c) JSON round trip


def test_json_round_trip_keeps_the_replay(manip, tmp_path):
    back = Result.read_json(manip.write_json(tmp_path / "manip.json"))
    assert back.multibody == manip.multibody
    assert back.multibody["root"] == "free_flyer" and (back.multibody["nq"], back.multibody["nv"]) == (10, 9)
    assert back.multibody["urdf"] == str((MODELS / "space_manipulator.urdf").resolve())
    assert back.multibody["urdf_xml"] == (MODELS / "space_manipulator.urdf").read_text()
    np.testing.assert_array_equal(back.configurations, manip.configurations)
    assert scene_of(back) == scene_of(manip)  # identical meshcat commands (up to fresh uuids)

    # The embedded URDF text is enough: the replay survives the file moving away ...
    moved = Result.read_json(tmp_path / "manip.json")
    moved.multibody["urdf"] = str(tmp_path / "gone.urdf")
    assert scene_of(moved) == scene_of(manip)
    # ... and the path alone is enough too.
    path_only = Result.read_json(tmp_path / "manip.json")
    del path_only.multibody["urdf_xml"]
    assert scene_of(path_only) == scene_of(manip)


def test_satellite_json_has_no_multibody():
    from viz_fixtures import synthetic_result

    d = synthetic_result(horizon=3).to_dict()
    back = Result.from_dict(d)
    assert d["multibody"] is None and d["configurations"] is None and not hasattr(back, "multibody")


# ----------------------------------------------------------------------------- bad input


def test_missing_configurations_names_the_parameter(manip, tmp_path):
    bad = Result.read_json(manip.write_json(tmp_path / "m.json"))
    bad.configurations = None
    with pytest.raises(InputError, match=r"^result\.configurations: expected \(H\+1, nq\)"):
        viz.export_html(bad, tmp_path / "bad.html")
    assert not (tmp_path / "bad.html").exists()


@pytest.mark.parametrize("mutate, match", [
    (lambda r: setattr(r, "configurations", r.configurations[:-1]), r"^result\.configurations: expected shape \(H\+1, nq\) = \(21, 10\)"),
    (lambda r: setattr(r, "configurations", r.configurations[:, :7]), r"^result\.configurations: expected shape"),
    (lambda r: r.configurations.__setitem__((3, 8), np.nan), r"^result\.configurations: expected finite"),
    (lambda r: r.multibody.__setitem__("root", "floating"), r"^result\.multibody\.root: expected one of"),
    (lambda r: r.multibody.__setitem__("urdf_xml", "<robot"), r"^result\.multibody: expected a valid URDF"),
    (lambda r: (r.multibody.pop("urdf_xml"), r.multibody.__setitem__("urdf", "/nonexistent.urdf")),
     r"^result\.multibody\.urdf: expected a readable URDF file"),
])
def test_bad_multibody_result_fails_before_any_server(manip, tmp_path, monkeypatch, mutate, match):
    started = []

    class Recording(subprocess.Popen):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            started.append(self)

    monkeypatch.setattr(meshcat_replay.subprocess, "Popen", Recording)
    bad = Result.read_json(manip.write_json(tmp_path / "m.json"))
    mutate(bad)
    with pytest.raises(InputError, match=match):
        viz.replay(bad)
    assert started == []


def test_multibody_result_without_description_falls_back_to_root_attitude(manip, tmp_path):
    old = Result.read_json(manip.write_json(tmp_path / "m.json"))
    old.multibody = None  # a JSON written before Result.multibody existed
    with pytest.warns(UserWarning, match="replaying only the root body's attitude, on the satellite model"):
        text = viz.html.render_html(old)
    assert viz.animation_frame_count(text) == H + 1
    # the satellite's bus carries the root attitude R_k
    bus = keyframes(animation_clips(decode_commands(text))["bus_0"])
    np.testing.assert_allclose(bus[:, :3, :3], manip.rotations, rtol=0, atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        viz.html.render_html(manip)  # a full description: no warning


# ----------------------------------------------------------------------------- (d) live loopback


def test_live_loopback_replay_of_the_full_model(manip):
    vis = viz.replay(manip, timeout_s=10)
    proc = vis.window.server_proc
    try:
        assert proc is not None and proc.poll() is None
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/static/", vis.url())
        assert re.fullmatch(r"tcp://127\.0\.0\.1:\d+", vis.window.zmq_url)
        # ask the server for the scene it holds and decode it
        blobs = re.findall(r'base64,([A-Za-z0-9+/=]+)"', vis.static_html())
        cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
        paths = {c["path"] for c in cmds if c["type"] == "set_object"}
        assert {f"/meshcat/{ROBOT}/{n}/{SHAPE}" for n in MANIPULATOR_OBJECTS} <= paths
        clips = animation_clips(cmds)
        assert set(clips) == MANIPULATOR_OBJECTS
        ee = keyframes(clips["ee_0"])
        np.testing.assert_allclose(ee, visual_placements(manip)[:, 4], rtol=0, atol=1e-12)
    finally:
        vis.close()
    assert proc.wait(timeout=5) is not None


def test_cli_multibody_view_and_html(monkeypatch, tmp_path, capsys):
    """``geoddp multibody NAME --view --html``: the solved multibody result goes to both."""
    from geoddp import cli
    from geoddp.scene import builtin

    full = builtin.scene_spec
    monkeypatch.setattr(builtin, "scene_spec",
                        lambda name, integrator=None, **kw: full(name, integrator, dt=0.2, horizon=10))
    seen = []

    def fake_replay(result, open_browser=False, **kw):
        seen.append(result)

    monkeypatch.setattr(viz, "replay", fake_replay)
    out = tmp_path / "dock.html"
    cli.main(["multibody", "spacecraft_docking", "--quiet", "--view", "--html", str(out)])
    assert f"wrote {out}" in capsys.readouterr().out
    (r,) = seen
    assert r.multibody["root"] == "free_flyer" and r.configurations.shape == (11, 7)
    assert viz.animation_frame_count(out.read_text()) == 11
    clips = animation_clips(decode_commands(out.read_text()))
    assert set(clips) == {"bus_0", "bus_1", "bus_2", "bus_3"}
