"""The replay scene of any Result, as meshcat commands: the single entry point of the live viewer
(:mod:`geoddp.viz.meshcat_replay`) and the static HTML export (:mod:`geoddp.viz.html`).

:func:`build_scene` draws the model :mod:`geoddp.viz.model` rebuilds (the multibody model of the
solve, or the built-in satellite) from its URDF primitive visuals, under ``vis["robot"]``, one
node per geometry object, and animates them: keyframe k of node ``robot/<object>`` is its world
placement oMg(q_k), at fps = 1/dt. The target pose is a translucent ghost of the whole model under
``vis["target_ghost"]`` (static), placed at :func:`geoddp.viz.model.ghost_configuration`.

Each animated node ``robot/<object>`` carries exactly ``oMg``; the shape's own static transform sits
on its child ``robot/<object>/shape``: for a primitive its frame correction (three.js cylinders lie
along y, Pinocchio's along z), for a mesh its URDF ``scale`` (diag(sx, sy, sz)). A DAE or binary
STL mesh is drawn as compact binary geometry (:mod:`geoddp.viz.compact_mesh`: the triangles meshcat's
viewer would build from the file, quantised; a DAE without a URDF ``<material>`` in the file's own
materials, else in the URDF colour), read once per file. A file that module leaves alone (OBJ,
ASCII STL, a textured DAE, ...) is drawn with meshcat's own mesh geometries, the file embedded in
the command (STL and OBJ through ``meshcat.geometry``; a DAE without a URDF ``<material>`` through
Pinocchio's ``pin.visualize.meshcat_visualizer.DaeMeshGeometry``, which keeps the file's own colours
and inlines its textures; a DAE with one through ``meshcat.geometry``, in the URDF colour). Either
way the HTML page stays self-contained. Above ``max_mesh_mb`` of mesh files (each counted once per
object that draws it) the scene is refused with a message that offers ``geometry="collision"``.

Besides the model: optional frame-target triads (``vis["frame_targets"]``, from
:func:`geoddp.viz.model.frame_targets`), an optional trail (``vis["trail"]``: a line through the
positions of the root or of a named frame, with a bead at each time step) and a camera that frames
the box of everything drawn over the whole trajectory (:func:`camera_view`).
A constrained result's keep-out cones, obstacles (spheres, half-spaces) and terminal poses sit
under ``vis["constraints"]`` (:mod:`geoddp.viz.constraint_shapes`).
A legged trajectory's ground, contact points and force arrows sit under ``vis["contacts"]``
(:mod:`geoddp.viz.contact_shapes`).
A ``scale`` other than 1 sits on ``vis["robot"]``, ``vis["target_ghost"]``, ``vis["frame_targets"]``,
``vis["trail"]``, ``vis["constraints"]`` and ``vis["contacts"]`` themselves.

Pinocchio's own ``pin.visualize.MeshcatVisualizer`` is not reused: it draws one configuration at a
time through its own ``meshcat.Visualizer`` (``display(q)``) and records animations only as videos,
whereas the live loopback viewer and the offline HTML recorder both need the whole trajectory as
one meshcat animation on a visualizer we provide.

This module only *describes* the scene: it talks to anything that behaves like a
``meshcat.Visualizer`` (a live one backed by a server, or the offline recorder of
:mod:`geoddp.viz.html`). Starting servers and writing files live elsewhere.
"""
from __future__ import annotations

import functools
import os
import warnings

import meshcat
import meshcat.geometry as g
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation

from ..solver.result import Result
from ..validate import InputError, positive_float
from .compact_mesh import CompactMeshObject, MeshData, read_mesh
from .constraint_shapes import CONSTRAINTS, constraint_shapes, draw_constraints
from .contact_shapes import CONTACTS, ContactScene, add_tracks, draw_contacts
from .model import (VisualModel, check_replayable, frame_positions, frame_targets, ghost_configuration,
                    load_visual_model, mesh_bytes, mesh_file, placements_at, replay_description,
                    satellite_description, trajectory_corners)

