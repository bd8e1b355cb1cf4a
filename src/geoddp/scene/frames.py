"""Frame tables shared by the cost terms (:mod:`.multibody`) and the constraints
(:mod:`.constraints`): a frame name checked against the model, configurations, and a target
placement (translation and one rotation form, or the frame at ``at_configuration``)."""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from .. import validate as v
from .reader import Reader

ROTATION_FORMS = ("quaternion", "rotation", "axis")  # "axis" goes with "angle_deg"
POSE_KEYS = ("translation", "quaternion", "rotation", "axis", "angle_deg")


def frame_list(model: pin.Model, limit: int = 8) -> str:
    """The model's frame names (the first ``limit``), for messages."""
    names = [f.name for f in model.frames if f.name != "universe"]
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f", ... ({len(names)} frames)" if len(names) > limit else "")


def read_configuration(r: Reader, val: Any, pm: pin.Model, path: str) -> np.ndarray:
    """A normalised configuration (nq,) of ``pm`` at ``path``."""
    q = r.check(v.finite_array, val, path, (pm.nq,))
    if not pin.isNormalized(pm, q, 1e-9):
        raise r.err(path, "expected a configuration with unit quaternions and unit (cos, sin) pairs "
                    "(to 1e-9), got a non-normalised one")
    return q


def read_frame(r: Reader, t: Mapping[str, Any], path: str, pm: pin.Model) -> tuple[str, pin.SE3 | None]:
    """The ``frame`` of a frame table (a cost term or a constraint at ``path``), checked against the
    model (did you mean), and its placement at ``at_configuration`` if the table has one, else None."""
    if "frame" not in t:
        raise r.err(f"{path}.frame", "missing required key (a frame name of the model)")
    frame = t["frame"]
    if not isinstance(frame, str):
        raise r.err(f"{path}.frame", f"expected a frame name (string), got {frame!r}")
    if not pm.existFrame(frame):
        guess = v.closest(frame, [f.name for f in pm.frames])
        hint = f"did you mean {guess!r}? " if guess else ""
        raise r.err(f"{path}.frame", f"expected a frame of model {pm.name!r}, got {frame!r}; {hint}"
                    f"frames: {frame_list(pm)}")
    if "at_configuration" in t:
        q = read_configuration(r, t["at_configuration"], pm, f"{path}.at_configuration")
        data = pm.createData()
        pin.framesForwardKinematics(pm, data, q)
        return frame, data.oMf[pm.getFrameId(frame)].copy()
    return frame, None


def placement_reference(r: Reader, t: Mapping[str, Any], path: str, M_at: pin.SE3 | None) -> np.ndarray:
    """The (4, 4) target placement of a frame_placement table (cost term or terminal constraint):
    ``M_at`` (the frame at ``at_configuration``, from :func:`read_frame`) or translation (m)
    and one rotation form (quaternion | rotation | axis + angle_deg)."""
    if M_at is None:
        if "translation" not in t:
            raise r.err(f"{path}.translation", "missing: a frame_placement reference needs translation and a "
                        "rotation (quaternion | rotation | axis + angle_deg), or at_configuration")
        p = r.check(v.finite_array, t["translation"], f"{path}.translation", (3,))
        R = r.rotation(t, path, ROTATION_FORMS)
        M_at = pin.SE3(R, p)
    return M_at.homogeneous
