"""Mesh files as compact binary geometry (geoddp.viz.compact_mesh): a COLLADA file read as meshcat's
viewer draws it (node transforms, polylist splitting, materials as three.js's ColladaLoader builds
them, up axis and unit ignored as meshcat ignores them), binary STL, the quantisation, the files left
to meshcat, and real example-robot-data meshes against Pinocchio's own loader (coal)."""
from __future__ import annotations

from pathlib import Path

import example_robot_data  # noqa: F401  (required: the robot meshes)
import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial import cKDTree

import geoddp.viz  # noqa: F401  (first: silences meshcat's import warning)
from geoddp.viz.compact_mesh import CompactMeshObject, MeshData, flat_shaded, quantise, read_dae, read_mesh, read_stl
from geoddp.viz.html import decode_commands, render_html
from geoddp.viz.model import example_robot_data_dir
from geoddp.viz.scene import ROBOT, SHAPE
from viz_meshes import CUBE_F, CUBE_V, drawn_triangles, quantisation_step, smooth_path, trajectory_result, write_stl

# Two geometries: a polylist (a quad, a pentagon and a triangle, with normals, two materials) under
# a chain of transforms (translate, rotate, scale, then a child node with a matrix), and a
# triangle list with no material and no normals; a <lines> primitive the viewer does not draw. The
# file says Y_UP in centimetres: meshcat ignores both (its merge reads the scene's stale matrix).
DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Y_UP</up_axis></asset>
  <library_effects>
    <effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
      <emission><color>0.1 0 0 1</color></emission>
      <diffuse><color>0.8 0.2 0.1 1</color></diffuse>
      <specular><color>0.5 0.5 0.5 1</color></specular>
      <shininess><float>12</float></shininess>
      <transparent opaque="A_ONE"><color>1 1 1 0.5</color></transparent>
      <transparency><float>1</float></transparency>
    </phong></technique></profile_COMMON></effect>
    <effect id="grey-fx"><profile_COMMON><technique sid="common"><lambert>
      <diffuse><color>0.3 0.3 0.3 1</color></diffuse>
    </lambert></technique>
    <extra><technique profile="GOOGLEEARTH"><double_sided>1</double_sided></technique></extra>
    </profile_COMMON></effect>
  </library_effects>
  <library_materials>
    <material id="red-mat"><instance_effect url="#red-fx"/></material>
    <material id="grey-mat"><instance_effect url="#grey-fx"/></material>
  </library_materials>
  <library_geometries>
    <geometry id="poly"><mesh>
      <source id="poly-pos"><float_array id="poly-pos-a" count="30">
        0 0 0  1 0 0  1 1 0  0 1 0   2 0 0  3 0 0  3 1 0  2.5 2 0  2 1 0   0 0 1</float_array>
        <technique_common><accessor source="#poly-pos-a" count="10" stride="3"/></technique_common></source>
      <source id="poly-nrm"><float_array id="poly-nrm-a" count="6">0 0 1  0 -1 0</float_array>
        <technique_common><accessor source="#poly-nrm-a" count="2" stride="3"/></technique_common></source>
      <vertices id="poly-v"><input semantic="POSITION" source="#poly-pos"/></vertices>
      <polylist material="m-red" count="2">
        <input semantic="VERTEX" source="#poly-v" offset="0"/><input semantic="NORMAL" source="#poly-nrm" offset="1"/>
        <vcount>4 5</vcount><p>0 0 1 0 2 0 3 0  4 0 5 0 6 0 7 0 8 0</p>
      </polylist>
      <polylist material="m-grey" count="1">
        <input semantic="VERTEX" source="#poly-v" offset="0"/><input semantic="NORMAL" source="#poly-nrm" offset="1"/>
        <vcount>3</vcount><p>0 1 1 1 9 1</p>
      </polylist>
      <lines count="1"><input semantic="VERTEX" source="#poly-v" offset="0"/><p>0 1</p></lines>
    </mesh></geometry>
    <geometry id="tri"><mesh>
      <source id="tri-pos"><float_array id="tri-pos-a" count="9">0 0 0  0 2 0  0 0 2</float_array>
        <technique_common><accessor source="#tri-pos-a" count="3" stride="3"/></technique_common></source>
      <vertices id="tri-v"><input semantic="POSITION" source="#tri-pos"/></vertices>
      <triangles count="1"><input semantic="VERTEX" source="#tri-v" offset="0"/><p>0 1 2</p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="scene">
    <node id="a"><translate>1 2 3</translate><rotate>0 0 1 90</rotate><scale>2 2 2</scale>
      <instance_geometry url="#poly"><bind_material><technique_common>
        <instance_material symbol="m-red" target="#red-mat"/><instance_material symbol="m-grey" target="#grey-mat"/>
      </technique_common></bind_material></instance_geometry>
      <node id="b"><matrix>1 0 0 10  0 1 0 0  0 0 1 0  0 0 0 1</matrix><instance_geometry url="#tri"/></node>
    </node>
    <node id="camera"><matrix>1 0 0 0 0 1 0 0 0 0 1 5 0 0 0 1</matrix></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""


