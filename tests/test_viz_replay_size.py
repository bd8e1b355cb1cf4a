"""The HTML replay's size: real arms within 5 MB (meshes as compact binary geometry, each embedded
once), and the page still building and animating the model in headless Chromium: the transforms
and triangle counts the viewer holds, read back through JavaScript, are the Result's and the mesh
files'.

Sizes measured with example-robot-data 5.0.0 (`geoddp run ... --html`), before (meshes embedded
as their files' text, once per object) and after: UR5 (ur5_reach) 9.80 -> 2.48 MB, Panda
(tests_panda.panda_scene) 15.02 -> 4.17 MB, Solo12 (solo12_reorient) 4.43 -> 2.23 MB; the
quadrotor (1.01 MB) and the satellite (1.10 MB), which have no mesh files, are the same pages as
before.
"""
from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import example_robot_data  # noqa: F401  (required: the robots' meshes)
import numpy as np
import pinocchio as pin
import pytest

from geoddp import cli, viz
from geoddp import Result
from geoddp.viz.compact_mesh import read_mesh
from geoddp.viz.html import CHUNKS_ID, COMMANDS_ID, chunked, command_bytes, decode_commands, render_html
from geoddp.viz.model import load_visual_model
from geoddp.viz.scene import ROBOT, SHAPE
from tests_panda import panda_scene
from viz_fixtures import OFFLINE_FLAG, chromium_or_skip, run_chromium, synthetic_result
from viz_meshes import drawn_triangles, smooth_path, trajectory_result

MAX_BYTES = 5_000_000


def run_html(argv: list[str], page: Path, capsys) -> tuple[Path, Result]:
    """`geoddp run ... --html page --json`; the page and the Result it replays."""
    res = page.with_suffix(".json")
    assert cli.main(["run", *argv, "--quiet", "--html", str(page), "--json", str(res)]) == 0
    capsys.readouterr()
    return page, Result.read_json(res)


@pytest.fixture(scope="module")
def ur5_page(tmp_path_factory):
    page = tmp_path_factory.mktemp("ur5") / "ur5_reach.html"
    res = page.with_suffix(".json")
    assert cli.main(["run", "ur5_reach", "--quiet", "--html", str(page), "--json", str(res)]) == 0
    return page, Result.read_json(res)


def test_ur5_replay_is_at_most_5_mb(ur5_page):
    page, _ = ur5_page
    size = page.stat().st_size
    print(f"UR5 replay: {size / 1e6:.2f} MB")
    assert size <= MAX_BYTES  # 2.48 MB; 9.80 MB with the DAE files' text embedded


def test_panda_replay_is_at_most_5_mb(tmp_path, capsys):
    page, _ = run_html([str(panda_scene(tmp_path))], tmp_path / "panda.html", capsys)
    size = page.stat().st_size
    print(f"Panda replay: {size / 1e6:.2f} MB")
    assert size <= MAX_BYTES  # 4.17 MB; 15.02 MB before


# ----------------------------------------------------------------------------- each mesh once


def test_chunk_table_round_trip():
    """Commands carrying shared payloads come back byte for byte, each payload stored once; a
    payload carried by one command only stays in it."""
    rng = np.random.default_rng(0)
    a, b, c = (rng.integers(0, 256, n, dtype=np.uint8).tobytes() for n in (3000, 2048, 5000))
    commands = [b"x" + a + b"y" + b + b"z", b"head" + a, b"solo" + c + b"tail", b"nothing"]
    payloads = [[a, b], [a], [c], []]
    chunks, entries = chunked(commands, payloads)
    assert chunks == [a]  # b and c are carried once
    assert entries[2] == commands[2] and entries[3] == commands[3]
    assert entries[0] == [b"x", 0, b"y" + b + b"z"] and entries[1] == [b"head", 0, b""]
    from geoddp.viz.html import _joined

    assert [_joined(e, chunks) for e in entries] == commands


