"""The keep-out figure: a body axis's path on the unit sphere with the keep-out cone drawn.

For a result whose constraints include a ``pointing_keep_out`` (``result.extra["constraints"]``,
:func:`geoddp.constraints.solve_constrained`), the left panel draws the unit sphere, the cone
around the world direction d (its rim on the sphere, the cap inside it shaded, a few generators
from the origin), and the boresight y_k = R_f,k a at every node k (the frame's world rotation
times the body axis), start and end marked; optionally the unconstrained solve's path for
comparison. The right panel is the angle between y_k and d against time, with the cone's
half-angle as a line. Reads Results only (the frame's rotation through the result's own model
description, as the replay rebuilds it); drawn on an Agg canvas, written atomically.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..output_files import check_outputs, write_atomic
from ..solver.result import Result, as_result
from ..validate import InputError
from .figures import DPI, FigureData
from .model import check_replayable

__all__ = ["plot_keep_out", "boresight", "keep_out_constraint", "PATH_COLOR", "FREE_COLOR", "CONE_COLOR"]

PATH_COLOR = "#1f77b4"  # the constrained path (matplotlib's tab:blue)
FREE_COLOR = "#ff7f0e"  # the unconstrained path (tab:orange)
CONE_COLOR = "#d62728"  # the cone (tab:red)


def keep_out_constraint(result: Result, name: str | None = None) -> dict[str, Any]:
    """The ``definition`` of a pointing_keep_out constraint of ``result`` (the first, or the one
    called ``name``): body_axis, world_direction (unit), min_angle_deg, frame.

    Raises:
        InputError: naming ``result`` (no constraints report, no pointing_keep_out) or ``name``.
    """
    report = as_result(result).extra.get("constraints")
    if not report:
        raise InputError("result", "expected a result of a constrained solve (extra['constraints']), got none")
    items = [it for it in report.get("items", []) if it.get("type") == "pointing_keep_out"]
    if not items:
        raise InputError("result", "expected a pointing_keep_out constraint among the result's constraints, got "
                         f"{[it.get('type') for it in report.get('items', [])]}")
    if name is not None:
        named = [it for it in items if it.get("name") == name]
        if not named:
            raise InputError("name", f"expected one of {[it.get('name') for it in items]}, got {name!r}")
        items = named
    return dict(items[0]["definition"])


def boresight(result: Result, body_axis: Any, frame: str | None = None) -> np.ndarray:
    """(H+1, 3) the unit body axis ``body_axis`` of ``frame`` in the world at every node: R_k a for
    the root body of a satellite result (frame None or its body frame), else the frame's world
    rotation from the result's model (Pinocchio's forward kinematics of its configurations)."""
    a = np.asarray(body_axis, dtype=float)
    a = a / np.linalg.norm(a)
    result = as_result(result)
    if frame is None:
        return np.asarray(result.rotations, dtype=float) @ a
    visual, Q = check_replayable(result)
    model = visual.model
    if not model.existFrame(frame):
        raise InputError("frame", f"expected a frame of the result's model, got {frame!r}")
    fid = model.getFrameId(frame)
    data = model.createData()
    out = np.empty((Q.shape[0], 3))
    for k, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        out[k] = data.oMf[fid].rotation @ a
    return out


def _angles_deg(y: np.ndarray, d: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(y @ d, -1.0, 1.0)))


def _cone_rim(d: np.ndarray, alpha: float, n: int = 181) -> np.ndarray:
    """(n, 3) points of the unit sphere at angle alpha (rad) from d."""
    e1 = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return np.cos(alpha) * d + np.sin(alpha) * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)


def plot_keep_out(result: Result, path: str | Path, unconstrained: Result | None = None,
                  name: str | None = None) -> FigureData:
    """Draw the keep-out figure of ``result`` into the PNG ``path`` (written atomically).

    Args:
        result: a constrained solve with a pointing_keep_out constraint.
        path: the PNG file.
        unconstrained: optionally the same problem solved without the constraint: its path is
            drawn too (dashed), e.g. to show that it crosses the cone.
        name: which pointing_keep_out constraint (by its name), if there are several.

    Returns:
        :class:`FigureData` with ``boresight`` (H+1, 3) (unit vectors), ``angle_deg`` (H+1,) (the
        angle to the direction, degrees), ``t`` (H+1,) s, ``cone_rim`` (n, 3), ``direction`` (3,),
        ``min_angle_deg`` (), and with ``unconstrained`` also ``free_boresight``, ``free_angle_deg``.
    """
    check_outputs({"path": path})
    definition = keep_out_constraint(result, name)
    d = np.asarray(definition["world_direction"], dtype=float)
    d /= np.linalg.norm(d)
    alpha = np.radians(float(definition["min_angle_deg"]))
    frame = definition.get("frame")
    y = boresight(result, definition["body_axis"], frame)
    arrays: dict[str, np.ndarray] = {"boresight": y, "angle_deg": _angles_deg(y, d),
                                     "t": np.asarray(result.times, dtype=float), "cone_rim": _cone_rim(d, alpha),
                                     "direction": d, "min_angle_deg": np.array(np.degrees(alpha))}
    if unconstrained is not None:
        yf = boresight(unconstrained, definition["body_axis"], frame)
        arrays["free_boresight"], arrays["free_angle_deg"] = yf, _angles_deg(yf, d)

    fig = Figure(figsize=(11.0, 5.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    u, v = np.mgrid[0.0:2.0 * np.pi:37j, 0.0:np.pi:19j]
    ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", linewidth=0.4)
    rim = arrays["cone_rim"]
    # the cap inside the cone, as rings shrinking to d, and generators from the origin
    for s in np.linspace(0.0, 1.0, 6)[1:]:
        ring = _cone_rim(d, s * alpha)
        ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=CONE_COLOR, alpha=0.25, linewidth=0.8)
    ax.plot(rim[:, 0], rim[:, 1], rim[:, 2], color=CONE_COLOR, linewidth=2.0, label=f"keep-out cone "
            f"({np.degrees(alpha):g} deg)")
    for p in rim[::30]:
        ax.plot([0.0, p[0]], [0.0, p[1]], [0.0, p[2]], color=CONE_COLOR, alpha=0.4, linewidth=0.8)
    ax.quiver(0.0, 0.0, 0.0, *d, color=CONE_COLOR, arrow_length_ratio=0.08, linewidth=1.5)
    if unconstrained is not None:
        yf = arrays["free_boresight"]
        ax.plot(yf[:, 0], yf[:, 1], yf[:, 2], color=FREE_COLOR, linestyle="--", linewidth=2.0,
                label="unconstrained")
    ax.plot(y[:, 0], y[:, 1], y[:, 2], color=PATH_COLOR, linewidth=3.0, label="constrained")
    ax.scatter(*y[0], color="k", s=30, marker="o", label="start")
    ax.scatter(*y[-1], color="k", s=40, marker="s", label="end")
    ax.set_xlim(-1, 1)
    ax.set_ylim(-1, 1)
    ax.set_zlim(-1, 1)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    # look from outside the sphere along the direction, slightly from above
    az = np.degrees(np.arctan2(d[1], d[0]))
    el = np.degrees(np.arcsin(np.clip(d[2], -1.0, 1.0)))
    ax.view_init(elev=el + 15.0, azim=az)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"body axis {np.round(np.asarray(definition['body_axis'], dtype=float), 3).tolist()} on the sphere")

    ax2 = fig.add_subplot(1, 2, 2)
    t = arrays["t"]
    ax2.axhspan(0.0, np.degrees(alpha), color=CONE_COLOR, alpha=0.12)
    ax2.axhline(np.degrees(alpha), color=CONE_COLOR, linewidth=1.5, label="cone half-angle")
    if unconstrained is not None:
        ax2.plot(t, arrays["free_angle_deg"], color=FREE_COLOR, linestyle="--", linewidth=2.0, label="unconstrained")
    ax2.plot(t, arrays["angle_deg"], color=PATH_COLOR, linewidth=2.5, label="constrained")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("angle to the direction [deg]")
    ax2.set_ylim(bottom=0.0)
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    ax2.set_title(f"smallest angle {arrays['angle_deg'][1:].min():.4f} deg")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    out = write_atomic(path, buf.getvalue())
    return FigureData(out, arrays)
