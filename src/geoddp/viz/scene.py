"""The satellite scene and its time-synchronised animation, as meshcat commands.

:func:`build_scene` is the entry point of the live viewer and the HTML export: a multibody result
(one with ``Result.multibody``) goes to :mod:`geoddp.viz.multibody` (the whole Pinocchio model),
any other to the satellite scene below (the TSO(3) attitude).

This module only *describes* the scene: it talks to anything that behaves like a
``meshcat.Visualizer`` (a live one backed by a server, or the offline recorder used by
:mod:`geoddp.viz.html`). Starting servers and writing files live elsewhere.
"""
from __future__ import annotations

import warnings

import numpy as np
import meshcat
import meshcat.geometry as g
from meshcat.animation import Animation

from ..result import Result
from .multibody import build_multibody_scene, check_multibody_result, is_multibody

#: Scene-tree names (relative to the visualizer root). The animation targets SATELLITE.
SATELLITE = "satellite"
GHOST = "target_ghost"

# Bus and panel dimensions in metres at scale 1 (x, y, z in the body frame).
BUS_SIZE = (1.0, 0.8, 0.6)
PANEL_SIZE = (0.6, 1.6, 0.02)
PANEL_GAP = 0.1  # clearance between the bus side and the panel root, in metres
AXIS_LENGTH = 1.2
AXIS_RADIUS = 0.03  # thicker than the panels so the y axis shows on them

BUS_COLOR = 0xC8A165  # gold foil
PANEL_COLOR = 0x1F3A93  # blue cells
AXIS_COLORS = {"x": 0xE02020, "y": 0x20B020, "z": 0x2040E0}
GHOST_COLOR = 0x88CCFF
GHOST_OPACITY = 0.3
GHOST_INFLATE = 1.03  # slightly larger than the satellite: no z-fighting when they coincide
# Uniform dark background (top = bottom colour, RGB in [0, 1]): space-like, and a single
# background colour makes "is anything drawn?" checks on screenshots trivial.
BACKGROUND_RGB = [0.05, 0.07, 0.12]


def _homogeneous(rotation: np.ndarray | None = None, translation=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 transform from a 3x3 rotation and a translation in metres."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


# three.js cylinders are built along their local +y axis; these rotations lay a
# cylinder along body x, y or z respectively.
_AXIS_ALIGN = {
    "x": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),  # y -> x
    "y": np.eye(3),
    "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # y -> z
}
_AXIS_UNIT = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}


def _add_body(vis: meshcat.Visualizer, scale: float, opacity: float, color_override: int | None) -> None:
    """Bus, two panels and axes under ``vis``; one body frame, origin at the centre of mass."""

    def mat(color: int) -> g.MeshLambertMaterial:
        c = color if color_override is None else color_override
        # depthWrite off for the ghost so the solid satellite stays visible inside it.
        extra = {"depthWrite": False} if opacity < 1.0 else {}
        return g.MeshLambertMaterial(color=c, opacity=opacity, **extra)

    bx, by, bz = (scale * s for s in BUS_SIZE)
    vis["bus"].set_object(g.Box([bx, by, bz]), mat(BUS_COLOR))
    px, py, pz = (scale * s for s in PANEL_SIZE)
    offset = by / 2 + scale * PANEL_GAP + py / 2
    for side, sign in (("panel_pos_y", 1.0), ("panel_neg_y", -1.0)):
        vis[side].set_object(g.Box([px, py, pz]), mat(PANEL_COLOR))
        vis[side].set_transform(_homogeneous(translation=(0.0, sign * offset, 0.0)))
    length, radius = scale * AXIS_LENGTH, scale * AXIS_RADIUS
    for name, R in _AXIS_ALIGN.items():
        node = vis["axes"][name]
        node.set_object(g.Cylinder(length, radius), mat(AXIS_COLORS[name]))
        # The cylinder is centred on its origin: shift it by half its length so it starts
        # at the body origin and pokes out of the bus along +axis.
        node.set_transform(_homogeneous(R, translation=_AXIS_UNIT[name] * (length / 2)))


def build_satellite(vis: meshcat.Visualizer, scale: float = 1.0) -> None:
    """Add the satellite and its translucent target ghost to ``vis``.

    Creates ``vis["satellite"]`` (a 1.0 x 0.8 x 0.6 m bus, two 0.6 x 1.6 m solar panels
    along body y, and a red/green/blue x/y/z body-axes triad of thin cylinders) and
    ``vis["target_ghost"]`` (the same shape, translucent, uniformly coloured). Both start
    at the identity attitude; :func:`animate_result` moves them.

    Args:
        vis: a ``meshcat.Visualizer`` (live or recording); nodes are created below it.
        scale: uniform size factor (1.0 gives the dimensions above in metres).
    """
    if not scale > 0:
        raise ValueError(f"scale must be positive, got {scale!r}")
    _add_body(vis[SATELLITE], scale, opacity=1.0, color_override=None)
    _add_body(vis[GHOST], scale * GHOST_INFLATE, opacity=GHOST_OPACITY, color_override=GHOST_COLOR)