def _transform(p, T):
    p = np.asarray(p, dtype=float)
    return p @ T[:3, :3].T + T[:3, 3]


def test_collada_as_the_viewer_draws_it(tmp_path):
    path = tmp_path / "part.dae"
    path.write_text(DAE)
    mesh = read_dae(path)
    # node a: translate (1, 2, 3) * rotate 90 deg about z * scale 2; node b below it: x + 10
    A = np.eye(4)
    A[:3, 3] = [1, 2, 3]
    A[:3, :3] = 2.0 * pin.exp3(np.array([0.0, 0.0, np.pi / 2]))
    B = A.copy()
    B[:3, 3] = _transform([10.0, 0.0, 0.0], A)
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [3, 1, 0], [2.5, 2, 0],
                    [2, 1, 0], [0, 0, 1]], dtype=float)
    # ColladaLoader's split: the quad (0, 1, 3), (1, 2, 3); the pentagon a fan from its first corner
    red = [[0, 1, 3], [1, 2, 3], [4, 5, 6], [4, 6, 7], [4, 7, 8]]
    expected = np.vstack([_transform(pos[red].reshape(-1, 3), A), _transform(pos[[0, 1, 9]], A),
                          _transform([[0, 0, 0], [0, 2, 0], [0, 0, 2]], B)]).reshape(-1, 3, 3)
    np.testing.assert_allclose(mesh.positions[mesh.triangles], expected, rtol=0, atol=1e-12)
    assert mesh.groups == [(0, 5, 0), (5, 1, 1), (6, 1, 2)]  # the lines are not drawn
    # normals: the file's, rotated by the node's rotation (and renormalised); the second geometry
    # has none: its face normal, (0, 2, 0) x (0, 0, 2) along x, turned 90 deg about z
    N = mesh.normals[mesh.triangles]
    np.testing.assert_allclose(N[0], [[0, 0, 1]] * 3, atol=1e-12)
    np.testing.assert_allclose(N[5], [[1, 0, 0]] * 3, atol=1e-12)  # (0, -1, 0) turned 90 deg about z
    np.testing.assert_allclose(N[6], [[0, 1, 0]] * 3, atol=1e-12)
    # ColladaLoader's materials: colours as three.js's getHex truncates them (0.8 * 255 = 204,
    # 0.1 * 255 = 25.5 -> 25), opacity = alpha * transparency (A_ONE), double_sided from the
    # profile's <extra>; a primitive naming no material: three.js's default MeshPhongMaterial
    red_m, grey_m, default = mesh.materials
    assert red_m == {"type": "MeshPhongMaterial", "color": 0xCC3319, "specular": 0x7F7F7F, "shininess": 12.0,
                     "emissive": 0x190000, "opacity": 0.5, "transparent": True, "side": 0}
    assert grey_m == {"type": "MeshLambertMaterial", "color": 0x4C4C4C, "side": 2}
    assert default == {"type": "MeshPhongMaterial"}


