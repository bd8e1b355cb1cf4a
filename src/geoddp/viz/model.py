"""The model a Result replays: rebuilt from a URDF, its visuals placed by forward kinematics.

One path for every result. The model comes from the result's description
(:func:`replay_description`): ``Result.multibody`` (the URDF text and root joint the solve used)
when present, else the built-in ``satellite.urdf`` with a spherical root, the one-body model of a
satellite (TSO(3)) result. The configuration sequence comes from the result
(:func:`replay_configurations`): ``Result.configurations`` (H+1, nq) for a multibody result, else
q_k = the unit quaternion (x, y, z, w) of ``rotations[k]``. The visual geometry comes from
``pin.buildGeomFromUrdfString(..., pin.GeometryType.VISUAL)`` and each object's world placement at
frame k is ``oMg`` from ``pin.forwardKinematics`` + ``pin.updateGeometryPlacements`` at q_k
(:func:`visual_placements`). The target pose of the root (:func:`ghost_configuration`) is the
final configuration with the root's rotation set to ``Result.target_rotation``.

The model is never rebuilt from the solver. Pure kinematics: drawing is :mod:`geoddp.viz.scene`.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..models.multibody import ROOTS, _root_joint
from ..models.satellite import DEFAULT_URDF as SATELLITE_URDF
from ..result import Result, rotations_to_quaternions
from ..validate import InputError

# Where the root joint's rotation sits in q (the quaternion (x, y, z, w)), for roots that have one.
_ROOT_QUATERNION = {"free_flyer": slice(3, 7), "spherical": slice(0, 4)}


@dataclass(frozen=True)
class VisualModel:
    """A rebuilt Pinocchio model with its visual geometry.

    Attributes:
        model: kinematic model (root joint as in the solve).
        geometry: its ``GeometryType.VISUAL`` geometry model.
        names: meshcat node name of each geometry object, in ``geometry.geometryObjects`` order.
        root: the root joint kind, one of ``ROOTS``.
    """

    model: pin.Model
    geometry: pin.GeometryModel
    names: tuple[str, ...]
    root: str = "fixed"

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
    description = getattr(result, "multibody", None)
    if description is not None:
        return description
    if result.configurations is not None:
        warnings.warn("this multibody result has no model description (Result.multibody): replaying only the "
                      "root body's attitude, on the satellite model", UserWarning, stacklevel=3)
    return satellite_description()


def load_visual_model(description: dict) -> VisualModel:
    """Rebuild the model and its visual geometry from a model description.

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
    return VisualModel(model, geometry, names, root)


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
    if getattr(result, "multibody", None) is not None:
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


def check_replayable(result: Result) -> tuple[VisualModel, np.ndarray]:
    """Check everything the replay reads, before anything is drawn or any server started.

    Returns:
        (the rebuilt :class:`VisualModel`, the configurations (H+1, nq)).

    Raises:
        InputError: naming the parameter: see :func:`load_visual_model` and
            :func:`replay_configurations`; ``result.configurations`` not (H+1, nq) for the
            model's nq; ``result.dt`` not a positive number of seconds; ``result.target_rotation``
            not a finite (3, 3) array.
    """
    visual = load_visual_model(replay_description(result))
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