def _legs_urdf(tmp_path: Path) -> Path:
    """Three links drawing the same (fine, > 1 KB of triangles) STL: a leg model's repeated feet."""
    from viz_meshes import write_stl

    u, v = np.meshgrid(np.linspace(0.2, np.pi - 0.2, 10), np.linspace(0, 2 * np.pi, 16, endpoint=False), indexing="ij")
    V = 0.05 * np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v), np.cos(u)], axis=-1).reshape(-1, 3)
    idx = np.arange(V.shape[0]).reshape(10, 16)
    F = [[idx[i, j], idx[i + 1, j], idx[i + 1, (j + 1) % 16]] for i in range(9) for j in range(16)]
    F += [[idx[i, j], idx[i + 1, (j + 1) % 16], idx[i, (j + 1) % 16]] for i in range(9) for j in range(16)]
    write_stl(tmp_path / "foot.stl", V, np.array(F))
    inertial = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>'
    links = "".join(f"""<link name="l{i}">{inertial}<visual><origin xyz="0 0 {0.2 * i}"/>
      <geometry><mesh filename="foot.stl"/></geometry><material name="m{i}"><color rgba="0.9 0.4 0.1 1"/></material>
      </visual></link>""" for i in range(3))
    joints = "".join(f"""<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>
      <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>""" for i in (1, 2))
    urdf = tmp_path / "legs.urdf"
    urdf.write_text(f'<robot name="legs">{links}{joints}</robot>')
    return urdf


def test_a_mesh_drawn_three_times_is_embedded_once(tmp_path):
    """Three objects drawing one file: the page holds its geometry once (a chunk), each object's
    command carries it again once joined, and Chromium builds all three from it."""
    urdf = _legs_urdf(tmp_path)
    model = pin.buildModelFromUrdf(str(urdf))
    result = trajectory_result(urdf, smooth_path(model, np.zeros(2), np.array([1.0, -0.5]), 10))
    text = render_html(result)
    cmds = decode_commands(text)
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    names = [f"/meshcat/{ROBOT}/l{i}_0/{SHAPE}" for i in range(3)]
    payloads = {objects[n]["geometries"][0]["data"]["attributes"]["position"]["array"].data for n in names}
    (payload,) = payloads
    assert len(payload) > 1024
    assert text.count(base64.b64encode(payload).decode()) == 1
    chunks = json.loads(re.search(r'id="%s">(.*?)</script>' % CHUNKS_ID, text).group(1))
    assert chunks == [base64.b64encode(payload).decode()]
    mesh = read_mesh(tmp_path / "foot.stl")
    for n in names:
        np.testing.assert_allclose(drawn_triangles(objects[n]), mesh.positions[mesh.triangles], rtol=0, atol=1e-6)
    # the page's own commands block holds no copy of it
    block = re.search(r'id="%s">(.*?)</script>' % COMMANDS_ID, text).group(1)
    pieces = [e for entry in json.loads(block) for e in (entry if isinstance(entry, list) else [entry])]
    assert sum(isinstance(e, int) for e in pieces) == 3  # one reference per object
    assert not any(payload in base64.b64decode(e) for e in pieces if isinstance(e, str))
    chromium_or_skip()
    page = tmp_path / "legs.html"
    page.write_text(text)
    counts = probe(page, 0.0)["triangles"]
    assert counts == {f"l{i}_0": len(mesh.triangles) for i in range(3)}


