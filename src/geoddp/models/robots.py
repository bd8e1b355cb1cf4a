"""Real robots by name: the URDFs, SRDF postures and meshes of ``example-robot-data``.

``example-robot-data`` (the optional extra ``geoddp[robots]``) ships URDFs, SRDFs and meshes of
some fifty robots; its loader classes (``example_robot_data.ROBOTS``) name, per robot, the URDF,
the SRDF, whether the root is a free flyer and the SRDF's reference posture. :func:`find` reads
only those class attributes (the loaders themselves are never instantiated: that would parse the
URDF and load every mesh) and returns a :class:`RobotSpec`; :meth:`RobotSpec.multibody` builds the
:class:`geoddp.models.multibody.Multibody` from the URDF path, and :meth:`RobotSpec.pin_models`
builds the ``pin.Model`` with its visual ``pin.GeometryModel`` for users who edit the model
before :meth:`Multibody.from_model <geoddp.models.multibody.Multibody.from_model>`.

Mesh URIs resolve as Pinocchio's URDF parser resolves them (:func:`resolve_mesh`):
``package://PKG/REST`` is searched in the given ``package_dirs`` in order, then in the
directories of ``ROS_PACKAGE_PATH`` and ``AMENT_PREFIX_PATH`` (each with ``/share``) as
``<dir>/PKG/REST``; ``file://PATH`` and absolute paths are taken as they are; a relative path is
relative to the URDF's directory. Scenes and the replay also search, after the given
directories, the URDF's directory, its parent and grandparent and example-robot-data's package
directory (:func:`default_package_dirs`). A ``package://`` URI whose package is in none of these
directories is a configuration error (InputError naming ``package_dirs``); a package that is
found but lacks one mesh file is a missing mesh: the solve does not need meshes, and the replay
draws the rest of the model and names the missing file.

Postures (:func:`configuration`): "neutral" (``pin.neutral``) or any ``group_state`` of the
robot's SRDF (``pin.loadReferenceConfigurations``: "standing", "half_sitting", ...), optionally
with a mapping of joint names to values on top (radians or metres for one-coordinate joints, the
joint's nq coordinates as a list otherwise).
"""
from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .urdf import captured_stderr, parse_xml, read_urdf_text, read_xml_text
from ..validate import InputError, closest
from .multibody import Multibody, package_dir_tuple

__all__ = ["RobotSpec", "names", "find", "resolve_mesh", "mesh_uris", "check_meshes", "default_package_dirs",
           "example_robot_data_dir", "postures", "check_srdf_text", "configuration", "load"]

INSTALL_HINT = "pip install 'geoddp[robots]' (example-robot-data and its loaders)"
_MESH = re.compile(r"<mesh\b[^>]*\bfilename\s*=\s*([\"'])(.*?)\1", re.S)


def _erd():
    """The ``example_robot_data`` module, or InputError naming ``robot`` when not installed."""
    try:
        import example_robot_data
    except ImportError:
        raise InputError("robot", f"robots by name need example-robot-data: {INSTALL_HINT}") from None
    return example_robot_data


@dataclass(frozen=True)
class RobotSpec:
    """Where a robot of ``example-robot-data`` lives and how its loader builds it.

    Attributes:
        name: its name in ``example_robot_data.ROBOTS`` ("ur5", "panda", "solo12", ...).
        urdf: absolute path of the URDF.
        srdf: absolute path of the SRDF (postures), or None.
        root: "free_flyer" when its loader adds a free-flyer root, else "fixed".
        package_dirs: directories ``package://`` URIs of the URDF are searched in (the
            ``share`` directory holding ``example-robot-data/robots/...``).
        default_posture: the loader's reference posture (a group_state of the SRDF), or None.
        loader_model: True when the loader changes the model its URDF gives ("talos_legs": Talos'
            URDF cut to its legs); that robot's model is then the loader's
            (``example_robot_data.load(name).model``), not the URDF's.
    """

    name: str
    urdf: Path
    srdf: Path | None
    root: str
    package_dirs: tuple[str, ...]
    default_posture: str | None
    loader_model: bool = False

    def multibody(self, *, dt: float, root: str | None = None, **kwargs: Any) -> Multibody:
        """The :class:`Multibody` of this robot from its URDF (root: the loader's unless given;
        other keywords as for ``Multibody``: actuation, integrator, gravity, backend, threads;
        ``package_dirs`` given here are searched for meshes before the robot's own)."""
        dirs = (*package_dir_tuple(kwargs.pop("package_dirs", ())), *self.package_dirs)
        return Multibody(self.urdf, root=root or self.root, dt=dt, package_dirs=dirs, **kwargs)

    def pin_models(self, root: str | None = None) -> tuple[pin.Model, pin.GeometryModel]:
        """(model, visual geometry) as ``pin.buildModelsFromUrdf`` builds them, meshes loaded:
        what a Pinocchio user edits (inertias, ``pin.buildReducedModel``) before
        :meth:`Multibody.from_model`."""
        rj = pin.JointModelFreeFlyer() if (root or self.root) == "free_flyer" else None
        args = (str(self.urdf), list(self.package_dirs)) + ((rj,) if rj is not None else ())
        model, visual = pin.buildModelsFromUrdf(*args, geometry_types=pin.GeometryType.VISUAL)
        return model, visual

    def postures(self, model: pin.Model) -> dict[str, np.ndarray]:
        """Named configurations (nq,) of ``model``: "neutral" and the SRDF's group states."""
        return postures(model, self.srdf)


