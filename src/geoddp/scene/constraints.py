"""The ``[[constraints]]`` (path: every node k = 1..H) and ``[[terminal_constraints]]`` (k = H)
tables of both scene kinds, read into :mod:`geoddp.constraints` objects.

Schema (``?`` = optional; every table has ``type`` and ``name?``)::

    type = "pointing_keep_out"      body_axis (3, body frame), world_direction (3), min_angle_deg in
                                    (0, 180), frame? (a satellite's body by default; required on a
                                    multibody model)
    type = "joint_limits"           joints? = {NAME = [lower, upper], ...} (1-dof revolute / prismatic;
                                    rad, m; -inf / inf for an open side), position? = "urdf",
                                    velocity? = {NAME = [lower, upper], ...}; at least one of them
    type = "frame_halfspace"        frame, normal (3), offset (m): normal . p_frame >= offset
    type = "frame_sphere_keep_out"  frame, centre (3, m), radius (m, > 0): |p_frame - centre| >= radius
    type = "frame_placement"        terminal only: frame, translation + one of quaternion | rotation |
                                    axis + angle_deg, or at_configuration (nq) (as the frame_placement cost)
    type = "state"                  terminal only: q? (nq: on the satellite the quaternion x, y, z, w),
                                    v? (nv); at least one

The tolerance every constraint is met to is ``[solver].constraint_tol`` (default 1e-8, in each
constraint's units). Errors name the key path (``constraints[1].min_angle_deg: expected ...``),
suggest the closest key or frame or joint name, and name the file.
"""
from __future__ import annotations

from collections.abc import Mapping
from types import SimpleNamespace
from typing import Any

import pinocchio as pin

from .. import validate as v
from ..constraints import KINDS, TERMINAL_ONLY, Constraint
from ..validate import InputError
from .frames import POSE_KEYS, placement_reference, read_frame
from .reader import Reader

ARRAYS = ("constraints", "terminal_constraints")
_KEYS: dict[str, tuple[str, ...]] = {
    "pointing_keep_out": ("body_axis", "world_direction", "min_angle_deg", "frame"),
    "joint_limits": ("joints", "position", "velocity"),
    "frame_halfspace": ("frame", "normal", "offset"),
    "frame_sphere_keep_out": ("frame", "centre", "radius"),
    "frame_placement": ("frame", "at_configuration") + POSE_KEYS,
    "state": ("q", "v"),
}
_REQUIRED: dict[str, tuple[str, ...]] = {
    "pointing_keep_out": ("body_axis", "world_direction", "min_angle_deg"),
    "frame_halfspace": ("frame", "normal", "offset"),
    "frame_sphere_keep_out": ("frame", "centre", "radius"),
    "frame_placement": ("frame",),
}


def read_constraints(r: Reader, pm: pin.Model, default_frame: str | None = None
                     ) -> tuple[tuple[Constraint, ...], tuple[Constraint, ...]]:
    """The scene's path and terminal constraints, each checked against the model ``pm`` (frames,
    joints, sizes) so that a bad table fails here, naming its key path.

    Args:
        r: the scene's reader (its schema lists :data:`ARRAYS` among its arrays).
        pm: the scene's ``pin.Model`` (the satellite's one body on a spherical root, or the multibody).
        default_frame: the frame a pointing constraint without ``frame`` uses (the satellite's
            body), or None (a multibody scene: frame required).
    """
    path = tuple(_read(t, p, r, pm, default_frame, terminal=False) for p, t in r.array("constraints"))
    terminal = tuple(_read(t, p, r, pm, default_frame, terminal=True) for p, t in r.array("terminal_constraints"))
    return path, terminal


def _read(t: Mapping[str, Any], path: str, r: Reader, pm: pin.Model, default_frame: str | None,
          terminal: bool) -> Constraint:
    if "type" not in t:
        raise r.err(f"{path}.type", f"missing required key (one of {' | '.join(KINDS)})")
    kind = r.check(v.choice, t["type"], f"{path}.type", tuple(KINDS))
    r.keys(t, ("type", "name") + _KEYS[kind], path, context=f' (type = "{kind}")')
    if kind in TERMINAL_ONLY and not terminal:
        raise r.err(f"{path}.type", f'a "{kind}" equality pins the state at every node of [[constraints]]; it is a '
                    "terminal constraint: put it in [[terminal_constraints]]")
    for key in _REQUIRED.get(kind, ()):
        if key not in t:
            raise r.err(f"{path}.{key}", f'missing required key for type = "{kind}"')
    kw = {k: t[k] for k in _KEYS[kind] if k in t}
    if "name" in t:
        kw["name"] = r.string(t["name"], f"{path}.name")
    M_at = None
    if "frame" in t:
        kw["frame"], M_at = read_frame(r, t, path, pm)  # did you mean, the model's frames listed
    if kind == "pointing_keep_out" and "frame" not in t:
        kw["frame"] = default_frame
    if kind == "frame_placement":
        refs = [k for k in POSE_KEYS if k in t]
        if M_at is not None and refs:
            raise r.err(f"{path}.at_configuration", f"expected either at_configuration or an explicit reference, "
                        f"got both (with {', '.join(refs)})")
        placement = placement_reference(r, t, path, M_at)
        kw = {"frame": kw["frame"], "placement": placement, **({"name": kw["name"]} if "name" in kw else {})}
    if kind == "state" and "q" not in t and "v" not in t:
        raise r.err(path, 'expected q and/or v (type = "state")')
    try:
        c = KINDS[kind](**kw)
        # bound once to the scene's model: unknown frames and joints, sizes, unsupported joints
        c.bind(SimpleNamespace(pin_model=pm))
    except InputError as e:
        raise r.err(f"{path}.{e.parameter}", e.detail) from None
    return c
