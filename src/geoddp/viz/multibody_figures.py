"""Matplotlib PNG figures of a multibody Result: joint positions and velocities, controls with their
limits, the frame targets' errors, and the solver's history.

Drawn like :mod:`.figures` (object API on an Agg canvas, headless, files written atomically); each
function returns, next to the paths, the arrays it plotted and the matplotlib figure
(:class:`~geoddp.viz.figures.FigureData`), so tests can check the drawn lines against the Result.

The joints are read from the model the Result describes (``Result.multibody``, rebuilt by
:func:`geoddp.viz.model.load_model`), in Pinocchio's order. A free-flyer root is drawn as its world
translation and its rotation vector, a spherical root as its rotation vector: the rotation vector
r_k = log3(R_k) (axis times angle, rad) of the root's world rotation, taken on the branch nearest
r_{k-1} (r and r - 2 pi r/|r| are the same rotation), so a turn through pi draws as a continuous
curve instead of jumping; never the raw quaternion components.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from matplotlib.figure import Figure

from ..output_files import output_folder
from ..solver.result import MultibodyResult, Result, as_result
from ..validate import InputError
from .figures import Figures, _color, _figure, controls_figure
from .model import load_model

#: The figures :func:`plot_multibody` writes, in order (``<name>.png``); ``frame_errors`` only when
#: there is a frame target.
MULTIBODY_FIGURES = ("joint_positions", "joint_velocities", "controls", "frame_errors", "solver_history")

_XYZ = ("x", "y", "z")


@dataclass
class Panel:
    """One axes of a joint figure: curves ``values`` (N, n) against time, one per label.

    Attributes:
        key: name of the panel's arrays in the figure data (``root_translation``, ``joints``, ...).
        title: axes title; ylabel: y axis label with units.
        labels: legend entry of each column.
        values: (N, n) values (N = H+1 time stamps).
    """

    key: str
    title: str
    ylabel: str
    labels: list[str]
    values: np.ndarray


def rotation_vectors(R: np.ndarray) -> np.ndarray:
    """Continuous rotation vectors (N, 3), rad, of rotations R (N, 3, 3).

    r_0 = log3(R_0) (angle in [0, pi]); each next r_k is log3(R_k) or one of its equivalents
    r + 2 pi n r/|r| (the same rotation), whichever is nearest r_{k-1}: a rotation through pi gives
    a continuous curve (angles above pi), as np.unwrap does for an angle.
    """
    out = np.empty((len(R), 3))
    for k, Rk in enumerate(np.asarray(R, dtype=float)):
        r = pin.log3(Rk)
        theta = float(np.linalg.norm(r))
        if k > 0 and theta > 1e-12:
            # the same rotation: (theta + 2 pi n) axis for every integer n (n < 0 flips the axis);
            # the n nearest r_{k-1} along the axis, and its neighbours, compared in full
            axis, prev = r / theta, out[k - 1]
            n0 = np.round((float(np.dot(prev, axis)) - theta) / (2.0 * np.pi))
            cands = [axis * (theta + 2.0 * np.pi * n) for n in (n0 - 1.0, n0, n0 + 1.0)]
            r = min(cands, key=lambda c: float(np.linalg.norm(c - prev)))
        out[k] = r
    return out


def _quaternion_rotations(quat: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations of Pinocchio quaternions (N, 4) in (x, y, z, w) order."""
    return np.array([pin.Quaternion(w, x, y, z).normalized().toRotationMatrix() for x, y, z, w in quat])


def _joint_kind(joint: Any) -> str:
    """"revolute" (angle in rad), "prismatic" (m) or "other" (Pinocchio's tangent coordinates)."""
    name = joint.shortname()
    if name.startswith("JointModelR"):  # RX, RY, RZ, RevoluteUnaligned, RUBX..: bounded or not
        return "revolute"
    if name.startswith("JointModelP") and not name.startswith("JointModelPlanar"):
        return "prismatic"
    return "other"