def names() -> tuple[str, ...]:
    """Names of the robots ``example-robot-data`` describes by a URDF, sorted."""
    erd = _erd()
    return tuple(sorted(n for n, cls in erd.ROBOTS.items() if getattr(cls, "urdf_filename", "")))


def find(name: Any, parameter: str = "robot") -> RobotSpec:
    """The robot called ``name`` in ``example-robot-data`` (remembered per ``sys.path`` while its
    URDF and SRDF files are there).

    Raises:
        InputError: naming ``parameter``: not a string, an unknown name (with the closest names
            and the full list), a robot described only by an SDF file, or example-robot-data
            not installed (with the pip command).
    """
    import sys

    # found before on this search path and its files still there: the same (a sweep looks up one
    # robot per case; the lookup resolves paths through example-robot-data, about 1 ms)
    key = (name, tuple(sys.path)) if isinstance(name, str) else None
    spec = _FOUND.get(key)
    if spec is not None and spec.urdf.is_file() and (spec.srdf is None or spec.srdf.is_file()):
        return spec
    erd = _erd()
    known = names()
    if not isinstance(name, str) or name not in known:
        import difflib

        close = difflib.get_close_matches(str(name), known, n=3) or [g for g in [closest(str(name), known)] if g]
        hint = f"did you mean {', '.join(map(repr, close))}? " if close else ""
        raise InputError(parameter, f"expected a robot of example-robot-data, got {name!r}; {hint}known robots: {', '.join(known)}")
    cls = erd.ROBOTS[name]
    subpath = os.path.join(cls.path, cls.urdf_subpath, cls.urdf_filename)
    try:
        robots = Path(erd.getModelPath(subpath))
    except OSError:
        raise InputError(parameter, f"expected the files of robot {name!r} to be installed, got none at {subpath} "
                                    f"({INSTALL_HINT})") from None
    urdf = (robots / subpath).resolve()
    srdf = None
    if getattr(cls, "srdf_filename", ""):
        p = robots / cls.path / cls.srdf_subpath / cls.srdf_filename
        srdf = p.resolve() if p.is_file() else None
    posture = getattr(cls, "ref_posture", None) if srdf is not None else None
    # URIs read package://example-robot-data/robots/...: the package directory is robots/../..
    spec = RobotSpec(name, urdf, srdf, "free_flyer" if getattr(cls, "free_flyer", False) else "fixed",
                     (str(robots.parent.parent.resolve()),), posture, _loader_edits_model(cls))
    if len(_FOUND) >= 64:
        _FOUND.clear()
    _FOUND[key] = spec
    return spec


def _loader_edits_model(cls) -> bool:
    """Whether example-robot-data's loader class ``cls`` does more than load its URDF (it defines
    its own constructor: talos_legs, human, panda_collision)."""
    try:
        from example_robot_data.utils import RobotLoader
    except ImportError:  # another layout of the loaders: assume the URDF's model
        return False
    return cls.__init__ is not RobotLoader.__init__


_FOUND: dict[tuple[str, tuple[str, ...]] | None, RobotSpec] = {}  # (name, sys.path) -> where it was found