def test_binary_stl_and_what_is_left_to_meshcat(tmp_path):
    stl = write_stl(tmp_path / "cube.stl")
    mesh = read_stl(stl)
    np.testing.assert_array_equal(mesh.positions[mesh.triangles], CUBE_V[CUBE_F])
    assert flat_shaded(mesh) and mesh.groups == [(0, 12, 0)] and mesh.materials == []
    (tmp_path / "ascii.stl").write_text(ASCII_STL)
    textured = DAE.replace('<diffuse><color>0.8 0.2 0.1 1</color></diffuse>',
                           '<diffuse><texture texture="img-sampler" texcoord="UV"/></diffuse>')
    (tmp_path / "textured.dae").write_text(textured)
    (tmp_path / "part.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "garbage.dae").write_text(DAE.replace("0 0 0  1 0 0  1 1 0", "0 0 zero  1 0 0  1 1 0"))
    (tmp_path / "nan.dae").write_text(DAE.replace("0 0 0  1 0 0  1 1 0", "0 0 nan  1 0 0  1 1 0"))
    (tmp_path / "short.dae").write_text(DAE.replace("<vcount>4 5</vcount>", "<vcount>4 7</vcount>"))
    (tmp_path / "not_xml.dae").write_bytes(b"\x00\xff<COLLADA")
    for name in ("ascii.stl", "textured.dae", "part.obj", "garbage.dae", "nan.dae", "short.dae", "not_xml.dae"):
        assert read_mesh(tmp_path / name) is None, name  # left to meshcat, as before


def test_quantisation(tmp_path):
    """Flat-shaded: separate triangles, no normals (the viewer computes the face normals); smooth:
    indexed, with int8 normals; positions within half a step of the file's, the bounding sphere
    around every normalised position."""
    # a smooth sphere: normals are the positions' directions, shared by the triangles around a vertex
    u, v = np.meshgrid(np.linspace(0.1, np.pi - 0.1, 12), np.linspace(0, 2 * np.pi, 24, endpoint=False), indexing="ij")
    V = 0.3 * np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v), np.cos(u)], axis=-1).reshape(-1, 3) + [1, 2, 3]
    idx = np.arange(V.shape[0]).reshape(12, 24)
    tris = [[idx[i, j], idx[i + 1, j], idx[i + 1, (j + 1) % 24]] for i in range(11) for j in range(24)]
    tris += [[idx[i, j], idx[i + 1, (j + 1) % 24], idx[i, (j + 1) % 24]] for i in range(11) for j in range(24)]
    tris = np.array(tris)
    smooth = MeshData(V, (V - [1, 2, 3]) / 0.3, tris, [(0, len(tris), 0)], [])
    assert not flat_shaded(smooth)
    q = quantise(smooth)
    assert q["normal"] is not None and q["index"] is not None and q["index"].dtype == np.uint16
    assert len(q["position"]) == len(V)  # each vertex once: its triangles share position and normal
    step = q["matrix"][0, 0] / 65535.0
    drawn = (q["position"] / 65535.0) @ q["matrix"][:3, :3].T + q["matrix"][:3, 3]
    assert np.abs(drawn[q["index"]] - V[tris]).max() <= 0.5 * step + 1e-15
    n = q["normal"][q["index"]].astype(float) / 127.0  # each corner's, as the viewer normalises int8
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(n * smooth.normals[tris], axis=-1), -1, 1))).max() < 0.7
    flat = MeshData(V[tris].reshape(-1, 3), None, np.arange(3 * len(tris)).reshape(-1, 3), [(0, len(tris), 0)], [])
    qf = quantise(flat)
    assert qf["normal"] is None and qf["index"] is None and len(qf["position"]) == 3 * len(tris)
    element = CompactMeshObject(smooth, {"type": "MeshLambertMaterial", "color": 0x123456})
    lowered = element.lower()["object"]
    sphere = lowered["geometries"][0]["data"]["boundingSphere"]
    unit = q["position"] / 65535.0
    assert np.linalg.norm(unit - sphere["center"], axis=1).max() <= sphere["radius"] + 1e-12
    assert sphere["radius"] < 1.0  # not the raw uint16 values' sphere
    np.testing.assert_allclose(drawn_triangles(lowered), V[tris], rtol=0, atol=0.5 * quantisation_step(lowered) + 1e-15)
    assert lowered["materials"][0]["color"] == 0x123456


