"""The model a Result replays: rebuilt from a URDF, its visuals placed by forward kinematics.

One path for every result. The model comes from the result's description
(:func:`replay_description`): ``Result.multibody`` (the URDF text and root joint the solve used)
when present, else the built-in ``satellite.urdf`` with a spherical root, the one-body model of a
satellite (TSO(3)) result. The configuration sequence comes from the result
(:func:`replay_configurations`): ``Result.configurations`` (H+1, nq) for a multibody result, else
q_k = the unit quaternion (x, y, z, w) of ``rotations[k]``. The visual geometry comes from
``pin.buildGeomFromUrdfString(..., pin.GeometryType.VISUAL, package_dirs)`` and each object's world placement at
frame k is ``oMg`` from ``pin.forwardKinematics`` + ``pin.updateGeometryPlacements`` at q_k
(:func:`visual_placements`). The target pose of the root (:func:`ghost_configuration`) is the
final configuration with the root's rotation set to ``Result.target_rotation``.

Meshes (DAE, STL, OBJ) are found the way Pinocchio finds them (``package://`` URIs searched in
:func:`package_dirs`); a mesh file found nowhere is left out of the geometry with a warning naming
the file (:func:`load_visual_model`), so the replay draws the rest. ``geometry="collision"`` builds
the ``<collision>`` elements instead of the ``<visual>`` ones (usually far smaller meshes).

The model is never rebuilt from the solver. Pure kinematics: drawing is :mod:`geoddp.viz.scene`.
"""
from __future__ import annotations

import difflib
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..models.multibody import ROOTS, _root_joint
from ..models.robots import default_package_dirs, example_robot_data_dir  # noqa: F401  (re-exported here)
from ..models.satellite import DEFAULT_URDF as SATELLITE_URDF
from ..solver.result import MultibodyResult, Result, as_result, rotations_to_quaternions
from ..validate import InputError

# Where the root joint's rotation sits in q (the quaternion (x, y, z, w)), for roots that have one.
_ROOT_QUATERNION = {"free_flyer": slice(3, 7), "spherical": slice(0, 4)}


@dataclass(frozen=True)
class VisualModel:
    """A rebuilt Pinocchio model with its visual geometry.

    Attributes:
        model: kinematic model (root joint as in the solve).
        geometry: its ``GeometryType.VISUAL`` (or ``COLLISION``) geometry model.
        names: meshcat node name of each geometry object, in ``geometry.geometryObjects`` order.
        root: the root joint kind, one of ``ROOTS``.
        kind: "visual" or "collision": which URDF elements ``geometry`` holds.
        missing: the URDF ``filename`` of every mesh that was found nowhere (left out).
        package_dirs: the directories ``package://`` URIs were searched in.
    """

    model: pin.Model
    geometry: pin.GeometryModel
    names: tuple[str, ...]
    root: str = "fixed"
    kind: str = "visual"
    missing: tuple[str, ...] = ()
    package_dirs: tuple[str, ...] = field(default_factory=tuple)

    @property
    def one_body(self) -> bool:
        """True when the root joint is the only joint (every visual rides on the root body)."""
        return self.model.njoints == (1 if self.root == "fixed" else 2)


def satellite_description() -> dict:
    """The model description of a satellite (TSO(3)) result: the built-in ``satellite.urdf``
    (bus, two solar panels, body axes as visuals) on a spherical root."""
    return {"urdf": str(SATELLITE_URDF), "root": "spherical", "nq": 4, "nv": 3}


def replay_description(result: Result) -> dict:
    """The description the replay rebuilds the model from: ``result.multibody``, or for a result
    without one the satellite's (:func:`satellite_description`).

    A result with ``configurations`` but no ``multibody`` (a multibody JSON written before the
    description existed) replays its root attitude on the satellite model, with a warning.
    """
    if isinstance(result, MultibodyResult):
        if result.multibody is not None:
            return result.multibody
        if result.configurations is not None:
            warnings.warn("this multibody result has no model description (Result.multibody): replaying only the "
                          "root body's attitude, on the satellite model", UserWarning, stacklevel=3)
    return satellite_description()