def example_robot_data_dir() -> str | None:
    """The package directory of the installed ``example-robot-data`` (the folder holding
    ``example-robot-data/robots/...``, which its URDFs' ``package://example-robot-data/...`` URIs
    name), or None when it is not installed.

    Found by the rule ``example_robot_data.getModelPath`` uses (``<entry>/../../../share`` for each
    ``sys.path`` entry), so the data package alone is enough: its Python loaders are not imported.
    """
    import sys

    # found once per search path and re-checked (scanning sys.path took 0.5 ms a scene)
    path = tuple(sys.path)
    known = _ERD_DIR.get(path)
    if known is not None and os.path.isdir(os.path.join(known, "example-robot-data", "robots")):
        return known
    for entry in path:
        share = Path(entry or ".") / ".." / ".." / ".." / "share"
        if (share / "example-robot-data" / "robots").is_dir():
            found = str(share.resolve())
            _ERD_DIR.clear()
            _ERD_DIR[path] = found
            return found
    return None


_ERD_DIR: dict[tuple[str, ...], str] = {}  # sys.path -> the package directory found on it


def default_package_dirs(urdf: str | Path | None) -> tuple[str, ...]:
    """Where ``package://`` URIs are searched after the given package_dirs (the replay searches
    the same, :func:`geoddp.viz.model.package_dirs`): the URDF's own directory, its parent and its
    grandparent (``<pkg>/urdf/robot.urdf`` naming ``package://<pkg>/meshes/...``), then the package
    directory of example-robot-data when installed."""
    dirs = []
    if urdf:
        here = Path(str(urdf)).resolve().parent
        dirs += [str(here), str(here.parent), str(here.parent.parent)]
    erd = example_robot_data_dir()
    if erd is not None:
        dirs.append(erd)
    return tuple(dict.fromkeys(dirs))


def _search_dirs(package_dirs: tuple[str, ...] | list[str]) -> list[str]:
    dirs = [str(d) for d in package_dirs]
    for var, suffix in (("ROS_PACKAGE_PATH", ""), ("AMENT_PREFIX_PATH", "share")):
        dirs += [os.path.join(d, suffix) if suffix else d for d in os.environ.get(var, "").split(os.pathsep) if d]
    return dirs


def resolve_mesh(uri: str, package_dirs: tuple[str, ...] | list[str] = (), base_dir: str | Path | None = None,
                 parameter: str = "package_dirs") -> Path | None:
    """The file a URDF mesh ``filename`` names, resolved as Pinocchio resolves it (module
    docstring), or None when its package is found but the file is not (a missing mesh).

    Args:
        uri: ``package://PKG/REST``, ``file://PATH``, an absolute or a relative path.
        package_dirs: directories searched first for ``package://`` URIs.
        base_dir: the URDF's directory (relative paths); the current directory if None.
        parameter: named in the error.

    Raises:
        InputError: naming ``parameter`` when a ``package://`` URI's package is in none of the
            directories searched (they are listed).
    """
    if uri.startswith("package://"):
        rest = uri[len("package://"):]
        package = rest.split("/", 1)[0]
        dirs = _search_dirs(package_dirs)
        for d in dirs:
            if os.path.isfile(os.path.join(d, rest)):
                return Path(d, rest).resolve()
        if not any(os.path.isdir(os.path.join(d, package)) for d in dirs):
            raise InputError(parameter, f"expected a directory holding package {package!r} (for {uri!r}), got none among "
                                        f"{dirs or '[] (no package_dirs, ROS_PACKAGE_PATH or AMENT_PREFIX_PATH)'}")
        return None
    path = Path(uri[len("file://"):] if uri.startswith("file://") else uri)
    if not path.is_absolute():
        path = Path(base_dir or ".") / path
    try:
        return path.resolve() if path.is_file() else None
    except (OSError, ValueError):  # a name too long for the file system, a NUL: no such file, a missing mesh
        return None


def mesh_uris(urdf: str | Path, parameter: str = "urdf") -> list[str]:
    """Every distinct ``<mesh filename>`` of a URDF file, in order (the file read as the model
    builder reads it, :func:`geoddp.models.urdf.read_urdf_text`: InputError naming ``parameter``
    and the file if it is not text)."""
    text = read_urdf_text(urdf, parameter)
    return list(dict.fromkeys(m.group(2) for m in _MESH.finditer(text)))