def check_result(result: Result) -> None:
    """Check the fields the viewer reads, so bad data fails here and not inside three.js.

    Raises:
        ValueError: ``rotations`` not (H+1, 3, 3) for ``times`` (H+1,), non-finite
            rotations, or ``dt`` not a positive number of seconds.
    """
    n = result.times.shape[0]
    if result.rotations.shape != (n, 3, 3):
        raise ValueError(f"rotations must be (H+1, 3, 3) = ({n}, 3, 3), got {result.rotations.shape}")
    if n < 1:
        raise ValueError("the trajectory has no time steps")
    if not (np.isfinite(result.dt) and result.dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {result.dt!r}")
    if not np.all(np.isfinite(result.rotations)):
        raise ValueError("rotations contain non-finite values")


def trajectory_animation(vis: meshcat.Visualizer, result: Result) -> Animation:
    """One keyframe per time step of ``result`` for ``vis["satellite"]``.

    Frame k holds R_k; the clip runs at fps = 1/dt, so keyframe k plays at t_k = k dt
    seconds and the replay is synchronised with the trajectory's own time.

    Args:
        vis: the visualizer holding the scene built by :func:`build_satellite`.
        result: the trajectory; reads ``rotations (H+1, 3, 3)`` and ``dt`` (s).

    Returns:
        A ``meshcat.animation.Animation`` with H+1 keyframes on the satellite node.
    """
    check_result(result)
    anim = Animation(default_framerate=1.0 / float(result.dt))
    node = vis[SATELLITE]
    for k, R in enumerate(result.rotations):
        with anim.at_frame(node, k) as frame:
            frame.set_transform(_homogeneous(R))
    return anim


def animate_result(vis: meshcat.Visualizer, result: Result, play: bool = True) -> Animation:
    """Place the ghost at R_d, put the satellite at R_0 and send the trajectory animation.

    Args:
        vis: visualizer with the scene from :func:`build_satellite`.
        result: reads ``rotations (H+1, 3, 3)``, ``target_rotation (3, 3)``, ``dt`` (s).
        play: start playing immediately in the viewer.

    Returns:
        The animation that was sent.
    """
    check_result(result)
    vis[GHOST].set_transform(_homogeneous(np.asarray(result.target_rotation, dtype=float)))
    vis[SATELLITE].set_transform(_homogeneous(result.rotations[0]))
    anim = trajectory_animation(vis, result)
    vis.set_animation(anim, play=play, repetitions=1)
    return anim


def set_backdrop(vis: meshcat.Visualizer) -> None:
    """Space backdrop: uniform dark background and no ground grid.

    The grid would otherwise cut through the satellite (it sits at the world origin) and
    hide its lower half.
    """
    vis["/Background"].set_property("top_color", BACKGROUND_RGB)
    vis["/Background"].set_property("bottom_color", BACKGROUND_RGB)
    vis["/Grid"].set_property("visible", False)


def check_replayable(result: Result) -> None:
    """Validate ``result`` for :func:`build_scene` (either kind) before anything is sent.

    Raises:
        ValueError: see :func:`check_result`, or
            :func:`geoddp.viz.multibody.check_multibody_result` for a multibody result.
    """
    if is_multibody(result):
        check_multibody_result(result)
    else:
        check_result(result)


def build_scene(vis: meshcat.Visualizer, result: Result, scale: float = 1.0, play: bool = True) -> Animation:
    """The whole replay scene: backdrop, bodies and the trajectory animation.

    A multibody result (``result.multibody`` set) replays the full Pinocchio model, root placement
    and every joint (:func:`geoddp.viz.multibody.build_multibody_scene`). Otherwise: backdrop,
    satellite, ghost at R_d and the attitude animation, in that order. A result with
    ``configurations`` but no ``multibody`` description (written before it existed) falls back to
    the root attitude, with a warning.

    Args:
        vis: live or recording visualizer.
        result: reads ``rotations (H+1, 3, 3)``, ``target_rotation (3, 3)``, ``dt`` (s); for a
            multibody result ``configurations (H+1, nq)`` and ``multibody`` instead.
        scale: satellite size factor (the satellite scene only; a multibody model is drawn at the
            URDF's size in metres).
        play: start the animation immediately.

    Returns:
        The animation (H+1 keyframes per animated node at fps = 1/dt).
    """
    if is_multibody(result):
        return build_multibody_scene(vis, result, play=play)
    if result.configurations is not None:
        warnings.warn("this multibody result has no model description (Result.multibody): replaying only the "
                      "root body's attitude", UserWarning, stacklevel=2)
    check_result(result)
    set_backdrop(vis)
    build_satellite(vis, scale=scale)
    return animate_result(vis, result, play=play)