try:  # Pinocchio's own DAE element: the file's materials and textures (as data URIs) are kept
    from pinocchio.visualize.meshcat_visualizer import DaeMeshGeometry as _PinDae
except ImportError:  # pragma: no cover - pin built without its meshcat visualizer
    _PinDae = None

#: Scene-tree name (relative to the visualizer root) of the group holding the model's visuals.
ROBOT = "robot"
#: Scene-tree name of the group holding the translucent target ghost.
GHOST = "target_ghost"
#: Name of the child node holding each object's primitive (static shape-frame correction).
SHAPE = "shape"
#: Scene-tree name of the group holding the frame-target triads.
TARGETS = "frame_targets"
#: Scene-tree name of the group holding the trail (``line`` and ``beads/<k>``).
TRAIL = "trail"
#: Scene-tree name of the group holding the animated ghost of a plan (a simulated run's replay).
PLAN = "plan_ghost"
#: Default limit (megabytes, 1e6 bytes) on the mesh data a scene embeds.
MAX_MESH_MB = 20.0
TRAIL_COLOR = 0xFFC030
# Frame-target triad axes x, y, z: saturated red, green, blue (a screenshot test finds the red one).
TRIAD_COLORS = (0xFF2020, 0x20E040, 0x3060FF)

GHOST_COLOR = 0x88CCFF
GHOST_OPACITY = 0.3
GHOST_INFLATE = 1.03  # each ghost primitive 3 % larger than the model's: no z-fighting when they coincide
# Uniform dark background (top = bottom colour, RGB in [0, 1]): space-like, and a single
# background colour makes "is anything drawn?" checks on screenshots trivial.
BACKGROUND_RGB = [0.05, 0.07, 0.12]

# three.js builds cylinders along their local +y axis, Pinocchio (coal) along +z: rotate y -> z.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
# Camera direction from its target (the centre of the trajectory's box), world coordinates (z up):
# from -y, a little ahead in x and above, so a reach along +x reads as a side view.
_CAMERA_DIRECTION = np.array([0.6, -1.0, 0.55])
# meshcat's default camera: 75 deg vertical field of view (the narrower one in a landscape window).
# A sphere of radius r about the target stays inside the view from distance r / sin(37.5 deg) =
# 1.64 r on (its near side looks larger than r / tan(37.5 deg) = 1.30 r suggests: at 1.4 r the
# satellite's near panel left the frame mid-turn).
_CAMERA_FIT = 1.7


def set_backdrop(vis: meshcat.Visualizer) -> None:
    """Space backdrop: uniform dark background, no ground grid and no world axes.

    The grid would otherwise cut through a model at the world origin and hide its lower half; the
    axes would sit at the orbit centre (the trajectory's centre, see :func:`_set_camera`), not at
    the world origin.
    """
    vis["/Background"].set_property("top_color", BACKGROUND_RGB)
    vis["/Background"].set_property("bottom_color", BACKGROUND_RGB)
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)


def _primitive(obj: pin.GeometryObject) -> tuple[g.Geometry, np.ndarray] | None:
    """(meshcat geometry, 4x4 shape-frame correction) of a primitive, or None if unsupported."""
    shape = obj.geometry
    kind = type(shape).__name__  # coal (Pinocchio 3+) or hppfcl: same class names
    if kind == "Box":
        return g.Box((2.0 * np.asarray(shape.halfSide)).tolist()), np.eye(4)
    if kind == "Sphere":
        return g.Sphere(float(shape.radius)), np.eye(4)
    if kind in ("Cylinder", "Capsule"):
        return g.Cylinder(2.0 * float(shape.halfLength), float(shape.radius)), _Y_TO_Z
    return None