def test_a_page_without_meshes_is_written_as_before(tmp_path):
    """The satellite's page: no chunk table, the three script blocks and the loader that hands
    each command's bytes to the viewer as they are (the page written before compact meshes)."""
    text = viz.export_html(synthetic_result(), tmp_path / "sat.html").read_text()
    assert CHUNKS_ID not in text and "joined" not in text
    assert "viewer.handle_command_bytearray(bytes(cmds[i]));" in text
    assert all(isinstance(e, str) for e in json.loads(re.search(r'id="%s">(.*?)</script>' % COMMANDS_ID, text).group(1)))
    assert not any(c["type"] == "set_object" and c["object"]["geometries"]
                   and c["object"]["geometries"][0]["type"] == "BufferGeometry" for c in decode_commands(text))
    assert [len(b) for b in command_bytes(text)] == [len(base64.b64decode(e)) for e in json.loads(
        re.search(r'id="%s">(.*?)</script>' % COMMANDS_ID, text).group(1))]


# ----------------------------------------------------------------------------- in the browser

# Appended to a copy of a page: after the page's own loader ran (and sought to #t=), the local
# transform of every node under /meshcat/robot (the keyframe oMg at that time) and the number of
# triangles of each drawn geometry, as the viewer holds them.
PROBE = """<pre id="geoddp-probe"></pre>
<script>
(function () {
  var out = {transforms: {}, triangles: {}, normals: {}};
  var robot = viewer.scene_tree.find(["meshcat", "robot"]);
  viewer.animator.mixer.update(0);
  for (var name in robot.children) {
    var node = robot.children[name];
    node.object.updateMatrix();
    out.transforms[name] = node.object.matrix.toArray();
    var obj = node.children["shape"].children["<object>"].object;
    var g = obj.geometry;
    out.triangles[name] = (g.index ? g.index.count : g.attributes.position.count) / 3;
    out.normals[name] = g.attributes.normal ? g.attributes.normal.count === g.attributes.position.count : false;
  }
  document.getElementById("geoddp-probe").textContent = JSON.stringify(out);
})();
</script>
</body>"""


def probe(page: Path, t: float) -> dict:
    """What the viewer of ``page`` holds at time ``t`` (s), read back through JavaScript."""
    text = page.read_text()
    probed = page.with_name(page.stem + "_probe.html")
    probed.write_text(text.replace("</body>", PROBE, 1))
    dom = run_chromium(probed.resolve().as_uri() + f"#t={t}", "--dump-dom", OFFLINE_FLAG).stdout
    m = re.search(r'<pre id="geoddp-probe">(.*?)</pre>', dom, flags=re.DOTALL)
    assert m and m.group(1), "the probe did not run (the page's script failed?)"
    return json.loads(m.group(1))


def test_ur5_replay_builds_and_animates_the_arm_in_chromium(ur5_page):
    """In headless Chromium, the UR5 page's viewer holds every link's mesh with as many triangles as
    the file has (normals computed or sent for each), and at t = 0 and t = t_f each link's
    transform is its placement oMg(q_0), oMg(q_H) from forward kinematics (float32 precision):
    the arm is built from the compact meshes and moves as the Result says."""
    chromium_or_skip()
    page, result = ur5_page
    visual = load_visual_model(result.multibody)
    data, gdata = visual.model.createData(), pin.GeometryData(visual.geometry)
    tf = float(result.times[-1])
    seen = {}
    for k, t in ((0, 0.0), (result.horizon, tf)):
        held = probe(page, t)
        pin.forwardKinematics(visual.model, data, result.configurations[k])
        pin.updateGeometryPlacements(visual.model, data, visual.geometry, gdata)
        assert set(held["transforms"]) == set(visual.names)
        for i, name in enumerate(visual.names):
            M = np.asarray(held["transforms"][name]).reshape(4, 4).T
            np.testing.assert_allclose(M, gdata.oMg[i].homogeneous, rtol=0, atol=2e-6)
            seen.setdefault(name, []).append(M)
        for i, obj in enumerate(visual.geometry.geometryObjects):
            mesh = read_mesh(obj.meshPath)
            assert held["triangles"][visual.names[i]] == len(mesh.triangles)
            assert held["normals"][visual.names[i]] is True
    moved = max(np.abs(a - b).max() for a, b in seen.values())
    assert moved > 0.1  # the links moved between the first and the last frame
