"""The replay scene of any Result, as meshcat commands: the single entry point of the live viewer
(:mod:`geoddp.viz.meshcat_replay`) and the static HTML export (:mod:`geoddp.viz.html`).

:func:`build_scene` draws the model :mod:`geoddp.viz.model` rebuilds (the multibody model of the
solve, or the built-in satellite) from its URDF primitive visuals, under ``vis["robot"]``, one
node per geometry object, and animates them: keyframe k of node ``robot/<object>`` is its world
placement oMg(q_k), at fps = 1/dt. The target pose is a translucent ghost of the whole model under
``vis["target_ghost"]`` (static), placed at :func:`geoddp.viz.model.ghost_configuration`.

Each animated node ``robot/<object>`` carries exactly ``oMg``; the primitive's own frame correction
(three.js cylinders lie along y, Pinocchio's along z) sits on its child ``robot/<object>/shape``.
A ``scale`` other than 1 sits on ``vis["robot"]`` and ``vis["target_ghost"]`` themselves.

Pinocchio's own ``pin.visualize.MeshcatVisualizer`` is not reused: it draws one configuration at a
time through its own ``meshcat.Visualizer`` (``display(q)``) and records animations only as videos,
whereas the live loopback viewer and the offline HTML recorder both need the whole trajectory as
one meshcat animation on a visualizer we provide.

This module only *describes* the scene: it talks to anything that behaves like a
``meshcat.Visualizer`` (a live one backed by a server, or the offline recorder of
:mod:`geoddp.viz.html`). Starting servers and writing files live elsewhere.
"""
from __future__ import annotations

import warnings

import meshcat
import meshcat.geometry as g
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation

from ..result import Result
from .model import (VisualModel, check_replayable, ghost_configuration, load_visual_model, placements_at,
                    satellite_description)

#: Scene-tree name (relative to the visualizer root) of the group holding the model's visuals.
ROBOT = "robot"
#: Scene-tree name of the group holding the translucent target ghost.
GHOST = "target_ghost"
#: Name of the child node holding each object's primitive (static shape-frame correction).
SHAPE = "shape"

GHOST_COLOR = 0x88CCFF
GHOST_OPACITY = 0.3
GHOST_INFLATE = 1.03  # each ghost primitive 3 % larger than the model's: no z-fighting when they coincide
# Uniform dark background (top = bottom colour, RGB in [0, 1]): space-like, and a single
# background colour makes "is anything drawn?" checks on screenshots trivial.
BACKGROUND_RGB = [0.05, 0.07, 0.12]

# three.js builds cylinders along their local +y axis, Pinocchio (coal) along +z: rotate y -> z.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
# Camera direction from the world origin (meshcat's orbit target), world coordinates (z up): from
# -y, a little ahead in x and above, so a reach along +x reads as a side view.
_CAMERA_DIRECTION = np.array([0.6, -1.0, 0.55])
# meshcat's default camera: 75 deg vertical field of view (the narrower one in a landscape window).
# A sphere of radius r about the target stays inside the view from distance r / sin(37.5 deg) =
# 1.64 r on (its near side looks larger than r / tan(37.5 deg) = 1.30 r, the older fit, suggests:
# at 1.4 r the satellite's near panel left the frame mid-turn).
_CAMERA_FIT = 1.7


def set_backdrop(vis: meshcat.Visualizer) -> None:
    """Space backdrop: uniform dark background and no ground grid.

    The grid would otherwise cut through a model at the world origin and hide its lower half.
    """
    vis["/Background"].set_property("top_color", BACKGROUND_RGB)
    vis["/Background"].set_property("bottom_color", BACKGROUND_RGB)
    vis["/Grid"].set_property("visible", False)


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
    model stays visible inside it). Objects that are not box, sphere, cylinder or capsule (e.g.
    meshes) are skipped, with a warning for the model (not again for its ghost).

    Returns:
        The indices (in ``visual.geometry.geometryObjects``) of the objects drawn.
    """
    vis.set_transform(np.diag([scale, scale, scale, 1.0]))
    drawn = []
    for i, (obj, name) in enumerate(zip(visual.geometry.geometryObjects, visual.names)):
        prim = _primitive(obj)
        if prim is None:
            if not ghost:
                warnings.warn(f"visual {obj.name!r}: {type(obj.geometry).__name__} geometry is not drawn "
                              "(only box, sphere, cylinder and capsule primitives are)", UserWarning, stacklevel=3)
            continue
        geometry, correction = prim
        if ghost:
            material = g.MeshLambertMaterial(color=GHOST_COLOR, opacity=GHOST_OPACITY, depthWrite=False)
            correction = correction @ np.diag([GHOST_INFLATE, GHOST_INFLATE, GHOST_INFLATE, 1.0])
        else:
            material = g.MeshLambertMaterial(color=_color(obj.meshColor), opacity=float(np.clip(obj.meshColor[3], 0, 1)))
        node = vis[name][SHAPE]
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


def _bounding_radius(obj: pin.GeometryObject) -> float:
    """Radius in metres of a sphere about the primitive's centre that holds it (0 if not drawn)."""
    shape = obj.geometry
    kind = type(shape).__name__
    if kind == "Box":
        return float(np.linalg.norm(shape.halfSide))
    if kind == "Sphere":
        return float(shape.radius)
    if kind == "Cylinder":
        return float(np.hypot(shape.radius, shape.halfLength))
    if kind == "Capsule":
        return float(shape.radius + shape.halfLength)
    return 0.0