def _mesh(obj: pin.GeometryObject, ghost: bool):
    """(drawable, 4x4 scale diag(meshScale)) of a mesh-file object, or None when it is not one (or
    its file is gone). The drawable is the file's triangles as compact binary geometry
    (:class:`~geoddp.viz.compact_mesh.MeshData`, read once per file) where
    :func:`~geoddp.viz.compact_mesh.read_mesh` reads it, else meshcat's own mesh geometry of the
    file (or Pinocchio's DAE element, which keeps the file's materials and textures)."""
    path = mesh_file(obj)
    if path is None:
        return None
    ext = path.rsplit(".", 1)[-1].lower()
    scale = np.diag([*np.asarray(obj.meshScale, dtype=float), 1.0])
    own = ext == "dae" and not ghost and not obj.overrideMaterial
    compact = _compact(path, os.path.getmtime(path))
    if compact is not None:
        # a DAE keeps the file's own materials unless the URDF gives one (or it is the ghost)
        return (compact if own and compact.materials else compact.plain), scale
    if own and _PinDae is not None:
        return _PinDae(path), scale
    loader = {"dae": g.DaeMeshGeometry, "stl": g.StlMeshGeometry, "obj": g.ObjMeshGeometry}[ext]
    return loader.from_file(path), scale


@functools.lru_cache(maxsize=128)  # a robot has up to ~60 mesh files
def _compact(path: str, mtime: float) -> MeshData | None:
    """:func:`~geoddp.viz.compact_mesh.read_mesh` of a file, remembered while it is unchanged
    (``mtime``): a model draws a file once per object that uses it, and again for its ghost."""
    return read_mesh(path)


def _color(rgba) -> int:
    """0xRRGGBB of an RGBA colour in [0, 1]."""
    r, gr, b = (int(round(255 * float(np.clip(c, 0, 1)))) for c in rgba[:3])
    return (r << 16) | (gr << 8) | b


def _draw(vis: meshcat.Visualizer, visual: VisualModel, placements: np.ndarray, scale: float,
          ghost: bool = False) -> list[int]:
    """One node per drawable visual object under ``vis`` (the group, scaled by ``scale``): node
    ``<name>`` at its world placement ``placements[i]`` (n_objects, 4, 4), and its child
    ``<name>/shape`` holding the primitive in the URDF's size (metres) and colour, or for the ghost
    inflated by GHOST_INFLATE, translucent and uniformly GHOST_COLOR (depthWrite off, so the solid
    model stays visible inside it). Mesh files (DAE, STL, OBJ) are drawn with their URDF scale on
    ``<name>/shape`` (see the module docstring for which loader). Other objects (e.g. a convex or
    height field built in code) are skipped, with a warning for the model (not again for its ghost).

    Returns:
        The indices (in ``visual.geometry.geometryObjects``) of the objects drawn.
    """
    vis.set_transform(np.diag([scale, scale, scale, 1.0]))
    drawn = []
    for i, (obj, name) in enumerate(zip(visual.geometry.geometryObjects, visual.names)):
        prim = _primitive(obj) or _mesh(obj, ghost)
        if prim is None:
            if not ghost:
                warnings.warn(f"visual {obj.name!r}: {type(obj.geometry).__name__} geometry is not drawn "
                              "(only box, sphere, cylinder and capsule primitives and DAE, STL and OBJ mesh files are)",
                              UserWarning, stacklevel=3)
            continue
        geometry, correction = prim
        if ghost:
            material = g.MeshLambertMaterial(color=GHOST_COLOR, opacity=GHOST_OPACITY, depthWrite=False)
            correction = correction @ np.diag([GHOST_INFLATE, GHOST_INFLATE, GHOST_INFLATE, 1.0])
        else:
            material = g.MeshLambertMaterial(color=_color(obj.meshColor), opacity=float(np.clip(obj.meshColor[3], 0, 1)))
        node = vis[name][SHAPE]
        if isinstance(geometry, MeshData):
            # compact geometry: the file's own materials, or this one for the whole mesh
            element = CompactMeshObject(geometry, None if geometry.materials else material.lower(None))
            element.path = node.path
            node.window.send(element)
        elif _PinDae is not None and isinstance(geometry, _PinDae):
            # A whole set_object command (geometry and the file's own materials), sent as is.
            geometry.path = node.path
            node.window.send(geometry)
        else:
            node.set_object(geometry, material)
        node.set_transform(correction)
        vis[name].set_transform(placements[i])
        drawn.append(i)
    return drawn