def joint_panels(model: pin.Model, root: str, Q: np.ndarray, V: np.ndarray) -> tuple[list[Panel], list[Panel]]:
    """The position and velocity panels of a trajectory (Q (N, nq), V (N, nv)) of ``model``.

    Positions: for a free-flyer root its world translation (m) and rotation vector (rad,
    :func:`rotation_vectors`), for a spherical root its rotation vector; then the revolute joints'
    angles (rad; an unbounded revolute joint's (cos, sin) pair as its angle, unwrapped), the
    prismatic joints' positions (m), and any other joint's tangent coordinates
    ``pin.difference(model, neutral, q)`` over that joint. Velocities: the root's linear (m/s) and
    angular (rad/s) velocity in its body frame (Pinocchio's local convention), then each joint's
    velocity (rad/s, m/s, or tangent rates).

    Returns:
        (position panels, velocity panels), each a list of :class:`Panel` (empty panels left out).
    """
    Q, V = np.asarray(Q, dtype=float), np.asarray(V, dtype=float)
    pos: list[Panel] = []
    vel: list[Panel] = []
    first = 1
    if root == "free_flyer":
        pos.append(Panel("root_translation", "root translation (world)", "position [m]",
                         [f"${a}$" for a in _XYZ], Q[:, 0:3]))
        pos.append(Panel("root_rotation", "root rotation vector log3(R) (world)", "rotation [rad]",
                         [f"$r_{a}$" for a in _XYZ], rotation_vectors(_quaternion_rotations(Q[:, 3:7]))))
        vel.append(Panel("root_linear_velocity", "root linear velocity (body frame)", "velocity [m/s]",
                         [f"$v_{a}$" for a in _XYZ], V[:, 0:3]))
        vel.append(Panel("root_angular_velocity", "root angular velocity (body frame)", "angular velocity [rad/s]",
                         [rf"$\omega_{a}$" for a in _XYZ], V[:, 3:6]))
        first = 2
    elif root == "spherical":
        pos.append(Panel("root_rotation", "root rotation vector log3(R) (world)", "rotation [rad]",
                         [f"$r_{a}$" for a in _XYZ], rotation_vectors(_quaternion_rotations(Q[:, 0:4]))))
        vel.append(Panel("root_angular_velocity", "root angular velocity (body frame)", "angular velocity [rad/s]",
                         [rf"$\omega_{a}$" for a in _XYZ], V[:, 0:3]))
        first = 2
    groups: dict[str, tuple[list[str], list[np.ndarray], list[np.ndarray]]] = {
        k: ([], [], []) for k in ("revolute", "prismatic", "other")}
    neutral = pin.neutral(model)
    for j in range(first, model.njoints):
        joint, name = model.joints[j], model.names[j]
        kind = _joint_kind(joint)
        iq, nq, iv, nv = joint.idx_q, joint.nq, joint.idx_v, joint.nv
        if nq == nv:
            q = Q[:, iq:iq + nq]
        elif kind == "revolute" and nq == 2:  # unbounded: (cos theta, sin theta)
            q = np.unwrap(np.arctan2(Q[:, iq + 1], Q[:, iq]))[:, None]
        else:
            q = np.array([pin.difference(model, neutral, qk)[iv:iv + nv] for qk in Q])
        labels, qs, vs = groups[kind]
        labels += [name] if nv == 1 else [f"{name}[{i}]" for i in range(nv)]
        qs.append(q)
        vs.append(V[:, iv:iv + nv])
    units = {"revolute": ("joint angles", "angle [rad]", "joint angular velocities", "velocity [rad/s]"),
             "prismatic": ("prismatic joints", "position [m]", "prismatic joint velocities", "velocity [m/s]"),
             "other": ("other joints (tangent coordinates)", "coordinate", "other joints (tangent rates)", "rate")}
    for kind, (labels, qs, vs) in groups.items():
        if labels:
            tq, yq, tv, yv = units[kind]
            key = "joints" if kind == "revolute" else f"{kind}_joints"
            pos.append(Panel(key, tq, yq, labels, np.hstack(qs)))
            vel.append(Panel(key, tv, yv, labels, np.hstack(vs)))
    return pos, vel


def _panels_figure(panels: list[Panel], t: np.ndarray, title: str, path: Path):
    """One axes per panel, stacked, sharing the time axis; returns the FigureData."""
    fig = Figure(figsize=(7.5, 1.0 + 2.4 * len(panels)))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    arrays: dict[str, np.ndarray] = {"t": t}
    for ax, p in zip(axes, panels):
        for i, label in enumerate(p.labels):
            ax.plot(t, p.values[:, i], color=_color(i, len(p.labels)), label=label)
        ax.set(ylabel=p.ylabel, title=p.title)
        ax.grid(alpha=0.3)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small",
                  ncol=1 if len(p.labels) <= 9 else 2)
        arrays[p.key] = p.values
        arrays[p.key + "/labels"] = list(p.labels)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    return _figure(fig, path, arrays)