#: Which URDF elements a replay draws: ``<visual>`` (as designed) or ``<collision>`` (usually
#: coarse meshes or primitives: the fallback when the visual meshes are too large to embed).
GEOMETRIES = ("visual", "collision")
_GEOMETRY_TYPE = {"visual": pin.GeometryType.VISUAL, "collision": pin.GeometryType.COLLISION}
# A stand-in for a mesh found nowhere: a box this small (metres) is recognisable after parsing and
# removed again (pin.GeometryModel.removeGeometryObject), so every other object keeps the name
# Pinocchio gives it from its position in the URDF (<link>_<index>).
_PLACEHOLDER_SIZE = 1.2345e-9
_MISSING_MESH = re.compile(r"Mesh (.+) could not be found")


def package_dirs(description: dict) -> tuple[str, ...]:
    """Where ``package://`` mesh URIs of a described model are searched, in order.

    ``description["package_dirs"]`` (a path or a list of paths) when given; then, always, the
    URDF's own directory and its parent and grandparent (``<pkg>/urdf/robot.urdf`` naming
    ``package://<pkg>/meshes/...``), when the description has a ``"urdf"`` path; then the
    ``example-robot-data`` package directory when it is installed (:func:`example_robot_data_dir`).
    Pinocchio also searches ``ROS_PACKAGE_PATH`` itself.

    Raises:
        InputError: naming ``result.multibody.package_dirs`` when it is not a path or a list of paths.
    """
    given = description.get("package_dirs")
    if given is None:
        given = []
    elif isinstance(given, (str, os.PathLike)):
        given = [given]
    if not isinstance(given, (list, tuple)) or not all(isinstance(d, (str, os.PathLike)) for d in given):
        raise InputError("result.multibody.package_dirs", f"expected a path or a list of paths, got {given!r}")
    dirs = [str(d) for d in given] + list(default_package_dirs(description.get("urdf")))
    return tuple(dict.fromkeys(dirs))  # first occurrence wins, order kept


def _without_mesh(xml: str, filename: str) -> str:
    """The URDF text with every ``<mesh filename="filename" .../>`` replaced by the placeholder box."""
    pattern = re.compile(r"<mesh\b[^>]*\bfilename\s*=\s*([\"'])%s\1[^>]*?(?:/>|>\s*</mesh\s*>)" % re.escape(filename))
    box = '<box size="{0} {0} {0}"/>'.format(_PLACEHOLDER_SIZE)
    out, n = pattern.subn(box, xml)
    if n == 0:  # Pinocchio names a mesh we cannot find in the text: do not loop forever
        raise InputError("result.multibody", f"expected loadable meshes: {filename!r} could not be found and is not a <mesh filename> of the URDF")
    return out


def _is_placeholder(obj: pin.GeometryObject) -> bool:
    shape = obj.geometry
    return type(shape).__name__ == "Box" and np.allclose(2.0 * np.asarray(shape.halfSide), _PLACEHOLDER_SIZE, rtol=1e-6, atol=0)