def model_animation(vis: meshcat.Visualizer, visual: VisualModel, placements: np.ndarray, dt: float,
                    drawn: list[int]) -> Animation:
    """One keyframe per time step and drawn object: node ``robot/<name>`` at oMg(q_k).

    Args:
        vis: visualizer holding the nodes drawn under ``vis["robot"]``.
        visual: the rebuilt model; placements: (H+1, n_objects, 4, 4) oMg along the trajectory.
        dt: time step in seconds; drawn: indices of the objects drawn.

    Returns:
        A ``meshcat.animation.Animation`` at fps = 1/dt with one clip per drawn object, H+1
        keyframes each (keyframe k plays at t_k = k dt seconds).
    """
    anim = Animation(default_framerate=1.0 / float(dt))
    for i in drawn:
        node = vis[ROBOT][visual.names[i]]
        for k in range(placements.shape[0]):
            with anim.at_frame(node, k) as frame:
                frame.set_transform(placements[k, i])
    return anim


def camera_view(points: np.ndarray, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """Where the default camera goes to see every point of ``points`` (N, 3), world metres.

    Returns:
        (target (3,), position (3,), radius): the target is the centre of the points' box, the
        radius the largest distance of a point from it (times ``scale``), and the camera sits along
        the fixed viewing direction at _CAMERA_FIT = 1.7 radii (>= 0.5 m) from the target: a sphere
        of that radius about the target fits meshcat's 75 deg field of view (it needs 1.64 radii).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3) * scale
    if pts.size == 0:
        pts = np.zeros((1, 3))
    target = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    radius = float(np.linalg.norm(pts - target, axis=1).max())
    direction = _CAMERA_DIRECTION / np.linalg.norm(_CAMERA_DIRECTION)
    return target, target + direction * max(0.5, _CAMERA_FIT * radius), radius


def _set_camera(vis: meshcat.Visualizer, target: np.ndarray, position: np.ndarray) -> None:
    """Look at ``target`` from ``position`` (world metres, z up).

    meshcat 0.3.2's orbit controls always look at the origin of the three.js world, and its
    viewer has no command to move that target; so the scene moves instead: the visualizer's root
    (``/meshcat``, holding every group drawn here) is translated by -target, which puts the target
    at the orbit centre and keeps every node's own transform (the keyframes stay oMg)."""
    vis.set_transform(_translation(-np.asarray(target, dtype=float)))
    d = np.asarray(position, dtype=float) - np.asarray(target, dtype=float)
    # The camera lives in meshcat's y-up "rotated" frame: world (x, y, z) -> (x, z, -y).
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(d[0]), float(d[2]), float(-d[1])])


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def triad_length(lower: np.ndarray, upper: np.ndarray) -> float:
    """Axis length (metres) of a frame-target triad: 20 % of the largest side of the trajectory's
    box, at least 5 cm."""
    return max(0.05, 0.2 * float(np.max(np.asarray(upper) - np.asarray(lower))))


def _draw_triad(vis: meshcat.Visualizer, placement: np.ndarray, length: float) -> None:
    """A frame triad at ``placement`` (4, 4): x, y, z axes as red, green, blue cylinders of
    ``length`` metres (radius length / 15) from the origin, and a white sphere at the origin,
    drawn over the model (:func:`_overlay`)."""
    vis.set_transform(placement)
    radius = length / 15.0
    # three.js cylinders lie along +y, centred: rotate y onto each axis and move half a length out.
    onto = {"x": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
            "y": np.eye(3), "z": _Y_TO_Z[:3, :3]}
    for (axis, R), color in zip(onto.items(), TRIAD_COLORS):
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = 0.5 * length * np.eye(3)["xyz".index(axis)]
        vis[axis].set_object(g.Cylinder(length, radius), _overlay(color))
        vis[axis].set_transform(T)
    vis["origin"].set_object(g.Sphere(1.6 * radius), _overlay(0xFFFFFF))