def _scene_targets(result: Result, model: pin.Model) -> list[tuple[str, str, str, np.ndarray]]:
    """(name, frame, type, reference) of the frame targets the Result's description records (its
    terminal frame_placement and frame_translation terms, :meth:`geoddp.problem.Problem.describe`)."""
    out = []
    for i, e in enumerate((result.multibody or {}).get("frame_targets") or []):
        where = f"result.multibody.frame_targets[{i}]"
        if not isinstance(e, dict) or not isinstance(e.get("frame"), str) or not model.existFrame(e["frame"]):
            raise InputError(where, f"expected a dict naming a frame of the model, got {e!r:.80}")
        if "placement" in e:
            out.append((e["frame"], e["frame"], "frame_placement", np.asarray(e["placement"], dtype=float)))
        elif "position" in e:
            out.append((e["frame"], e["frame"], "frame_translation", np.asarray(e["position"], dtype=float)))
    return out


def frame_error_series(result: Result, scene: Any = None) -> list[dict[str, Any]]:
    """Each frame target's errors along the trajectory: :func:`geoddp.scene.build.frame_errors`
    of ``scene``'s terminal frame terms (placement, translation, rotation) when a multibody scene
    spec is given, else of the frame targets recorded in ``result.multibody["frame_targets"]``
    (its terminal frame placement and translation terms) by
    :func:`geoddp.scene.build.frame_target_errors`.

    Returns:
        One dict per target: ``name``, ``frame``, ``type`` and ``position_error_m`` (H+1,) and/or
        ``rotation_error_deg`` (H+1,).
    """
    from ..scene.build import frame_errors, frame_target_errors

    Q = np.asarray(result.configurations, dtype=float)
    if scene is not None:
        return frame_errors(scene, Q)
    model = load_model(result.multibody)
    return frame_target_errors(model, Q, _scene_targets(result, model))


def _frame_errors_figure(rows: list[dict[str, Any]], t: np.ndarray, path: Path):
    """Position errors (m) and rotation errors (deg) of the frame targets against time, log y."""
    panels = [("position_error_m", "position error [m]", "frame position error |p - p_ref|"),
              ("rotation_error_deg", "rotation error [deg]", "frame rotation error angle(R_ref^T R)")]
    panels = [p for p in panels if any(p[0] in r for r in rows)]
    fig = Figure(figsize=(7.5, 1.0 + 2.6 * len(panels)))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    arrays: dict[str, Any] = {"t": t}
    for ax, (key, ylabel, title) in zip(axes, panels):
        for i, r in enumerate(rows):
            if key not in r:
                continue
            e = np.asarray(r[key], dtype=float)
            # log scale: the end of a reach is orders of magnitude below its start; a zero (exactly
            # on target) has no place there and is not drawn
            ax.semilogy(t, np.where(e > 0, e, np.nan), color=_color(i, len(rows)), label=f"{r['name']} ({r['frame']})")
            arrays[f"{r['name']}/{key}"] = e
        ax.set(ylabel=ylabel, title=title)
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Frame targets")
    return _figure(fig, path, arrays)


def solver_history_figure(result: Result, out: Path):
    """``solver_history.png`` in the folder ``out``: the cost J_i and the gradient norm
    ||dJ/dU||_i at each iterate i (0: the initial guess) of the solve, log y; filled markers on
    iterates reached by a second-order step, open ones by a first-order step; the status in the
    title.

    Returns:
        Its :class:`~geoddp.viz.figures.FigureData`: ``iteration (n,)``, ``cost (n,)``,
        ``grad_norm (n,)``, ``second_order (n,)`` (bool; False for iterate 0).
    """
    J = np.asarray(result.cost_history, dtype=float)
    g = np.asarray(result.grad_norm_history, dtype=float)
    it = np.arange(J.size)
    second = np.zeros(J.size, dtype=bool)
    exp = list(result.expansion_history or [])
    second[1:1 + len(exp)] = [e == "second" for e in exp[: J.size - 1]]
    fig = Figure(figsize=(11.0, 4.2))
    ax_j, ax_g = fig.subplots(1, 2)
    for ax, y, ylabel, title in ((ax_j, J, "$J_i$", "Cost"), (ax_g, g, r"$\|\partial J / \partial U\|_i$",
                                                                  "Gradient norm")):
        finite_pos = np.isfinite(y) & (y > 0)
        ax.plot(it, np.where(finite_pos, y, np.nan), "-", color="tab:blue", lw=1.2)
        ax.plot(it[finite_pos & ~second], y[finite_pos & ~second], "o", mfc="none", color="tab:blue", ms=4,
                label="first-order step")
        ax.plot(it[finite_pos & second], y[finite_pos & second], "o", color="tab:blue", ms=4,
                label="second-order step")
        if finite_pos.any():
            ax.set_yscale("log")
        ax.set(xlabel="iteration $i$", ylabel=ylabel, title=title)
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="best", fontsize="small")
    fig.suptitle(f"{result.iterations} iterations: {result.status}")
    return _figure(fig, out / "solver_history.png",
                   {"iteration": it, "cost": J, "grad_norm": g, "second_order": second})