def load_model(description: dict) -> pin.Model:
    """Rebuild the kinematic model (no geometry) of a model description, root joint as solved.

    Args:
        description: ``Result.multibody``: ``"root"`` in ("free_flyer", "spherical", "fixed") and the
            model as ``"pin_model"`` (Pinocchio's text archive, a model handed over with
            ``Multibody.from_model``), else the URDF as ``"urdf_xml"`` (text, preferred) or ``"urdf"``
            (path).

    Raises:
        InputError: naming ``result.multibody`` (or the key) when the description is incomplete or
            its model cannot be parsed.
    """
    if not isinstance(description, dict):
        raise InputError("result.multibody", f"expected a dict with 'urdf_xml' or 'urdf' and 'root', got {type(description).__name__}")
    root = description.get("root")
    if root not in ROOTS:
        raise InputError("result.multibody.root", f"expected one of {ROOTS}, got {root!r}")
    if description.get("pin_model") is not None:
        model = pin.Model()
        try:
            model.loadFromString(str(description["pin_model"]))
        except (ValueError, RuntimeError, TypeError) as exc:
            raise InputError("result.multibody.pin_model", f"expected Pinocchio's text archive of a model ({exc})") from None
        return model
    xml = _urdf_text(description)
    rj = _root_joint(root)
    try:
        return pin.buildModelFromXML(xml) if rj is None else pin.buildModelFromXML(xml, rj)
    except (ValueError, RuntimeError) as exc:
        raise InputError("result.multibody", f"expected a valid URDF ({exc})") from None


def load_visual_model(description: dict, geometry: str = "visual") -> VisualModel:
    """Rebuild the model and its visual (or collision) geometry from a model description.

    Args:
        description: dict with ``"root"`` in ("free_flyer", "spherical", "fixed") and the URDF,
            as ``"urdf_xml"`` (text, preferred: the model exactly as solved) or ``"urdf"`` (path);
            optionally ``"package_dirs"`` (a path or list of paths) for ``package://`` mesh URIs
            (see :func:`package_dirs` for the defaults added after them).
        geometry: "visual" (the URDF's ``<visual>`` elements) or "collision" (its ``<collision>``
            elements).

    A mesh file found nowhere is left out, with a ``UserWarning`` naming the file and the
    directories searched; every other object is kept under the name Pinocchio gives it.

    Raises:
        InputError: naming ``result.multibody`` (or the key) when the description is incomplete
            or its URDF cannot be parsed; naming ``geometry`` when it is not one of GEOMETRIES.
    """
    if geometry not in GEOMETRIES:
        raise InputError("geometry", f"expected one of {GEOMETRIES}, got {geometry!r}")
    model = load_model(description)
    root = description["root"]
    dirs = package_dirs(description)
    if description.get("pin_model") is not None:
        return _handed_over_geometry(model, description, dirs, geometry)
    return _geometry_from_urdf(model, _urdf_text(description), dirs, root, geometry)


def _urdf_text(description: dict) -> str:
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
    return xml


def _handed_over_geometry(model: pin.Model, description: dict, dirs: tuple[str, ...], geometry: str) -> VisualModel:
    """The visuals of a model handed over as a ``pin.Model`` (``Multibody.from_model``): from the
    geometry records when given (``geometry_objects``), else from the URDF named with it (links
    found by name in the model: a reduced model keeps every link's frame), else none (with a
    warning)."""
    root = description["root"]
    records = description.get("geometry_objects")
    if records is not None:
        return _geometry_from_records(model, records, dirs, root)
    if description.get("urdf_xml") is not None or description.get("urdf") is not None:
        return _geometry_from_urdf(model, _urdf_text(description), dirs, root, geometry)
    warnings.warn("this model was handed over as a pin.Model without a visual geometry model or URDF: "
                  "nothing of it can be drawn (pass geometry= to Multibody.from_model)", UserWarning, stacklevel=3)
    return VisualModel(model, pin.GeometryModel(), (), root, geometry, (), dirs)