def _overlay(color: int) -> g.MeshLambertMaterial:
    """A material drawn over the model (no depth test; three.js draws transparent objects after
    opaque ones): a target inside or behind the robot stays visible."""
    return g.MeshLambertMaterial(color=color, opacity=0.95, transparent=True, depthTest=False)


def _draw_trail(vis: meshcat.Visualizer, points: np.ndarray, bead: float) -> None:
    """The trail through ``points`` (N, 3) metres: a line (float32 vertices, as three.js takes
    them) and a bead (sphere of radius ``bead``) placed exactly at each point by its node's
    transform (``beads/<k>``)."""
    vis["line"].set_object(g.Line(g.PointsGeometry(np.asarray(points, dtype=np.float32).T),
                                  g.LineBasicMaterial(color=TRAIL_COLOR, linewidth=2.0)))
    for k, p in enumerate(points):
        vis["beads"][str(k)].set_object(g.Sphere(bead), g.MeshLambertMaterial(color=TRAIL_COLOR))
        vis["beads"][str(k)].set_transform(_translation(p))


def check_mesh_size(result: Result, visual: VisualModel, copies: int, max_mesh_mb: float | None) -> int:
    """The mesh data (bytes) the scene embeds for ``copies`` drawings of the model (2 with a ghost).

    Raises:
        InputError: naming ``max_mesh_mb`` when it is not a positive number or None, or when the
            data exceeds it; the message gives both sizes and the way out (``geometry="collision"``,
            with the collision meshes' size, or a larger ``max_mesh_mb``).
    """
    if max_mesh_mb is not None and not (isinstance(max_mesh_mb, (int, float)) and max_mesh_mb > 0):
        raise InputError("max_mesh_mb", f"expected a positive number of megabytes or None, got {max_mesh_mb!r}")
    total = copies * mesh_bytes(visual)
    if max_mesh_mb is None or total <= max_mesh_mb * 1e6:
        return total
    hint = ""
    if visual.kind == "visual":
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                other = copies * mesh_bytes(load_visual_model(replay_description(result), "collision"))
            hint = f"pass geometry='collision' to draw the collision geometry instead ({other / 1e6:.1f} MB), or "
        except InputError:
            pass
    raise InputError("max_mesh_mb", f"expected at most {max_mesh_mb:g} MB of mesh data to embed, got "
                     f"{total / 1e6:.1f} MB ({visual.kind} meshes{', drawn twice: model and ghost' if copies > 1 else ''}): "
                     f"{hint}raise max_mesh_mb (None: no limit)")


