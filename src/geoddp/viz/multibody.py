"""Replay of a multibody Result: every visual of the Pinocchio model, moved by forward kinematics.

The model is rebuilt from ``Result.multibody`` (the URDF text and root joint the solve used), never
from the solver. Its visual geometry comes from ``pin.buildGeomFromUrdfString(...,
pin.GeometryType.VISUAL)``; primitives (box, cylinder, sphere, capsule drawn as a cylinder) become
meshcat objects under ``vis["robot"]``, one node per geometry object. At frame k each node's world
placement is ``oMg`` from ``pin.forwardKinematics`` + ``pin.updateGeometryPlacements`` at the
configuration q_k, recorded as keyframe k of a meshcat animation at fps = 1/dt.

Pinocchio's own ``pin.visualize.MeshcatVisualizer`` is not reused: it draws one configuration at a
time through its own ``meshcat.Visualizer`` (``display(q)``) and records animations only as videos,
whereas the live loopback viewer and the offline HTML recorder both need the whole trajectory as
one meshcat animation on a visualizer we provide.

Each animated node ``robot/<object>`` carries exactly ``oMg``; the primitive's own frame correction
(three.js cylinders lie along y, Pinocchio's along z) sits on its child ``robot/<object>/shape``.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import meshcat
import meshcat.geometry as g
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation

from ..models.multibody import ROOTS, _root_joint
from ..result import Result
from ..validate import InputError

#: Scene-tree name (relative to the visualizer root) of the group holding the model's visuals.
ROBOT = "robot"
#: Name of the child node holding each object's primitive (static shape-frame correction).
SHAPE = "shape"

# three.js builds cylinders along their local +y axis, Pinocchio (coal) along +z: rotate y -> z.
_Y_TO_Z = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
# Camera direction from the world origin (meshcat's orbit target), world coordinates (z up): from
# -y, a little ahead in x and above, so a reach along +x reads as a side view.
_CAMERA_DIRECTION = np.array([0.6, -1.0, 0.55])
# meshcat's default camera: 75 deg vertical field of view. A sphere of radius r about the target
# fills the view's height from distance r / tan(37.5 deg) = 1.30 r.
_CAMERA_FIT = 1.4


@dataclass(frozen=True)
class VisualModel:
    """A rebuilt Pinocchio model with its visual geometry.

    Attributes:
        model: kinematic model (root joint as in the solve).
        geometry: its ``GeometryType.VISUAL`` geometry model.
        names: meshcat node name of each geometry object, in ``geometry.geometryObjects`` order.
    """

    model: pin.Model
    geometry: pin.GeometryModel
    names: tuple[str, ...]


def is_multibody(result: Result) -> bool:
    """True when ``result`` carries a multibody model description (``result.multibody``)."""
    return getattr(result, "multibody", None) is not None


def load_visual_model(description: dict) -> VisualModel:
    """Rebuild the model and its visual geometry from a ``Result.multibody`` description.

    Args:
        description: dict with ``"root"`` in ("free_flyer", "spherical", "fixed") and the URDF,
            as ``"urdf_xml"`` (text, preferred: the model exactly as solved) or ``"urdf"`` (path).

    Raises:
        InputError: naming ``result.multibody`` (or the key) when the description is incomplete
            or its URDF cannot be parsed.
    """
    if not isinstance(description, dict):
        raise InputError("result.multibody", f"expected a dict with 'urdf_xml' or 'urdf' and 'root', got {type(description).__name__}")
    root = description.get("root")
    if root not in ROOTS:
        raise InputError("result.multibody.root", f"expected one of {ROOTS}, got {root!r}")
    xml = description.get("urdf_xml")
    if xml is None:
        path = description.get("urdf")
        if path is None:
            raise InputError("result.multibody", "expected 'urdf_xml' (URDF text) or 'urdf' (path), got neither")
        try:
            with open(path, encoding="utf-8") as f:
                xml = f.read()
        except OSError as exc:
            raise InputError("result.multibody.urdf", f"expected a readable URDF file, got {path!r} ({exc})") from None
    rj = _root_joint(root)
    try:
        model = pin.buildModelFromXML(xml) if rj is None else pin.buildModelFromXML(xml, rj)
        geometry = pin.buildGeomFromUrdfString(model, xml, pin.GeometryType.VISUAL)
    except (ValueError, RuntimeError) as exc:
        raise InputError("result.multibody", f"expected a valid URDF with loadable visuals ({exc})") from None
    names = tuple(o.name.replace("/", "_") for o in geometry.geometryObjects)
    return VisualModel(model, geometry, names)


def check_multibody_result(result: Result, visual: VisualModel | None = None) -> VisualModel:
    """Check what the multibody replay reads; return the rebuilt :class:`VisualModel`.

    Raises:
        InputError: naming the parameter: ``result.multibody`` missing or invalid,
            ``result.configurations`` missing, not (H+1, nq) for ``times`` (H+1,), or
            non-finite, ``result.dt`` not positive.
    """
    if not is_multibody(result):
        raise InputError("result.multibody", "expected the model description of a multibody solve (urdf, root), got None")
    Q = result.configurations
    if Q is None:
        raise InputError("result.configurations", "expected (H+1, nq) Pinocchio configurations, got None")
    if visual is None:
        visual = load_visual_model(result.multibody)
    n, nq = int(np.shape(result.times)[0]), int(visual.model.nq)
    Q = np.asarray(Q)
    if Q.shape != (n, nq):
        raise InputError("result.configurations", f"expected shape (H+1, nq) = ({n}, {nq}), got {Q.shape}")
    if n < 1:
        raise InputError("result.times", "expected at least one time step, got none")
    if not np.all(np.isfinite(Q)):
        raise InputError("result.configurations", "expected finite values, got NaN or inf")
    if not (np.isfinite(result.dt) and result.dt > 0):
        raise InputError("result.dt", f"expected a positive number of seconds, got {result.dt!r}")
    return visual


def visual_placements(result: Result, visual: VisualModel | None = None) -> np.ndarray:
    """World placements of every visual object along the trajectory.

    Args:
        result: multibody result; reads ``configurations (H+1, nq)`` and ``multibody``.
        visual: the rebuilt model (rebuilt from ``result.multibody`` if None).

    Returns:
        (H+1, n_objects, 4, 4) homogeneous transforms oMg (metres), from ``pin.forwardKinematics``
        and ``pin.updateGeometryPlacements`` at each q_k.
    """
    visual = check_multibody_result(result, visual)
    model, gmodel = visual.model, visual.geometry
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    Q = np.asarray(result.configurations, dtype=float)
    out = np.empty((Q.shape[0], gmodel.ngeoms, 4, 4))
    for k, q in enumerate(Q):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gmodel, gdata)
        for i in range(gmodel.ngeoms):
            out[k, i] = gdata.oMg[i].homogeneous
    return out


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


def _material(rgba) -> g.MeshLambertMaterial:
    r, gr, b, a = (float(c) for c in rgba)
    color = (int(round(255 * np.clip(r, 0, 1))) << 16) | (int(round(255 * np.clip(gr, 0, 1))) << 8) | int(round(255 * np.clip(b, 0, 1)))
    return g.MeshLambertMaterial(color=color, opacity=float(np.clip(a, 0, 1)))


def build_robot(vis: meshcat.Visualizer, visual: VisualModel) -> list[str]:
    """Create one node per drawable visual object under ``vis["robot"]``.

    Node ``robot/<name>`` is the object's frame (placed by :func:`multibody_animation`); its child
    ``robot/<name>/shape`` holds the primitive in the URDF's size (metres) and colour. Objects
    that are not box, sphere, cylinder or capsule (e.g. meshes) are skipped with a warning.

    Returns:
        The names of the nodes created.
    """
    drawn = []
    for obj, name in zip(visual.geometry.geometryObjects, visual.names):
        prim = _primitive(obj)
        if prim is None:
            warnings.warn(f"visual {obj.name!r}: {type(obj.geometry).__name__} geometry is not drawn "
                          "(only box, sphere, cylinder and capsule primitives are)", UserWarning, stacklevel=2)
            continue
        geometry, correction = prim
        node = vis[ROBOT][name][SHAPE]
        node.set_object(geometry, _material(obj.meshColor))
        node.set_transform(correction)
        drawn.append(name)
    return drawn


def multibody_animation(vis: meshcat.Visualizer, result: Result, visual: VisualModel | None = None,
                        placements: np.ndarray | None = None) -> Animation:
    """One keyframe per time step and drawn visual object: node ``robot/<name>`` at oMg(q_k).

    Args:
        vis: visualizer holding the nodes of :func:`build_robot`.
        result: reads ``configurations (H+1, nq)``, ``multibody`` and ``dt`` (s).
        visual, placements: precomputed :func:`load_visual_model` / :func:`visual_placements`.

    Returns:
        A ``meshcat.animation.Animation`` at fps = 1/dt with one clip per object, H+1 keyframes
        each (keyframe k plays at t_k = k dt seconds).
    """
    visual = check_multibody_result(result, visual)
    if placements is None:
        placements = visual_placements(result, visual)
    anim = Animation(default_framerate=1.0 / float(result.dt))
    for i, (obj, name) in enumerate(zip(visual.geometry.geometryObjects, visual.names)):
        if _primitive(obj) is None:
            continue  # not drawn by build_robot
        node = vis[ROBOT][name]
        for k in range(placements.shape[0]):
            with anim.at_frame(node, k) as frame:
                frame.set_transform(placements[k, i])
    return anim


def _frame_camera(vis: meshcat.Visualizer, placements: np.ndarray, visual: VisualModel) -> None:
    """Put the default camera (looking at the world origin, meshcat's orbit target) just far enough
    out to see the whole trajectory: 1.4x the largest reach of any object over time, >= 3 m."""
    radius = 0.0
    for obj in visual.geometry.geometryObjects:
        s = obj.geometry
        for attr in ("halfSide", "radius", "halfLength"):
            if hasattr(s, attr):
                radius = max(radius, float(np.linalg.norm(np.atleast_1d(getattr(s, attr)))))
    reach = float(np.linalg.norm(placements[:, :, :3, 3], axis=-1).max()) + radius if placements.size else 1.0
    d = _CAMERA_DIRECTION / np.linalg.norm(_CAMERA_DIRECTION) * max(3.0, _CAMERA_FIT * reach)
    # The camera lives in meshcat's y-up "rotated" frame: world (x, y, z) -> (x, z, -y).
    vis["/Cameras/default/rotated/<object>"].set_property("position", [float(d[0]), float(d[2]), float(-d[1])])


def build_multibody_scene(vis: meshcat.Visualizer, result: Result, play: bool = True) -> Animation:
    """Backdrop, the model's visuals at q_0, the camera, and the trajectory animation.

    Args:
        vis: live or recording visualizer.
        result: multibody result; reads ``configurations (H+1, nq)``, ``multibody``, ``dt`` (s).
        play: start the animation immediately.

    Returns:
        The animation (one clip per visual object, H+1 keyframes each, fps = 1/dt).

    Raises:
        InputError: see :func:`check_multibody_result`.
    """
    from .scene import set_backdrop  # scene.py dispatches here: import at call time, no cycle

    visual = check_multibody_result(result)
    placements = visual_placements(result, visual)
    set_backdrop(vis)
    drawn = set(build_robot(vis, visual))
    for i, name in enumerate(visual.names):
        if name in drawn:
            vis[ROBOT][name].set_transform(placements[0, i])
    _frame_camera(vis, placements, visual)
    anim = multibody_animation(vis, result, visual, placements)
    vis.set_animation(anim, play=play, repetitions=1)
    return anim