def _geometry_from_records(model: pin.Model, records: list, dirs: tuple[str, ...], root: str) -> VisualModel:
    """Rebuild a visual geometry model from :func:`geoddp.models.multibody.geometry_records`:
    meshes loaded by coal (as Pinocchio's URDF parser does), primitives by size. A mesh file that
    is gone is left out with a warning naming it."""
    import coal

    if not isinstance(records, (list, tuple)):
        raise InputError("result.multibody.geometry_objects", f"expected a list of records, got {type(records).__name__}")
    gmodel = pin.GeometryModel()
    missing: list[str] = []
    loader = coal.MeshLoader()
    for i, rec in enumerate(records):
        where = f"result.multibody.geometry_objects[{i}]"
        try:
            joint = rec["joint"]
            if not model.existJointName(joint):
                raise InputError(where + ".joint", f"expected a joint of the model, got {joint!r}")
            jid = model.getJointId(joint)
            frame = rec.get("frame")
            fid = model.getFrameId(frame) if frame is not None and model.existFrame(frame) else 0
            placement = pin.SE3(np.asarray(rec["placement"], dtype=float))
            if "mesh" in rec:
                path = str(rec["mesh"])
                if not os.path.isfile(path):
                    missing.append(path)
                    continue
                scale = np.asarray(rec.get("scale", [1.0, 1.0, 1.0]), dtype=float)
                shape = loader.load(path, scale)
            else:
                kind = rec["shape"]
                if kind == "box":
                    shape = coal.Box(*np.asarray(rec["size"], dtype=float))
                elif kind == "sphere":
                    shape = coal.Sphere(float(rec["radius"]))
                elif kind == "cylinder":
                    shape = coal.Cylinder(float(rec["radius"]), float(rec["length"]))
                elif kind == "capsule":
                    shape = coal.Capsule(float(rec["radius"]), float(rec["length"]))
                else:
                    raise InputError(where + ".shape", f"expected box, sphere, cylinder or capsule, got {kind!r}")
            obj = pin.GeometryObject(str(rec["name"]), jid, fid, placement, shape)
            if "mesh" in rec:
                obj.meshPath = path
                obj.meshScale = scale
            obj.meshColor = np.asarray(rec.get("color", [0.8, 0.8, 0.8, 1.0]), dtype=float)
            obj.overrideMaterial = bool(rec.get("override_material", False))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(where, f"expected a geometry record (name, joint, placement, mesh or shape), got {exc!r}") from None
        gmodel.addGeometryObject(obj)
    for filename in missing:
        warnings.warn(f"mesh file {filename!r} not found: the visual objects using it are not drawn, the rest of the "
                      "model is", UserWarning, stacklevel=3)
    names = tuple(o.name.replace("/", "_") for o in gmodel.geometryObjects)
    return VisualModel(model, gmodel, names, root, "visual", tuple(missing), dirs)


def _geometry_from_urdf(model: pin.Model, xml: str, dirs: tuple[str, ...], root: str, geometry: str) -> VisualModel:
    """The URDF's visual (or collision) geometry on ``model``; meshes found nowhere left out."""
    missing: list[str] = []
    while True:
        try:
            gmodel = pin.buildGeomFromUrdfString(model, xml, _GEOMETRY_TYPE[geometry], package_dirs=list(dirs))
            break
        except (ValueError, RuntimeError) as exc:
            # Pinocchio resolves package:// URIs itself and stops at the first mesh it cannot find,
            # naming it: leave that mesh out and parse again (once per missing file).
            m = _MISSING_MESH.search(str(exc))
            if m is None or m.group(1) in missing:
                raise InputError("result.multibody", f"expected a valid URDF with loadable {geometry} geometry ({exc})") from None
            missing.append(m.group(1))
            xml = _without_mesh(xml, m.group(1))
    for name in [o.name for o in gmodel.geometryObjects if _is_placeholder(o)]:
        gmodel.removeGeometryObject(name)
    for filename in missing:
        warnings.warn(f"mesh file {filename!r} not found (searched package_dirs {list(dirs)} and ROS_PACKAGE_PATH): "
                      f"the {geometry} objects using it are not drawn, the rest of the model is", UserWarning, stacklevel=3)
    names = tuple(o.name.replace("/", "_") for o in gmodel.geometryObjects)
    return VisualModel(model, gmodel, names, root, geometry, tuple(missing), dirs)