def build_scene(vis: meshcat.Visualizer, result: Result, scale: float = 1.0, play: bool = True, *,
                geometry: str = "visual", trail: str | None = None,
                max_mesh_mb: float | None = MAX_MESH_MB, prepared: tuple | None = None,
                plan: Result | None = None, contacts: ContactScene | None = None) -> Animation:
    """The whole replay scene of any result: backdrop, the model's visuals at q_0, the target
    ghost, frame-target triads, the trail, the constraints' shapes (keep-out cones, obstacles and
    terminal poses of a constrained solve: :mod:`geoddp.viz.constraint_shapes`), the camera, and
    the trajectory animation, in that order.

    Args:
        vis: live or recording visualizer.
        result: any Result: the model comes from ``multibody`` (else the built-in satellite), the
            configurations from ``configurations (H+1, nq)`` (else ``rotations (H+1, 3, 3)``), the
            ghost from ``target_rotation (3, 3)``, triads from ``frame_targets`` in ``multibody``
            or ``extra`` (:func:`geoddp.viz.model.frame_targets`), the frame rate from ``dt`` (s).
        scale: uniform size factor of the drawing (1.0: the URDF's size in metres); it scales the
            scene about the world origin, so keyframes stay the model's oMg.
        play: start the animation immediately.
        geometry: "visual" (the URDF's visuals) or "collision" (its collision geometry).
        trail: None (no trail), "root" (the root body's path) or a frame name of the model (e.g.
            the end effector's): a line through its positions at every time step.
        max_mesh_mb: largest mesh data (MB) to embed, None for no limit
            (:func:`check_mesh_size`).
        prepared: what :func:`prepare_scene` returned for this result and these options (the
            live viewer checks before starting its server, and the meshes are loaded once).
        plan: another Result of the same model (the plan a simulated run flew): drawn as a
            translucent ghost under ``vis["plan_ghost"]``, animated beside the model (its last
            configuration held if the run is longer).
        contacts: a legged trajectory's ground, contact points and force arrows
            (:class:`geoddp.viz.contact_shapes.ContactScene`), drawn under ``vis["contacts"]`` and
            animated with the model; None: none.

    Returns:
        The animation (one clip per drawn visual object, H+1 keyframes each, fps = 1/dt).

    Raises:
        InputError: naming the parameter, see :func:`geoddp.viz.model.check_replayable`,
            :func:`check_mesh_size`, :func:`geoddp.viz.model.frame_positions` (``trail``) and
            :func:`geoddp.viz.model.frame_targets`.
        InputError: ``scale`` not a finite number > 0.
    """
    scale = positive_float(scale, "scale")
    if prepared is None:
        prepared = prepare_scene(result, geometry=geometry, trail=trail, max_mesh_mb=max_mesh_mb)
    visual, Q, q_ghost, targets, path = prepared
    placements = placements_at(visual, Q)
    # A visualizer may be replayed into again: nothing of an earlier scene may remain.
    if contacts is not None and not isinstance(contacts, ContactScene):
        raise InputError("contacts", f"expected a ContactScene or None, got {type(contacts).__name__}")
    if contacts is not None and contacts.forces.horizon + 1 != len(Q):
        raise InputError("contacts", f"expected the forces of the result's {len(Q) - 1} nodes, got "
                         f"{contacts.forces.horizon}")
    for group in (ROBOT, GHOST, TARGETS, TRAIL, PLAN, CONSTRAINTS, CONTACTS):
        vis[group].delete()
    set_backdrop(vis)
    drawn = _draw(vis[ROBOT], visual, placements[0], scale)
    seen = placements[:, drawn]
    plan_placements = None
    if plan is not None:
        _, Qp = check_replayable(plan, geometry)
        if Qp.shape[1] != Q.shape[1]:
            raise InputError("plan", f"expected a plan of the same model (nq = {Q.shape[1]}), got nq = {Qp.shape[1]}")
        Qp = np.vstack([Qp, np.repeat(Qp[-1:], max(0, len(Q) - len(Qp)), axis=0)])[: len(Q)]
        plan_placements = placements_at(visual, Qp)
        _draw(vis[PLAN], visual, plan_placements[0], scale, ghost=True)
        seen = np.concatenate([seen, plan_placements[:, drawn]])
    if q_ghost is not None:
        ghost = placements_at(visual, q_ghost[None])
        _draw(vis[GHOST], visual, ghost[0], scale, ghost=True)
        seen = np.concatenate([seen, ghost[:, drawn]])
    corners = trajectory_corners(_subset(visual, drawn), seen)
    lower, upper = (corners.min(axis=0), corners.max(axis=0)) if corners.size else (np.zeros(3), np.zeros(3))
    points = [corners]
    if targets:
        length = triad_length(lower, upper)
        vis[TARGETS].set_transform(np.diag([scale, scale, scale, 1.0]))
        for i, (frame, M) in enumerate(targets):
            _draw_triad(vis[TARGETS][f"{i}_{frame}".replace("/", "_")], M, length)
            # the triad is its origin and its three axis tips (one cylinder radius further out)
            points.append(M[:3, 3] + np.vstack([np.zeros(3), (1.0 + 1.0 / 15.0) * length * M[:3, :3].T]))
    if path is not None:
        vis[TRAIL].set_transform(np.diag([scale, scale, scale, 1.0]))
        _draw_trail(vis[TRAIL], path, bead=0.006 * float(np.max(upper - lower)) + 1e-3)
        points.append(path)
    moving: dict = {}
    shapes = constraint_shapes(result)
    if shapes:
        vis[CONSTRAINTS].set_transform(np.diag([scale, scale, scale, 1.0]))
        length = triad_length(lower, upper)
        extra, moving = draw_constraints(vis[CONSTRAINTS], shapes, visual, Q, lower, upper,
                                         lambda node, M: _draw_triad(node, M, length))
        points.extend(extra)
    contact_tracks: list = []
    if contacts is not None:
        vis[CONTACTS].set_transform(np.diag([scale, scale, scale, 1.0]))
        extra, contact_tracks = draw_contacts(vis[CONTACTS], contacts)
        points.extend(extra)
    target, position, _ = camera_view(np.vstack(points), scale)
    _set_camera(vis, target, position)
    anim = model_animation(vis, visual, placements, result.dt, drawn)
    for node, keys in moving.items():  # a keep-out cone whose apex follows a moving frame
        for k in range(keys.shape[0]):
            with anim.at_frame(node, k) as frame:
                frame.set_transform(keys[k])
    add_tracks(anim, contact_tracks)
    if plan_placements is not None:
        for i in drawn:
            node = vis[PLAN][visual.names[i]]
            for k in range(plan_placements.shape[0]):
                with anim.at_frame(node, k) as frame:
                    frame.set_transform(plan_placements[k, i])
    vis.set_animation(anim, play=play, repetitions=1)
    return anim