def check_meshes(urdf: str | Path, package_dirs: tuple[str, ...] | list[str] = (),
                 parameter: str = "package_dirs", urdf_parameter: str = "urdf") -> list[str]:
    """Resolve every mesh of a URDF (:func:`resolve_mesh`) as the replay will: in
    ``package_dirs``, then :func:`default_package_dirs`; the URIs of the missing ones. When this
    process found every one of the same URIs, from the same folder and search path, before, the
    files found then are checked again on disk instead (a missing one resolves everything anew).

    Raises:
        InputError: naming ``parameter`` for a ``package://`` URI whose package is found nowhere;
            naming ``urdf_parameter`` and the file for a URDF that is not text (:func:`mesh_uris`).
    """
    base = Path(urdf).resolve().parent
    dirs = list(dict.fromkeys([str(d) for d in package_dirs] + list(default_package_dirs(urdf))))
    uris = mesh_uris(urdf, urdf_parameter)
    # every mesh found before, from the same URIs, folder and search path, and still there: found
    # again (a sweep checks the same robot for every case; resolving its meshes took 1.5-2.7 ms)
    key = (str(base), tuple(uris), tuple(_search_dirs(dirs)))
    files = _RESOLVED.get(key)
    if files is not None and all(os.path.isfile(f) for f in files):
        return []
    found = [resolve_mesh(u, dirs, base, parameter) for u in uris]
    missing = [u for u, f in zip(uris, found) if f is None]
    if not missing:
        if len(_RESOLVED) >= 64:
            _RESOLVED.clear()
        _RESOLVED[key] = tuple(str(f) for f in found)
    return missing


# (URDF folder, mesh URIs, search path) -> the files they resolved to, when every one was found
_RESOLVED: dict[tuple[str, tuple[str, ...], tuple[str, ...]], tuple[str, ...]] = {}


def postures(model: pin.Model, srdf: str | Path | None, parameter: str = "srdf") -> dict[str, np.ndarray]:
    """Named configurations (nq,) of ``model``: "neutral" (``pin.neutral``) and each
    ``group_state`` of the SRDF (``pin.loadReferenceConfigurationsFromXML``: joints the state does
    not name keep their neutral value, joints the model lacks are skipped; quaternions normalised).

    The SRDF is read as a URDF is (:func:`geoddp.models.urdf.read_xml_text`: its encoding, no
    entity declarations) and checked before Pinocchio reads it (:func:`check_srdf_text`), because
    Pinocchio prints "Could not read joint config" for a value it cannot read and keeps the
    joint's neutral value: a posture that silently differs from the file.

    Raises:
        InputError: naming ``parameter`` and the file: not text, not well-formed XML, no
            ``<robot>`` root, a group state or joint without a name, a joint value that is not
            the joint's coordinates (nq finite numbers; one angle for a continuous joint).
    """
    out = {"neutral": pin.neutral(model)}
    if srdf is not None:
        text = read_xml_text(srdf, parameter, "SRDF")
        check_srdf_text(text, model, parameter, srdf)
        m = pin.Model(model)  # loading writes into the model: keep the caller's untouched
        with captured_stderr() as said:
            try:
                pin.loadReferenceConfigurationsFromXML(m, text, False)
            except (RuntimeError, ValueError) as exc:
                raise InputError(parameter, f"{srdf}: expected an SRDF file Pinocchio can read ({exc})") from None
        if said:  # a value Pinocchio could not read despite the checks: refused, not guessed
            raise InputError(parameter, f"{srdf}: {'; '.join(said[-3:])}")
        for entry in m.referenceConfigurations:  # boost map entries: .key(), .data()
            out[str(entry.key())] = pin.normalize(m, np.array(entry.data(), dtype=float))
    return out


def check_srdf_text(text: str, model: pin.Model, parameter: str = "srdf", path: str | Path = "SRDF") -> None:
    """Refuse, naming ``parameter``, the file, the group state and the joint: an SRDF that is not
    well-formed XML or has no ``<robot>`` root, a ``group_state`` or one of its joints without a
    name, and a value of a joint of ``model`` that is not its nq finite numbers (one angle for a
    continuous joint, as Pinocchio reads it); elements nested too deep for Pinocchio's reader
    (:func:`geoddp.models.urdf.parse_xml`)."""
    root = parse_xml(text, parameter, f"{path}: ")
    if root.tag != "robot":
        raise InputError(parameter, f"{path}: expected an SRDF (a <robot> root element), got <{root.tag}>")
    for state in root.findall("group_state"):
        sname = state.get("name")
        if not sname:
            raise InputError(parameter, f"{path}: a <group_state> without a name")
        for joint in state.findall("joint"):
            jname = joint.get("name")
            if not jname:
                raise InputError(parameter, f"{path}: group_state {sname!r}: a <joint> without a name")
            if not model.existJointName(jname):
                continue  # Pinocchio skips it (an SRDF may describe a larger model than a reduced one)
            jm = model.joints[model.getJointId(jname)]
            want = 1 if (jm.nq == 2 and jm.nv == 1) else jm.nq  # a continuous joint's angle
            raw = joint.get("value")
            try:
                vals = [float(x) for x in (raw or "").split()]
            except ValueError:
                vals = []
            if len(vals) != want or not all(math.isfinite(x) for x in vals):
                raise InputError(parameter, f"{path}: group_state {sname!r}, joint {jname!r}: value = {raw!r}, expected "
                                 f"{want} finite number{'s' if want > 1 else ''}")