ASCII_STL = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid x\n"


def test_a_file_left_to_meshcat_is_drawn_as_before(tmp_path):
    """A textured DAE keeps Pinocchio's DAE element (the file's text, its textures inlined); an
    ASCII STL meshcat's STL geometry (the file's bytes)."""
    textured = Path(example_robot_data_dir()) / "example-robot-data/robots/anymal_c_simple_description/meshes/battery.dae"
    (tmp_path / "part.stl").write_text(ASCII_STL)
    urdf = tmp_path / "two.urdf"
    inertial = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>'
    urdf.write_text(f"""<robot name="two"><link name="base">{inertial}
      <visual><geometry><mesh filename="{textured}"/></geometry></visual></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="l"/><axis xyz="0 0 1"/>
      <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <link name="l">{inertial}<visual><geometry><mesh filename="part.stl"/></geometry></visual></link></robot>""")
    model = pin.buildModelFromUrdf(str(urdf))
    result = trajectory_result(urdf, smooth_path(model, np.zeros(1), np.ones(1), 4))
    objects = {c["path"]: c["object"] for c in decode_commands(render_html(result)) if c["type"] == "set_object"}
    inner = objects[f"/meshcat/{ROBOT}/base_0/{SHAPE}"]["object"]
    assert inner["type"] == "_meshfile_object" and inner["format"] == "dae" and inner["data"] == textured.read_text()
    (geom,) = objects[f"/meshcat/{ROBOT}/l_0/{SHAPE}"]["geometries"]
    assert geom["type"] == "_meshfile" and geom["format"] == "stl" and geom["data"].data == ASCII_STL.encode()


ROBOT_MESHES = [  # example-robot-data files of every kind the reader covers (and one it leaves)
    "ur_description/meshes/ur5/visual/upperarm.dae",  # several materials per geometry, smooth
    "panda_description/meshes/visual/link7.dae",  # flat-shaded, rotated nodes
    "icub_description/meshes/upmc/collision/icub_simple_collision_r_shoulder_2.dae",  # polylist, Y_UP
    "romeo_description/meshes/V1/visual/LWristYaw.dae",  # translate / rotate / scale nodes
    "baxter_description/meshes/electric_gripper/fingers/extended_narrow.DAE",  # lines among the triangles
    "iris_description/meshes/iris_prop_ccw.dae",  # constant shading
    "solo_description/meshes/stl/with_foot/solo_foot.stl",  # binary STL
]


@pytest.mark.parametrize("rel", ROBOT_MESHES)
def test_robot_meshes_match_pinocchios_loader(rel):
    """Each file's triangles as read here are the ones Pinocchio's loader (coal, through assimp)
    builds from it: every vertex within 1e-6 of the mesh size of one of coal's (assimp reads float32)
    and back, as many triangles up to zero-area ones (coal drops some, the viewer draws nothing of
    them)."""
    import coal

    path = Path(example_robot_data_dir()) / "example-robot-data" / "robots" / rel
    mesh = read_mesh(path)
    assert mesh is not None
    bvh = coal.MeshLoader().load(str(path), np.ones(3))
    V = np.asarray(bvh.vertices())
    P = mesh.positions[mesh.triangles].reshape(-1, 3)
    scale = float(np.max(V.max(axis=0) - V.min(axis=0)))
    assert cKDTree(V).query(P)[0].max() <= 1e-6 * scale and cKDTree(P).query(V)[0].max() <= 1e-6 * scale
    tri = mesh.positions[mesh.triangles]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert np.count_nonzero(area > 0) <= bvh.num_tris <= len(mesh.triangles)  # coal drops some zero-area ones


def test_textured_robot_mesh_is_left_to_meshcat():
    path = Path(example_robot_data_dir()) / "example-robot-data/robots/anymal_c_simple_description/meshes/battery.dae"
    assert read_mesh(path) is None
