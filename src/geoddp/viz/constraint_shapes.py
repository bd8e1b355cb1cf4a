"""The constraints of a solve drawn in the replay: keep-out cones, obstacles and terminal poses.

A constrained result (:func:`geoddp.constraints.solve_constrained`) carries its constraints'
definitions in ``result.extra["constraints"]["items"]``. :func:`constraint_shapes` reads them
into plain shapes (world coordinates, metres), and :func:`draw_constraints` draws them as meshcat
objects under ``vis["constraints"]``, one node ``constraints/<i>_<name>`` per constraint i:

* ``pointing_keep_out``: the keep-out cone, a translucent red cone with its apex at the frame's
  origin (the satellite's centre of mass for its body), its axis along the world direction d and
  its half-angle the constraint's ``min_angle_deg``; a cone of half-angle above 90 degrees is
  drawn as its boundary (the cone of 180 - alpha around -d). Its apex follows the frame: one
  keyframe per node when the frame's origin moves.
* ``frame_sphere_keep_out``: the sphere (centre, radius), translucent red.
* ``frame_halfspace``: a square patch of the plane n.p = offset (a thin translucent red box whose
  z axis is n), centred at the point of the plane nearest the centre of the drawn trajectory and
  as wide as 1.5 times the trajectory's box.
* terminal ``frame_placement``: the target pose as a triad (as the frame-target triads).

``joint_limits`` and ``state`` constraints have no shape in the world and are not drawn.
Reads Results only.
"""
from __future__ import annotations

from typing import Any

import meshcat
import meshcat.geometry as g
import numpy as np

from .model import VisualModel, frame_positions

__all__ = ["CONSTRAINTS", "KEEP_OUT_COLOR", "KEEP_OUT_OPACITY", "constraint_shapes", "draw_constraints",
           "cone_axis_rotation"]

#: Scene-tree name of the group holding the constraints' shapes.
CONSTRAINTS = "constraints"
#: Colour and opacity of every keep-out shape (cone, sphere, half-space boundary).
KEEP_OUT_COLOR = 0xE03030
KEEP_OUT_OPACITY = 0.35
# A cone's slant length, as a fraction of the largest side of the trajectory's box (at least 0.3 m).
CONE_LENGTH = 0.6
# A half-space patch's side, as a multiple of the largest side of the trajectory's box (at least 0.5 m).
PLANE_SIZE = 1.5


def _frame_or_root(definition: dict[str, Any]) -> str:
    frame = definition.get("frame")
    return "root" if frame is None else str(frame)


def constraint_shapes(result: Any) -> list[dict[str, Any]]:
    """The drawable constraints of ``result`` (none without ``extra["constraints"]``), in the
    report's order: dicts with ``index``, ``name``, ``kind`` ("cone" | "sphere" | "plane" |
    "pose") and the world data of that kind: a cone ``frame``, ``direction`` (unit d),
    ``half_angle_deg``; a sphere ``centre``, ``radius``; a plane ``normal`` (unit),
    ``offset``; a pose ``frame``, ``placement`` (4, 4)."""
    report = (getattr(result, "extra", None) or {}).get("constraints") or {}
    shapes = []
    for i, item in enumerate(report.get("items", [])):
        d = dict(item.get("definition", {}))
        kind = item.get("type")
        base = {"index": i, "name": str(item.get("name", kind))}
        if kind == "pointing_keep_out":
            u = np.asarray(d["world_direction"], dtype=float)
            shapes.append(base | {"kind": "cone", "frame": _frame_or_root(d), "direction": u / np.linalg.norm(u),
                                  "half_angle_deg": float(d["min_angle_deg"])})
        elif kind == "frame_sphere_keep_out":
            shapes.append(base | {"kind": "sphere", "centre": np.asarray(d["centre"], dtype=float),
                                  "radius": float(d["radius"])})
        elif kind == "frame_halfspace":
            shapes.append(base | {"kind": "plane", "normal": np.asarray(d["normal"], dtype=float),
                                  "offset": float(d["offset"])})
        elif kind == "frame_placement" and item.get("where") == "terminal":
            shapes.append(base | {"kind": "pose", "frame": str(d["frame"]),
                                  "placement": np.asarray(d["placement"], dtype=float)})
    return shapes