def mesh_file(obj: pin.GeometryObject) -> str | None:
    """The resolved mesh file of a geometry object drawn from a file (DAE, STL, OBJ), else None."""
    path = getattr(obj, "meshPath", "") or ""
    if Path(path).suffix.lower() in (".dae", ".stl", ".obj") and os.path.isfile(path):
        return path
    return None


def mesh_bytes(visual: VisualModel) -> int:
    """Bytes of mesh data the replay embeds for one drawing of the model: the sum of the mesh
    files' sizes, each counted once per object that uses it (that is what the page carries)."""
    return sum(os.path.getsize(f) for f in (mesh_file(o) for o in visual.geometry.geometryObjects) if f)


def replay_configurations(result: Result, nq: int | None = None) -> np.ndarray:
    """The configuration sequence of ``result``, (H+1, nq); ``nq`` (the rebuilt model's) is checked
    when given.

    ``result.configurations`` for a multibody result (one with ``multibody``), else the unit
    quaternions (x, y, z, w) of ``result.rotations`` (the spherical root's q_k).

    Raises:
        InputError: naming ``result.configurations`` or ``result.rotations`` when missing, of the
            wrong shape for ``times`` (H+1,), or non-finite.
    """
    n = int(np.shape(result.times)[0])
    if n < 1:
        raise InputError("result.times", "expected at least one time step, got none")
    if isinstance(result, MultibodyResult) and result.multibody is not None:
        if result.configurations is None:
            raise InputError("result.configurations", "expected (H+1, nq) Pinocchio configurations, got None")
        Q = np.asarray(result.configurations, dtype=float)
        if Q.ndim != 2 or Q.shape[0] != n or (nq is not None and Q.shape[1] != nq):
            raise InputError("result.configurations", f"expected shape (H+1, nq) = ({n}, {'nq' if nq is None else nq}), got {Q.shape}")
        if not np.all(np.isfinite(Q)):
            raise InputError("result.configurations", "expected finite values, got NaN or inf")
        return Q
    R = np.asarray(result.rotations, dtype=float)
    if R.shape != (n, 3, 3):
        raise InputError("result.rotations", f"expected shape (H+1, 3, 3) = ({n}, 3, 3), got {R.shape}")
    if not np.all(np.isfinite(R)):
        raise InputError("result.rotations", "expected finite values, got NaN or inf")
    return rotations_to_quaternions(R)


def check_replayable(result: Result, geometry: str = "visual") -> tuple[VisualModel, np.ndarray]:
    """Check everything the replay reads, before anything is drawn or any server started.

    Args:
        result: the result to replay.
        geometry: "visual" or "collision", see :func:`load_visual_model`.

    Returns:
        (the rebuilt :class:`VisualModel`, the configurations (H+1, nq)).

    Raises:
        InputError: naming the parameter: see :func:`load_visual_model` and
            :func:`replay_configurations`; ``result.configurations`` not (H+1, nq) for the
            model's nq; ``result.dt`` not a positive number of seconds; ``result.target_rotation``
            not a finite (3, 3) array.
    """
    visual = load_visual_model(replay_description(as_result(result)), geometry)
    Q = replay_configurations(result, int(visual.model.nq))
    if not (np.isfinite(result.dt) and result.dt > 0):
        raise InputError("result.dt", f"expected a positive number of seconds, got {result.dt!r}")
    target = getattr(result, "target_rotation", None)
    if target is not None and not (np.shape(target) == (3, 3) and np.all(np.isfinite(target))):
        raise InputError("result.target_rotation", f"expected a finite (3, 3) rotation, got shape {np.shape(target)}")
    return visual, Q


def placements_at(visual: VisualModel, Q: np.ndarray) -> np.ndarray:
    """(N, n_objects, 4, 4) world placements oMg (metres) of every visual object at each row of
    ``Q`` (N, nq), from ``pin.forwardKinematics`` + ``pin.updateGeometryPlacements``."""
    model, gmodel = visual.model, visual.geometry
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    out = np.empty((Q.shape[0], gmodel.ngeoms, 4, 4))
    for k, q in enumerate(Q):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, gmodel, gdata)
        for i in range(gmodel.ngeoms):
            out[k, i] = gdata.oMg[i].homogeneous
    return out