def _joint_value(model: pin.Model, joint: str, value: Any, q: np.ndarray, path: str) -> None:
    jid = model.getJointId(joint)
    jm = model.joints[jid]
    i, nq, nv = jm.idx_q, jm.nq, jm.nv
    if nq == 1 or (nq == 2 and nv == 1):  # revolute / prismatic, or continuous (cos, sin)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise InputError(path, f"expected a finite number (rad or m) for joint {joint!r}, got {value!r}")
        if nq == 1:
            q[i] = float(value)
        else:
            q[i:i + 2] = np.cos(value), np.sin(value)
        return
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.shape != (nq,) or not np.all(np.isfinite(arr)):
        raise InputError(path, f"expected the {nq} coordinates of joint {joint!r} ({jm.shortname()}), got {value!r}")
    q[i:i + nq] = arr


def configuration(model: pin.Model, named: Mapping[str, np.ndarray], posture: Any = "neutral",
                  joints: Mapping[str, Any] | None = None, parameter: str = "initial.q") -> np.ndarray:
    """A configuration (nq,): the posture called ``posture`` with ``joints`` set on top.

    Args:
        model: the model the configuration is for.
        named: the named postures (:func:`postures`).
        posture: a name in ``named``.
        joints: joint name -> value: a number (rad, or m for a prismatic joint) for a
            one-degree-of-freedom joint (a continuous joint's angle is written as (cos, sin)),
            else the joint's nq coordinates (a free flyer's (x, y, z, qx, qy, qz, qw)).
        parameter: named in errors (``initial.q``; ``initial.joints.<name>`` for a joint).

    Raises:
        InputError: an unknown posture or joint name (with the closest names), a value of the
            wrong kind, or a result that is not a normalised configuration.
    """
    if not isinstance(posture, str) or posture not in named:
        import difflib

        keys = list(named)
        close = difflib.get_close_matches(str(posture), keys, n=3) or [g for g in [closest(str(posture), keys)] if g]
        hint = f"did you mean {', '.join(map(repr, close))}? " if close else ""
        raise InputError(parameter, f"expected a named posture, got {posture!r}; {hint}postures: {', '.join(keys)}")
    q = np.array(named[posture], dtype=float)
    if joints:
        if not isinstance(joints, Mapping):
            raise InputError(parameter, f"expected a mapping of joint names to values, got {type(joints).__name__}")
        jnames = [str(n) for n in model.names[1:]]
        base = parameter.rsplit(".", 1)[0] if "." in parameter else parameter
        for joint, value in joints.items():
            path = f"{base}.joints.{joint}"
            if joint not in jnames:
                import difflib

                close = difflib.get_close_matches(str(joint), jnames, n=3)
                hint = f"; did you mean {', '.join(map(repr, close))}?" if close else f"; joints: {', '.join(jnames)}"
                raise InputError(path, f"expected a joint name of the model, got {joint!r}{hint}")
            _joint_value(model, joint, value, q, path)
    if not pin.isNormalized(model, q, 1e-9):
        raise InputError(parameter, "expected unit quaternions, got a non-normalised configuration")
    return q


def load(name: str, *, dt: float, root: str | None = None, check_mesh_dirs: bool = True, **kwargs: Any) -> Multibody:
    """The :class:`Multibody` of robot ``name`` of example-robot-data (from its URDF; see
    :meth:`RobotSpec.multibody` for the keywords). ``check_mesh_dirs`` resolves every mesh URI in
    the model's package folders (:func:`check_meshes`) before it is returned, so a broken
    installation fails here rather than in the replay."""
    model = find(name).multibody(dt=dt, root=root, **kwargs)
    if check_mesh_dirs:
        check_meshes(model.urdf, model.package_dirs)
    return model