def _frame_camera(vis: meshcat.Visualizer, placements: np.ndarray, visual: VisualModel, scale: float) -> None:
    """Put the default camera (looking at the world origin, meshcat's orbit target) just far enough
    out to see the whole trajectory: 1.7x the largest reach of any object over time (its centre's
    distance from the origin plus its bounding radius), >= 3 m."""
    radii = np.array([_bounding_radius(o) for o in visual.geometry.geometryObjects])
    if placements.size:
        reach = float((np.linalg.norm(placements[:, :, :3, 3], axis=-1) + radii[None, :]).max())
    else:
        reach = 1.0
    d = _CAMERA_DIRECTION / np.linalg.norm(_CAMERA_DIRECTION) * max(3.0, _CAMERA_FIT * scale * reach)
    # The camera lives in meshcat's y-up "rotated" frame: world (x, y, z) -> (x, z, -y).
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(d[0]), float(d[2]), float(-d[1])])


def build_satellite(vis: meshcat.Visualizer, scale: float = 1.0) -> None:
    """Draw the built-in satellite (``satellite.urdf``'s bus, two solar panels and body axes) at
    the identity attitude under ``vis["robot"]``, and its translucent ghost under
    ``vis["target_ghost"]``; :func:`build_scene` does this and more for a satellite result.

    Args:
        vis: a ``meshcat.Visualizer`` (live or recording); nodes are created below it.
        scale: uniform size factor (1.0: the URDF's size in metres, a 1.0 x 0.8 x 0.6 m bus).
    """
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale!r}")
    visual = load_visual_model(satellite_description())
    identity = placements_at(visual, np.array([[0.0, 0.0, 0.0, 1.0]]))[0]
    _draw(vis[ROBOT], visual, identity, scale)
    _draw(vis[GHOST], visual, identity, scale, ghost=True)


def build_scene(vis: meshcat.Visualizer, result: Result, scale: float = 1.0, play: bool = True) -> Animation:
    """The whole replay scene of any result: backdrop, the model's visuals at q_0, the target
    ghost, the camera, and the trajectory animation, in that order.

    Args:
        vis: live or recording visualizer.
        result: any Result: the model comes from ``multibody`` (else the built-in satellite), the
            configurations from ``configurations (H+1, nq)`` (else ``rotations (H+1, 3, 3)``), the
            ghost from ``target_rotation (3, 3)``, the frame rate from ``dt`` (s).
        scale: uniform size factor of the drawing (1.0: the URDF's size in metres); it scales the
            scene about the world origin, so keyframes stay the model's oMg.
        play: start the animation immediately.

    Returns:
        The animation (one clip per drawn visual object, H+1 keyframes each, fps = 1/dt).

    Raises:
        InputError: naming the parameter, see :func:`geoddp.viz.model.check_replayable`.
        ValueError: ``scale`` not positive.
    """
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale!r}")
    visual, Q = check_replayable(result)
    placements = placements_at(visual, Q)
    # A visualizer may be replayed into again: nothing of an earlier model or ghost may remain.
    vis[ROBOT].delete()
    vis[GHOST].delete()
    set_backdrop(vis)
    drawn = _draw(vis[ROBOT], visual, placements[0], scale)
    seen = placements
    q_ghost = ghost_configuration(result, visual, Q)
    if q_ghost is not None:
        ghost = placements_at(visual, q_ghost[None])
        _draw(vis[GHOST], visual, ghost[0], scale, ghost=True)
        seen = np.concatenate([placements, ghost])
    _frame_camera(vis, seen, visual, scale)
    anim = model_animation(vis, visual, placements, result.dt, drawn)
    vis.set_animation(anim, play=play, repetitions=1)
    return anim


__all__ = ["BACKGROUND_RGB", "GHOST", "ROBOT", "SHAPE", "build_satellite", "build_scene",
           "check_replayable", "model_animation", "set_backdrop"]
