"""A small arm with mesh visuals (STL and OBJ files written here), for the mesh replay tests.

Kept out of conftest.py on purpose: the main branch owns that file.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pinocchio as pin

from geoddp import Result
from geoddp.solver import STATUS_CONVERGED_COST
from geoddp.solver.result import MultibodyResult

# A unit cube [-0.5, 0.5]^3: 8 vertices, 12 triangles (outward normals).
CUBE_V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
CUBE_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def write_stl(path: Path, vertices: np.ndarray = CUBE_V, faces: np.ndarray = CUBE_F) -> Path:
    """A binary STL file of the triangles ``vertices[faces]``."""
    out = bytearray(b"geoddp test mesh".ljust(80, b" "))
    out += struct.pack("<I", len(faces))
    for f in faces:
        a, b, c = vertices[f]
        n = np.cross(b - a, c - a)
        n = n / np.linalg.norm(n)
        out += struct.pack("<12fH", *n, *a, *b, *c, 0)
    path.write_bytes(bytes(out))
    return path


def write_obj(path: Path, vertices: np.ndarray = CUBE_V, faces: np.ndarray = CUBE_F) -> Path:
    """A Wavefront OBJ file of the same triangles (1-based indices)."""
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


# Two links on revolute joints about z; each carries a scaled mesh visual placed off its frame, and a
# box collision. The base's STL is named by a package:// URI, the arm's OBJ by a path relative to the
# URDF's directory.
URDF = """<?xml version="1.0"?>
<robot name="mesh_arm">
  <material name="orange"><color rgba="1.0 0.5 0.0 1.0"/></material>
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual>
      <origin xyz="0 0 0.1" rpy="0 0 0.3"/>
      <geometry><mesh filename="package://mesh_pkg/meshes/base.stl" scale="0.4 0.4 0.2"/></geometry>
      <material name="orange"/>
    </visual>
    <collision><geometry><box size="0.4 0.4 0.2"/></geometry></collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/>
  </joint>
  <link name="arm">
    <inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual>
      <origin xyz="0.5 0 0" rpy="0.2 0 0"/>
      <geometry><mesh filename="../meshes/arm.obj" scale="1.0 0.1 0.1"/></geometry>
      <material name="teal"><color rgba="0.0 0.6 0.6 1.0"/></material>
    </visual>
    <collision><origin xyz="0.5 0 0"/><geometry><box size="1.0 0.1 0.1"/></geometry></collision>
  </link>
  <joint name="wrist" type="revolute">
    <parent link="arm"/><child link="hand"/><origin xyz="1.0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/>
  </joint>
  <link name="hand">
    <inertial><mass value="0.5"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual>
      <geometry><mesh filename="package://mesh_pkg/meshes/base.stl" scale="0.1 0.1 0.1"/></geometry>
    </visual>
  </link>
  <joint name="tool_joint" type="fixed">
    <parent link="hand"/><child link="tool"/><origin xyz="0.1 0 0"/>
  </joint>
  <link name="tool"/>
</robot>
"""


def mesh_arm(root: Path) -> Path:
    """Write the package ``root/mesh_pkg`` (urdf/mesh_arm.urdf, meshes/base.stl, meshes/arm.obj);
    return the URDF path."""
    pkg = root / "mesh_pkg"
    (pkg / "urdf").mkdir(parents=True, exist_ok=True)
    (pkg / "meshes").mkdir(exist_ok=True)
    write_stl(pkg / "meshes" / "base.stl")
    write_obj(pkg / "meshes" / "arm.obj")
    urdf = pkg / "urdf" / "mesh_arm.urdf"
    urdf.write_text(URDF)
    return urdf


def trajectory_result(urdf: Path, Q: np.ndarray, dt: float = 0.05, root: str = "fixed",
                      extra: dict | None = None, **description) -> Result:
    """A Result replaying configurations ``Q`` (H+1, nq) of the model at ``urdf`` (no solver:
    a Result as the viewer reads it, the solver fields zero)."""
    model = pin.buildModelFromUrdf(str(urdf))
    H = Q.shape[0] - 1
    return MultibodyResult(
        times=dt * np.arange(H + 1), rotations=np.tile(np.eye(3), (H + 1, 1, 1)),
        angular_velocities=np.zeros((H + 1, 3)), controls=np.zeros((H, model.nv)),
        feedforward=np.zeros((H, model.nv)), feedback=np.zeros((H, model.nv, 2 * model.nv)),
        target_rotation=np.eye(3), target_angular_velocity=np.zeros(3), cost=0.0, iterations=0,
        converged=True, status=STATUS_CONVERGED_COST, message="replay fixture", cost_history=np.zeros(1),
        grad_norm_history=np.zeros(1), reg_history=np.zeros(0), step_history=np.zeros(0),
        expansion_history=[], solve_time_s=0.0, timings={}, expansion="first", integrator="euler", dt=dt,
        configurations=np.asarray(Q, dtype=float), velocities=np.zeros((H + 1, model.nv)),
        multibody={"urdf": str(urdf), "root": root, "nq": model.nq, "nv": model.nv, **description},
        extra=dict(extra or {}),
    )


def smooth_path(model: pin.Model, q0: np.ndarray, q1: np.ndarray, horizon: int) -> np.ndarray:
    """(horizon+1, nq) configurations from q0 to q1 along a smoothstep in time."""
    s = np.linspace(0.0, 1.0, horizon + 1)
    s = 3 * s**2 - 2 * s**3
    return np.array([pin.interpolate(model, q0, q1, si) for si in s])


def drawn_triangles(obj: dict) -> np.ndarray:
    """(t, 3, 3) triangles a compact mesh ``set_object`` draws, in the mesh file's coordinates
    (before the URDF scale), decoded here from the command alone: the uint16 positions normalised
    to [0, 1] (three.js ``normalized``), mapped by the object's own matrix (column-major), through
    the index when there is one."""
    (geom,) = obj["geometries"]
    assert geom["type"] == "BufferGeometry", geom["type"]
    data = geom["data"]
    pos = data["attributes"]["position"]
    assert pos["type"] == "Uint16Array" and pos["normalized"] is True and pos["itemSize"] == 3
    P = np.frombuffer(pos["array"].data, dtype="<u2").reshape(-1, 3) / 65535.0
    M = np.asarray(obj["object"]["matrix"], dtype=float).reshape(4, 4).T
    P = P @ M[:3, :3].T + M[:3, 3]
    if "index" in data:
        dtype = {"Uint16Array": "<u2", "Uint32Array": "<u4"}[data["index"]["type"]]
        P = P[np.frombuffer(data["index"]["array"].data, dtype=dtype)]
    return P.reshape(-1, 3, 3)


def quantisation_step(obj: dict) -> float:
    """The position step (file units) of a compact mesh: its uniform scale / 65535."""
    M = np.asarray(obj["object"]["matrix"], dtype=float).reshape(4, 4).T
    return float(M[0, 0]) / 65535.0