def _subset(visual: VisualModel, indices: list[int]) -> VisualModel:
    """The model with only the geometry objects ``indices`` (for the box of what is drawn)."""
    gmodel = pin.GeometryModel()
    for i in indices:
        gmodel.addGeometryObject(visual.geometry.geometryObjects[i])
    return VisualModel(visual.model, gmodel, tuple(visual.names[i] for i in indices), visual.root, visual.kind)


def prepare_scene(result: Result, *, geometry: str = "visual", trail: str | None = None,
                  max_mesh_mb: float | None = MAX_MESH_MB):
    """Everything :func:`build_scene` reads, checked, before anything is drawn or a server started.

    Returns:
        (visual model, configurations (H+1, nq), ghost configuration (nq,) or None,
        frame targets [(name, (4, 4))], trail points (H+1, 3) or None).

    Raises:
        InputError: as :func:`build_scene`.
    """
    visual, Q = check_replayable(result, geometry)
    q_ghost = ghost_configuration(result, visual, Q)
    check_mesh_size(result, visual, 1 if q_ghost is None else 2, max_mesh_mb)
    targets = frame_targets(result)
    if trail is not None and not isinstance(trail, str):
        raise InputError("trail", f"expected None, 'root' or a frame name, got {trail!r}")
    path = None if trail is None else frame_positions(visual, Q, trail)
    return visual, Q, q_ghost, targets, path


def build_satellite(vis: meshcat.Visualizer, scale: float = 1.0) -> None:
    """Draw the built-in satellite (``satellite.urdf``'s bus, two solar panels and body axes) at
    the identity attitude under ``vis["robot"]``, and its translucent ghost under
    ``vis["target_ghost"]``; :func:`build_scene` does this and more for a satellite result.

    Args:
        vis: a ``meshcat.Visualizer`` (live or recording); nodes are created below it.
        scale: uniform size factor (1.0: the URDF's size in metres, a 1.0 x 0.8 x 0.6 m bus).
    """
    scale = positive_float(scale, "scale")
    visual = load_visual_model(satellite_description())
    identity = placements_at(visual, np.array([[0.0, 0.0, 0.0, 1.0]]))[0]
    _draw(vis[ROBOT], visual, identity, scale)
    _draw(vis[GHOST], visual, identity, scale, ghost=True)


__all__ = ["BACKGROUND_RGB", "CONSTRAINTS", "CONTACTS", "GHOST", "MAX_MESH_MB", "PLAN", "ROBOT", "SHAPE", "TARGETS", "TRAIL", "build_satellite",
           "build_scene", "camera_view", "check_mesh_size", "check_replayable", "model_animation", "prepare_scene",
           "set_backdrop"]
