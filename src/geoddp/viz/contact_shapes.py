"""A legged robot's ground, contact points and force arrows in the replay.

:func:`draw_contacts` draws, under ``vis["contacts"]`` (:data:`CONTACTS`), from the
:class:`geoddp.problem.legged_forces.ContactForces` of a trajectory:

* ``ground``: the flat ground, a thin grey box whose top face is the plane z = ``ground_height``
  (the mean height of the feet on the ground at the first frame), as wide as the feet's path plus
  0.5 m on every side;
* ``points/<foot>``: a small sphere (radius ``POINT_RADIUS``) at each foot on the ground, placed at
  the foot's position and shown only at the frames where that foot is on the ground;
  points and arrows are drawn over the model (no depth test), so the leg does not hide them;
* ``forces/<foot>/shaft`` and ``/head``: the force of the ground on the foot at contact node k as an
  arrow from the foot along the force, ``force_scale`` m per N long (the shaft's length; the head,
  a cone ``HEAD_LENGTH`` long, sits beyond it), shown at frame k when the foot carries a force;
* ``impulses/<foot>/shaft`` and ``/head``: the same for the impulse of a foot that touches down at
  an impulse node, ``impulse_scale`` m per N s, in another colour.

The shaft is a cylinder of unit length along three.js's +y: its keyframe k carries the position
``p_k + (L_k / 2) d_k``, the rotation taking +y onto the unit force direction d_k and the scale
(1, L_k, 1), L_k = scale |f_k|; hidden arrows keep their last pose with ``visible`` false. The
last frame (the terminal state, with no node dynamics) has no arrows.
"""
from __future__ import annotations

from dataclasses import dataclass

import meshcat
import meshcat.geometry as g
import numpy as np

from ..problem.legged_forces import ContactForces
from ..validate import InputError, positive_float
from .constraint_shapes import cone_axis_rotation

__all__ = ["CONTACTS", "ContactScene", "arrow_keys", "draw_contacts"]

#: Scene-tree name of the group holding the ground, contact points and arrows.
CONTACTS = "contacts"
GROUND_COLOR = 0x9A9A9A
GROUND_THICKNESS = 0.01  # m
GROUND_MARGIN = 0.5  # m beyond the feet's path on every side
POINT_COLOR = 0xFFD020
POINT_RADIUS = 0.02  # m
FORCE_COLOR = 0x20C0FF
IMPULSE_COLOR = 0xFF6020
SHAFT_RADIUS = 0.008  # m
HEAD_LENGTH = 0.03  # m
HEAD_RADIUS = 0.015  # m
_HIDDEN = 1e-9  # below this length (m) an arrow is not shown