def cone_axis_rotation(axis: np.ndarray) -> np.ndarray:
    """(3, 3) a rotation taking three.js's cylinder axis +y onto the unit vector ``axis``."""
    y = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    return np.column_stack([x, y, z])


def _material() -> g.MeshLambertMaterial:
    return g.MeshLambertMaterial(color=KEEP_OUT_COLOR, opacity=KEEP_OUT_OPACITY, transparent=True)


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def draw_constraints(vis: meshcat.Visualizer, shapes: list[dict[str, Any]], visual: VisualModel, Q: np.ndarray,
                     lower: np.ndarray, upper: np.ndarray, draw_triad: Any) -> tuple[list[np.ndarray], dict]:
    """Draw ``shapes`` (:func:`constraint_shapes`) under ``vis`` (the ``constraints`` group).

    Args:
        vis: the group's visualizer node.
        shapes: the constraints to draw.
        visual, Q: the replayed model and its configurations (H+1, nq) (a cone's apex follows its
            frame's origin).
        lower, upper: the box (3,) of the drawn trajectory, metres (sizes of cones and planes).
        draw_triad: ``f(vis, placement (4, 4))`` that draws a pose triad.

    Returns:
        (points to keep in the camera's view, {node: (H+1, 4, 4) keyframes} of the cones whose
        apex moves).
    """
    size = float(np.max(np.asarray(upper) - np.asarray(lower)))
    centre = 0.5 * (np.asarray(lower) + np.asarray(upper))
    points: list[np.ndarray] = []
    moving: dict = {}
    for s in shapes:
        node = vis[f"{s['index']}_{s['name']}".replace("/", "_")]
        if s["kind"] == "cone":
            alpha = np.radians(s["half_angle_deg"])
            slant = max(0.3, CONE_LENGTH * size)
            axis = s["direction"] if np.cos(alpha) >= 0.0 else -s["direction"]
            height = max(abs(slant * np.cos(alpha)), 1e-3 * slant)
            radius = slant * np.sin(alpha)
            # three.js: the cone's tip (radiusTop = 0) at +y h/2, its base at -y h/2: the tip goes to
            # the apex and the base out along the axis, so +y maps onto -axis.
            R = cone_axis_rotation(-axis)
            node.set_object(g.Cylinder(height, radiusTop=0.0, radiusBottom=radius), _material())
            apex = frame_positions(visual, Q, s["frame"])
            offset = 0.5 * height * axis
            keys = np.array([_pose(R, a + offset) for a in apex])
            node.set_transform(keys[0])
            if np.ptp(apex, axis=0).max() > 1e-9:
                moving[node] = keys
            rim = radius * np.vstack([R[:, 0], -R[:, 0], R[:, 2], -R[:, 2]])
            points.extend([apex, (apex[:1] + height * axis) + rim])
        elif s["kind"] == "sphere":
            node.set_object(g.Sphere(s["radius"]), _material())
            node.set_transform(_pose(np.eye(3), s["centre"]))
            points.append(s["centre"] + s["radius"] * np.vstack([np.eye(3), -np.eye(3)]))
        elif s["kind"] == "plane":
            n = s["normal"] / np.linalg.norm(s["normal"])
            side = max(0.5, PLANE_SIZE * size)
            p0 = centre - (centre @ n - s["offset"]) * n  # the plane's point nearest the trajectory
            Rz = cone_axis_rotation(n)[:, [2, 0, 1]]  # columns (x, y, z) with z = n
            node.set_object(g.Box([side, side, 1e-3 * side]), _material())
            node.set_transform(_pose(Rz, p0))
        elif s["kind"] == "pose":
            draw_triad(node, s["placement"])
            points.append(s["placement"][:3, 3][None])
    return points, moving