def plot_solver_history(result: Result, out_dir: str | Path) -> Figures:
    """Write ``solver_history.png`` (:func:`solver_history_figure`) of any Result into ``out_dir``.

    Raises:
        InputError: ``result`` not a :class:`Result`, or ``out_dir`` not a folder that can be
            written (:func:`geoddp.output_files.output_folder`).
    """
    result = as_result(result)
    figs = Figures()
    figs.add("solver_history", solver_history_figure(result, output_folder(out_dir)))
    return figs


def plot_multibody(result: Result, out_dir: str | Path, scene: Any = None) -> Figures:
    """The figures of a multibody Result, written into ``out_dir`` (created if needed).

    - ``joint_positions.png``: stacked panels against time (s): a free-flyer root's world
      translation (m) and rotation vector (rad), a spherical root's rotation vector, the revolute
      joints' angles (rad), the prismatic joints' positions (m), any other joint's tangent
      coordinates (:func:`joint_panels`).
    - ``joint_velocities.png``: the same panels for the velocities: the root's linear (m/s) and
      angular (rad/s) velocity in its body frame, each joint's velocity.
    - ``controls.png``: u_k held over [t_k, t_{k+1}), with the control limits (``result.limits``)
      dashed and the saturated intervals shaded, as for the satellite.
    - ``frame_errors.png`` (when there is a frame target): each target's position error (m) and
      rotation error (deg) against time, log scale (:func:`frame_error_series`).
    - ``solver_history.png``: J_i and ||dJ/dU||_i per iteration (:func:`solver_history_figure`).

    Args:
        result: a multibody Result (with ``multibody``, ``configurations`` (H+1, nq) and
            ``velocities`` (H+1, nv)).
        out_dir: output folder.
        scene: the multibody scene spec solved (``geoddp.scene.load_scene``), whose terminal frame
            terms give the frame targets (frame_rotation terms included); None: the targets the
            Result records.

    Returns:
        :class:`~geoddp.viz.figures.Figures`: name -> path, with ``.data[name]``: ``arrays`` (``t``
        and one (H+1, n) array per panel key with its ``<key>/labels``; controls as
        :func:`geoddp.viz.figures.controls_figure`; frame_errors ``<name>/position_error_m`` and
        ``<name>/rotation_error_deg``; solver_history as :func:`solver_history_figure`) and
        ``figure`` (the matplotlib Figure).

    Raises:
        InputError: ``result`` not a multibody Result (naming ``result.multibody``), its
            configurations or velocities not (H+1, nq) and (H+1, nv), or ``out_dir`` not a folder
            that can be written.
    """
    result = as_result(result)
    if not isinstance(result, MultibodyResult) or result.multibody is None:
        raise InputError("result.multibody", "expected a multibody Result with its model description (the "
                         "satellite's figures are geoddp.viz.plot_trajectory)")
    model = load_model(result.multibody)
    t = np.asarray(result.times, dtype=float)
    Q, V = result.configurations, result.velocities
    if Q is None or np.shape(Q) != (t.size, model.nq):
        raise InputError("result.configurations", f"expected shape (H+1, nq) = ({t.size}, {model.nq}), got "
                         f"{None if Q is None else np.shape(Q)}")
    if V is None or np.shape(V) != (t.size, model.nv):
        raise InputError("result.velocities", f"expected shape (H+1, nv) = ({t.size}, {model.nv}), got "
                         f"{None if V is None else np.shape(V)}")
    out = output_folder(out_dir)
    figs = Figures()
    pos, vel = joint_panels(model, result.multibody["root"], Q, V)
    figs.add("joint_positions", _panels_figure(pos, t, "Positions", out / "joint_positions.png"))
    figs.add("joint_velocities", _panels_figure(vel, t, "Velocities", out / "joint_velocities.png"))
    m = np.shape(result.controls)[1]
    figs.add("controls", controls_figure(result, out, legend_columns=1 if m <= 6 else 2))
    rows = frame_error_series(result, scene)
    if rows:
        figs.add("frame_errors", _frame_errors_figure(rows, t, out / "frame_errors.png"))
    figs.add("solver_history", solver_history_figure(result, out))
    return figs