def visual_placements(result: Result, visual: VisualModel | None = None) -> np.ndarray:
    """World placements of every visual object along the trajectory.

    Args:
        result: any result; see :func:`replay_description` and :func:`replay_configurations`.
        visual: the rebuilt model (rebuilt from the result's description if None).

    Returns:
        (H+1, n_objects, 4, 4) homogeneous transforms oMg (metres) at each q_k.
    """
    rebuilt, Q = check_replayable(result)
    return placements_at(visual or rebuilt, Q)


def ghost_configuration(result: Result, visual: VisualModel, Q: np.ndarray) -> np.ndarray | None:
    """The target pose drawn as a translucent ghost, or None when there is none to draw.

    The final configuration q_H with the root's rotation replaced by ``result.target_rotation``:
    for a satellite result, exactly R_d. Drawn only for a free-flyer or spherical root of a
    one-body model (every visual on the root body). ``Result.target_rotation`` of a multibody
    result is the rotation of the last terminal frame-placement term's frame, which the Result
    does not name: on an articulated model (the manipulator's target is its end effector's) it is
    not the root's, so no ghost is drawn there; nor for a fixed root, whose rotation is fixed.

    Returns:
        (nq,) configuration, or None.
    """
    target = getattr(result, "target_rotation", None)
    if target is None or visual.root not in _ROOT_QUATERNION or not visual.one_body:
        return None
    q = np.array(Q[-1], dtype=float)
    q[_ROOT_QUATERNION[visual.root]] = rotations_to_quaternions(np.asarray(target, dtype=float)[None])[0]
    return q