@dataclass
class ContactScene:
    """What the replay draws of a legged trajectory (see the module docstring).

    Attributes:
        forces: the trajectory's :class:`~geoddp.problem.legged_forces.ContactForces`.
        force_scale: arrow length per newton, m/N (1e-3: 1 mm per N).
        impulse_scale: arrow length per newton second of an impulse, m/(N s).
        ground: draw the ground plane.
    """

    forces: ContactForces
    force_scale: float = 1e-3
    impulse_scale: float = 1.0
    ground: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.forces, ContactForces):
            raise InputError("contacts.forces", f"expected a ContactForces, got {type(self.forces).__name__}")
        self.force_scale = positive_float(self.force_scale, "force_scale")
        self.impulse_scale = positive_float(self.impulse_scale, "impulse_scale")

    @property
    def ground_height(self) -> float:
        """z (m) of the ground: the mean height of the feet on the ground at the first frame
        (0 with no foot down)."""
        c = self.forces
        down = c.on_ground[0]
        return float(c.positions[0, down, 2].mean()) if down.any() else 0.0

    def arrows(self, impulses: bool) -> tuple[np.ndarray, np.ndarray]:
        """(tails (H + 1, nf, 3), vectors (H + 1, nf, 3)) of the force (``impulses``: impulse)
        arrows at every frame, m: zero vectors where none is drawn (the last frame included)."""
        c = self.forces
        H = c.horizon
        scale = self.impulse_scale if impulses else self.force_scale
        which = c.active & (c.impulse[:, None] if impulses else ~c.impulse[:, None])
        vec = np.zeros((H + 1, len(c.feet), 3))
        vec[:H] = np.where(which[..., None], scale * c.forces, 0.0)
        return c.positions, vec


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def arrow_keys(tail: np.ndarray, vector: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """(shaft pose (4, 4) without its scale, head pose (4, 4), shaft length L (m), shown) of one
    arrow from ``tail`` along ``vector`` (m)."""
    L = float(np.linalg.norm(vector))
    if L <= _HIDDEN:
        return np.eye(4), np.eye(4), 0.0, False
    d = vector / L
    R = cone_axis_rotation(d)
    return _pose(R, tail + 0.5 * L * d), _pose(R, tail + (L + 0.5 * HEAD_LENGTH) * d), L, True


def _material(color: int, overlay: bool = False) -> g.MeshLambertMaterial:
    """Opaque, or (``overlay``) drawn over the model (no depth test; three.js draws transparent
    objects after opaque ones): a foot's point and arrow stay visible inside the leg."""
    if overlay:
        return g.MeshLambertMaterial(color=color, opacity=0.95, transparent=True, depthTest=False)
    return g.MeshLambertMaterial(color=color)


def draw_contacts(vis: meshcat.Visualizer, scene: ContactScene) -> tuple[list[np.ndarray], list]:
    """Draw ``scene`` under ``vis`` (the ``contacts`` group) at frame 0.

    Returns:
        (points to keep in the camera's view, the animation tracks: a list of
        ``(node, frame k, kind, value)`` with kind "transform" (4, 4), "scale" (3,) or "visible"
        (bool), one per node, frame and property, for every frame 0..H).
    """
    c = scene.forces
    H1 = c.horizon + 1
    points: list[np.ndarray] = [c.positions.reshape(-1, 3)]
    tracks: list = []
    if scene.ground:
        z = scene.ground_height
        lo = c.positions.reshape(-1, 3).min(axis=0) - GROUND_MARGIN
        hi = c.positions.reshape(-1, 3).max(axis=0) + GROUND_MARGIN
        vis["ground"].set_object(g.Box([float(hi[0] - lo[0]), float(hi[1] - lo[1]), GROUND_THICKNESS]),
                                 _material(GROUND_COLOR))
        vis["ground"].set_transform(_pose(np.eye(3), [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                                      z - 0.5 * GROUND_THICKNESS]))
    for i, foot in enumerate(c.feet):
        node = vis["points"][foot]
        node.set_object(g.Sphere(POINT_RADIUS), _material(POINT_COLOR, True))
        for k in range(H1):
            tracks.append((node, k, "transform", _pose(np.eye(3), c.positions[k, i])))
            tracks.append((node, k, "visible", bool(c.on_ground[k, i])))
    for group, impulses, color in (("forces", False, FORCE_COLOR), ("impulses", True, IMPULSE_COLOR)):
        tails, vecs = scene.arrows(impulses)
        if not np.any(vecs):
            continue
        points.append((tails + vecs).reshape(-1, 3))
        for i, foot in enumerate(c.feet):
            if not np.any(vecs[:, i]):
                continue
            shaft, head = vis[group][foot]["shaft"], vis[group][foot]["head"]
            shaft.set_object(g.Cylinder(1.0, SHAFT_RADIUS), _material(color, True))
            head.set_object(g.Cylinder(HEAD_LENGTH, radiusTop=0.0, radiusBottom=HEAD_RADIUS), _material(color, True))
            last = (np.eye(4), np.eye(4), 1.0)
            for k in range(H1):
                S, Hd, L, shown = arrow_keys(tails[k, i], vecs[k, i])
                if shown:
                    last = (S, Hd, L)
                S, Hd, L = last  # a hidden arrow keeps its last pose (no flight through the scene)
                tracks += [(shaft, k, "transform", S), (shaft, k, "scale", [1.0, L, 1.0]),
                           (shaft, k, "visible", shown), (head, k, "transform", Hd), (head, k, "visible", shown)]
    # frame 0 as the static state too (a viewer that does not play the animation shows it)
    for node, k, kind, value in tracks:
        if k != 0:
            continue
        if kind == "transform":
            node.set_transform(value)
        else:
            node.set_property(kind, [float(x) for x in value] if kind == "scale" else bool(value))
    return points, tracks


def add_tracks(anim, tracks: list) -> None:
    """Put :func:`draw_contacts`' tracks into a ``meshcat.animation.Animation``."""
    for node, k, kind, value in tracks:
        with anim.at_frame(node, k) as frame:
            if kind == "transform":
                frame.set_transform(value)
            elif kind == "scale":
                frame.set_property("scale", "vector3", [float(x) for x in value])
            else:
                frame.set_property("visible", "boolean", bool(value))