def _frame_id(model: pin.Model, frame: str, parameter: str) -> int:
    """Id of the frame named ``frame``; InputError naming ``parameter`` with close names if none."""
    names = [f.name for f in model.frames]
    if not isinstance(frame, str) or frame not in names:
        close = difflib.get_close_matches(str(frame), names, n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else f"; the model's frames are {names}"
        raise InputError(parameter, f"expected 'root' or a frame name of the model, got {frame!r}{hint}")
    return int(model.getFrameId(frame))


def frame_positions(visual: VisualModel, Q: np.ndarray, frame: str = "root") -> np.ndarray:
    """World positions (metres) of a frame at each configuration: the trail of the replay.

    Args:
        visual: the rebuilt model; Q: (N, nq) configurations.
        frame: a frame name of the model (e.g. the end effector's), or "root": the placement of
            the first joint (the root body: a free flyer's base), oMi[1].

    Returns:
        (N, 3) positions: ``oMf[frame].translation`` after ``pin.framesForwardKinematics`` (or
        ``oMi[1].translation`` after ``pin.forwardKinematics`` for "root").

    Raises:
        InputError: naming ``trail`` for an unknown frame name (with the closest names).
    """
    model = visual.model
    data = model.createData()
    out = np.empty((Q.shape[0], 3))
    if frame == "root":
        joint = 1 if model.njoints > 1 else 0
        for k, q in enumerate(Q):
            pin.forwardKinematics(model, data, q)
            out[k] = data.oMi[joint].translation
        return out
    fid = _frame_id(model, frame, "trail")
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        out[k] = data.oMf[fid].translation
    return out


def frame_targets(result: Result) -> list[tuple[str, np.ndarray]]:
    """The target placements of frames to draw as triads: ``"frame_targets"`` of the model
    description (``result.multibody``) and of ``result.extra``, in that order.

    Each entry is a dict ``{"frame": name, "placement": (4, 4) homogeneous world placement}`` or
    ``{"frame": name, "position": (3,) metres[, "rotation": (3, 3)]}`` (identity rotation if
    omitted). The frame name only labels the triad; the placement is in world coordinates.

    Returns:
        [(frame name, (4, 4) placement)], possibly empty.

    Raises:
        InputError: naming ``result.extra.frame_targets[i]`` (or ``result.multibody...``) when an
            entry is malformed or not finite.
    """
    out = []
    description = result.multibody if isinstance(result, MultibodyResult) else None
    sources = (("result.multibody.frame_targets", (description or {}).get("frame_targets")),
               ("result.extra.frame_targets", (getattr(result, "extra", None) or {}).get("frame_targets")))
    for where, entries in sources:
        if entries is None:
            continue
        if not isinstance(entries, (list, tuple)):
            raise InputError(where, f"expected a list of {{'frame', 'placement'}} dicts, got {type(entries).__name__}")
        for i, e in enumerate(entries):
            name = f"{where}[{i}]"
            if not isinstance(e, dict) or not isinstance(e.get("frame"), str):
                raise InputError(name, f"expected a dict with a 'frame' name, got {e!r}")
            M = np.eye(4)
            if "placement" in e:
                M = np.asarray(e["placement"], dtype=float)
                if M.shape != (4, 4):
                    raise InputError(name + ".placement", f"expected a (4, 4) homogeneous placement, got shape {M.shape}")
            elif "position" in e:
                pos = np.asarray(e["position"], dtype=float)
                if pos.shape != (3,):
                    raise InputError(name + ".position", f"expected a (3,) position in metres, got shape {pos.shape}")
                M[:3, 3] = pos
                if e.get("rotation") is not None:
                    R = np.asarray(e["rotation"], dtype=float)
                    if R.shape != (3, 3):
                        raise InputError(name + ".rotation", f"expected a (3, 3) rotation, got shape {R.shape}")
                    M[:3, :3] = R
            else:
                raise InputError(name, "expected 'placement' (4, 4) or 'position' (3,), got neither")
            if not np.all(np.isfinite(M)):
                raise InputError(name, "expected finite values, got NaN or inf")
            out.append((e["frame"], M))
    return out


def local_boxes(visual: VisualModel) -> np.ndarray:
    """(n_objects, 8, 3) corners (metres) of each object's axis-aligned box in its own geometry
    frame: coal's ``aabb_local`` (meshes are loaded by Pinocchio with their scale applied, so the
    box is the drawn size)."""
    out = np.zeros((visual.geometry.ngeoms, 8, 3))
    signs = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=float)
    for i, obj in enumerate(visual.geometry.geometryObjects):
        shape = obj.geometry
        shape.computeLocalAABB()
        lo, hi = np.asarray(shape.aabb_local.min_), np.asarray(shape.aabb_local.max_)
        out[i] = lo + signs * (hi - lo)
    return out


def trajectory_corners(visual: VisualModel, placements: np.ndarray) -> np.ndarray:
    """(N * n_objects * 8, 3) world points (metres): the corners of each object's local box
    (:func:`local_boxes`) placed by ``placements`` (N, n_objects, 4, 4) at every frame. Their
    convex hull holds every drawn object at every frame (a box is the hull of its corners)."""
    if placements.size == 0:
        return np.zeros((0, 3))
    corners = local_boxes(visual)  # (n, 8, 3)
    world = np.einsum("kiab,icb->kica", placements[:, :, :3, :3], corners) + placements[:, :, None, :3, 3]
    return world.reshape(-1, 3)


def trajectory_box(visual: VisualModel, placements: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned box (lower (3,), upper (3,), metres) holding every object over every
    frame of ``placements`` (N, n_objects, 4, 4): the box of :func:`trajectory_corners`, so every
    vertex of every drawn mesh at every frame lies inside."""
    pts = trajectory_corners(visual, placements)
    if pts.size == 0:
        return np.zeros(3), np.zeros(3)
    return pts.min(axis=0), pts.max(axis=0)
