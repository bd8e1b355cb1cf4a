"""Matplotlib PNG figures of a trajectory and of solver convergence.

Figures are drawn with the object API on an Agg canvas (no pyplot, no global backend
switch), so this works headless and never opens windows. Every function returns, next to
the file paths, the exact arrays it plotted (:class:`FigureData`) so tests can check the
figures against the Result.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..output_files import output_folder, write_atomic
from ..solver.result import Result, as_result, rotations_to_quaternions
from ..validate import InputError

DPI = 120
QUAT_LABELS = ("$q_x$", "$q_y$", "$q_z$", "$q_w$")
OMEGA_LABELS = (r"$\Omega_x$", r"$\Omega_y$", r"$\Omega_z$")
COLORS = ("tab:red", "tab:green", "tab:blue", "tab:purple", "tab:orange", "tab:brown")


@dataclass
class FigureData:
    """One written figure and the arrays drawn in it.

    Attributes:
        path: the PNG file.
        arrays: name -> the array plotted (units in the docstring of the plotting function).
        figure: the matplotlib Figure that was saved (its axes' lines hold the data as drawn).
    """

    path: Path
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    figure: Figure | None = None


class Figures(dict):
    """``dict[str, Path]`` (figure name -> PNG path) that also carries ``data``.

    ``data[name]`` is the :class:`FigureData` of that figure.
    """

    def __init__(self) -> None:
        super().__init__()
        self.data: dict[str, FigureData] = {}

    def add(self, name: str, fig_data: FigureData) -> None:
        self[name] = fig_data.path
        self.data[name] = fig_data


def _save(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` atomically (rendered in memory, then
    :func:`geoddp.output_files.write_atomic`: a kill never leaves a truncated image)."""
    FigureCanvasAgg(fig)  # attach an Agg canvas: savefig then needs no GUI backend
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return write_atomic(path, buf.getvalue())


def _figure(fig: Figure, path: Path, arrays: dict) -> FigureData:
    """Save ``fig`` at ``path`` and return its :class:`FigureData` (arrays and the figure)."""
    return FigureData(_save(fig, path), arrays, fig)


def _target_quaternion(result: Result) -> np.ndarray:
    """q_d (x, y, z, w) with the sign of the final quaternion (q and -q are one attitude)."""
    qd = rotations_to_quaternions(np.asarray(result.target_rotation, dtype=float)[None])[0]
    return -qd if np.dot(qd, result.quaternions[-1]) < 0 else qd


def plot_trajectory(result: Result, out_dir: str | Path) -> Figures:
    """Quaternion, angular-velocity and control histories of one trajectory.

    Writes in ``out_dir`` (created if needed):

    - ``quaternion.png``: q_x, q_y, q_z, q_w of ``result.quaternions (H+1, 4)`` against
      ``times (H+1,)`` in s, with the target quaternion drawn as circles at t_f (the
      paper's Figure 2, left). The target's sign is chosen to match q_H.
    - ``angular_velocity.png``: Omega (rad/s, body frame) against time, target at t_f.
    - ``controls.png``: u_k (actuation units) held constant over [t_k, t_{k+1}); with control
      limits (``result.limits``) the bounds dashed and the saturated intervals shaded.

    Args:
        result: the trajectory.
        out_dir: output directory.

    Returns:
        :class:`Figures`: name -> path, with ``.data[name].arrays``:
        quaternion: ``t (H+1,)``, ``quaternions (H+1, 4)``, ``target_time ()``,
        ``target_quaternion (4,)``; angular_velocity: ``t``, ``angular_velocities (H+1, 3)``,
        ``target_time``, ``target_angular_velocity (3,)``; controls: ``edges (H+1,)``,
        ``controls (H, m)``, and with limits ``lower``, ``upper`` (H, m) (NaN: unbounded) and
        ``saturated`` (list of (input, t_start, t_end)).

    Raises:
        InputError: ``result`` not a :class:`Result`, or ``out_dir`` not a folder that can be
            written (:func:`geoddp.output_files.output_folder`).
    """
    result = as_result(result)
    out = output_folder(out_dir)
    figs = Figures()
    t = np.asarray(result.times, dtype=float)
    tf = float(t[-1])

    q = result.quaternions
    qd = _target_quaternion(result)
    fig = Figure(figsize=(6.4, 4.0))
    ax = fig.add_subplot()
    for i in range(4):
        ax.plot(t, q[:, i], color=COLORS[i], label=QUAT_LABELS[i])
        ax.plot([tf], [qd[i]], "o", mfc="none", ms=9, mew=1.5, color=COLORS[i])
    ax.plot([], [], "o", mfc="none", color="k", label="target $q_d$")  # legend entry only
    ax.set(xlabel="time [s]", ylabel="quaternion component", title="Attitude")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    figs.add("quaternion", _figure(fig, out / "quaternion.png",
                                   {"t": t, "quaternions": q, "target_time": np.asarray(tf), "target_quaternion": qd}))

    w = np.asarray(result.angular_velocities, dtype=float)
    wd = np.asarray(result.target_angular_velocity, dtype=float)
    fig = Figure(figsize=(6.4, 4.0))
    ax = fig.add_subplot()
    for i in range(3):
        ax.plot(t, w[:, i], color=COLORS[i], label=OMEGA_LABELS[i])
        ax.plot([tf], [wd[i]], "o", mfc="none", ms=9, mew=1.5, color=COLORS[i])
    ax.plot([], [], "o", mfc="none", color="k", label=r"target $\Omega_d$")
    ax.set(xlabel="time [s]", ylabel="angular velocity [rad/s]", title="Body angular velocity")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    figs.add("angular_velocity", _figure(fig, out / "angular_velocity.png", {
        "t": t, "angular_velocities": w, "target_time": np.asarray(tf), "target_angular_velocity": wd}))

    figs.add("controls", controls_figure(result, out))
    return figs


def controls_figure(result: Result, out: Path, legend_columns: int = 1) -> FigureData:
    """``controls.png`` in the folder ``out``: u_k (actuation units) held constant over
    [t_k, t_{k+1}) against time (s), one line per input u_1 .. u_m; with control limits
    (``result.limits``) each finite bound dashed and the saturated intervals shaded
    (:func:`_draw_limits`).

    Returns:
        Its :class:`FigureData`: ``edges (H+1,)``, ``controls (H, m)``, and with limits ``lower``,
        ``upper`` (H, m) (NaN: unbounded) and ``saturated`` (list of (input, t_start, t_end)).
    """
    t = np.asarray(result.times, dtype=float)
    u = np.asarray(result.controls, dtype=float)
    fig = Figure(figsize=(6.4, 4.0))
    ax = fig.add_subplot()
    for j in range(u.shape[1]):
        # Zero-order hold: u_k acts on [t_k, t_{k+1}), which stairs() draws exactly.
        ax.stairs(u[:, j], t, color=_color(j, u.shape[1]), label=f"$u_{{{j + 1}}}$", baseline=None)
    arrays = {"edges": t, "controls": u}
    limits = getattr(result, "limits", None)
    if limits is not None:
        arrays.update(_draw_limits(ax, t, u, limits, getattr(result, "active_set", None)))
    ax.set(xlabel="time [s]", ylabel="control", title="Controls")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small", ncol=legend_columns)
    return _figure(fig, out / "controls.png", arrays)


def _color(j: int, count: int):
    """Colour of curve j of ``count`` in one axes: COLORS for up to six curves, else matplotlib's
    tab20 (twenty distinct colours: a robot's joints or inputs)."""
    return COLORS[j] if count <= len(COLORS) else colormaps["tab20"](j % 20)


def _draw_limits(ax, t: np.ndarray, u: np.ndarray, limits: tuple[np.ndarray, np.ndarray],
                 active: np.ndarray | None) -> dict:
    """Control limits on the controls axes: each input's finite bounds as dashed
    stairs in its colour, and the intervals [t_k, t_{k+1}) where it sits on a bound shaded in
    its colour. Returns the figure data: ``lower``, ``upper`` (H, m) (NaN where unbounded) and
    ``saturated`` (list of (input, t_start, t_end) intervals)."""
    lo, hi = (np.asarray(b, dtype=float) for b in limits)
    if active is None:
        active = np.where(u >= hi, 1, np.where(u <= lo, -1, 0))
    active = np.asarray(active)
    intervals = []
    drawn: list[np.ndarray] = []
    for j in range(u.shape[1]):
        c = _color(j, u.shape[1])
        for bound in (lo[:, j], hi[:, j]):
            if not np.isfinite(bound).any() or any(np.array_equal(bound, b) for b in drawn):
                continue
            drawn.append(bound)
            # a bound several inputs share is drawn once, in grey; an input's own in its colour
            shared = sum(np.array_equal(bound, lo[:, i]) or np.array_equal(bound, hi[:, i]) for i in range(u.shape[1]))
            ax.stairs(np.where(np.isfinite(bound), bound, np.nan), t, color="0.35" if shared > 1 else c, ls="--",
                      lw=0.9, alpha=0.8, baseline=None)
        on = np.concatenate(([False], active[:, j] != 0, [False]))
        starts, ends = np.flatnonzero(~on[:-1] & on[1:]), np.flatnonzero(on[:-1] & ~on[1:])
        for a, b in zip(starts, ends):  # nodes a .. b-1 saturated: [t_a, t_b)
            ax.axvspan(t[a], t[b], color=c, alpha=0.12, lw=0)
            intervals.append((j, float(t[a]), float(t[b])))
    ax.plot([], [], "k--", lw=0.9, label="limits")
    ax.fill_between([], [], color="0.5", alpha=0.25, label="saturated")
    return {"lower": np.where(np.isfinite(lo), lo, np.nan), "upper": np.where(np.isfinite(hi), hi, np.nan),
            "saturated": intervals}


def control_errors(result: Result) -> np.ndarray:
    """||U_i - U*|| (Frobenius over all H x m entries) per iterate, U* = ``result.controls``.

    Returns:
        (iterations+1,) errors, from ``control_history (iterations+1, H, m)``.

    Raises:
        ValueError: the result has no control history.
    """
    if result.control_history is None:
        raise ValueError("this Result has no control_history (record it in the solver)")
    diff = np.asarray(result.control_history, dtype=float) - np.asarray(result.controls, dtype=float)[None]
    return np.linalg.norm(diff.reshape(diff.shape[0], -1), axis=1)


def plot_convergence(
    results: dict[str, Result],
    out_dir: str | Path,
    reference_cost: float | None = None,
    reference_label: str = "",
    reference_history: np.ndarray | None = None,
) -> Figures:
    """Convergence of several solves (the paper's Figure 3) and their cost histories.

    Writes in ``out_dir``:

    - ``convergence.png``, two panels: left, ||U_i - U*|| against iteration i (log y),
      U* being that run's final controls; right, ||U_{i+1} - U*|| against ||U_i - U*||
      (log-log; slope 1 = linear, slope 2 = quadratic convergence), with y = x dotted.
      Zero errors (the last iterate) cannot sit on a log axis and are not drawn.
      Runs without ``control_history`` are left out of this figure.
    - ``cost_history.png``, two panels: left, J_i against iteration; right, J_i - J_min
      (log y), J_min the smallest cost of all runs. ``reference_cost`` (e.g. another
      solver's optimum) is a horizontal line in both when given and drawable.

    Args:
        results: label -> Result (e.g. {"first order": r1, "second order": r2}).
        out_dir: output directory.
        reference_cost: cost J of a reference solution, or None.
        reference_label: legend text for the reference line.
        reference_history: (n,) cost per iteration of an off-the-shelf solver, drawn as a
            dashed curve in both cost panels (stored as ``"reference/cost"``).

    Returns:
        :class:`Figures` with ``.data["convergence"].arrays``: ``"<label>/iteration"``,
        ``"<label>/error"`` (iterations+1,), ``"<label>/error_now"`` and
        ``"<label>/error_next"`` (the plotted pairs); ``.data["cost_history"].arrays``:
        ``"<label>/iteration"``, ``"<label>/cost"``, ``"<label>/cost_minus_min"``,
        ``"j_min"`` and, when given, ``"reference_cost"``.

    Raises:
        InputError: ``results`` not a non-empty dict of :class:`Result` (naming ``results`` or
            ``results[label]``), or ``out_dir`` not a folder that can be written
            (:func:`geoddp.output_files.output_folder`).
    """
    if not isinstance(results, dict) or not results:
        raise InputError("results", f"expected a dict label -> Result with at least one entry, got {results!r:.80}")
    for label, r in results.items():
        as_result(r, f"results[{label!r}]")
    out = output_folder(out_dir)
    figs = Figures()

    conv: dict[str, np.ndarray] = {}
    fig = Figure(figsize=(11.0, 4.2))
    ax_it, ax_pair = fig.subplots(1, 2)
    lo, hi = np.inf, 0.0
    for n, (label, res) in enumerate(results.items()):
        if res.control_history is None:
            continue
        color = COLORS[n % len(COLORS)]
        err = control_errors(res)
        it = np.arange(err.size)
        keep = err > 0
        ax_it.semilogy(it[keep], err[keep], "o-", ms=4, color=color, label=label)
        now, nxt = err[:-1], err[1:]
        pair = (now > 0) & (nxt > 0)
        ax_pair.loglog(now[pair], nxt[pair], "o-", ms=4, color=color, label=label)
        if pair.any():
            lo = min(lo, now[pair].min(), nxt[pair].min())
            hi = max(hi, now[pair].max(), nxt[pair].max())
        conv.update({
            f"{label}/iteration": it,
            f"{label}/error": err,
            f"{label}/error_now": now[pair],
            f"{label}/error_next": nxt[pair],
        })
    if hi > 0:
        ax_pair.loglog([lo, hi], [lo, hi], ":", color="grey", label="$y = x$")
    ax_it.set(xlabel="iteration $i$", ylabel=r"$\|U_i - U^*\|$", title="Distance to the solution")
    ax_pair.set(xlabel=r"$\|U_i - U^*\|$", ylabel=r"$\|U_{i+1} - U^*\|$", title="Rate of convergence")
    for ax in (ax_it, ax_pair):
        ax.grid(alpha=0.3, which="both")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize="small")
    if not conv:
        ax_it.text(0.5, 0.5, "no run recorded control_history", ha="center", transform=ax_it.transAxes)
    figs.add("convergence", FigureData(_save(fig, out / "convergence.png"), conv))

    costs: dict[str, np.ndarray] = {}
    j_min = min(float(np.min(r.cost_history)) for r in results.values())
    if reference_history is not None:
        j_min = min(j_min, float(np.min(reference_history)))
    fig = Figure(figsize=(11.0, 4.2))
    ax_j, ax_dj = fig.subplots(1, 2)
    for n, (label, res) in enumerate(results.items()):
        color = COLORS[n % len(COLORS)]
        J = np.asarray(res.cost_history, dtype=float)
        it = np.arange(J.size)
        dJ = J - j_min
        keep = dJ > 0
        ax_j.plot(it, J, "o-", ms=4, color=color, label=label)
        ax_dj.semilogy(it[keep], dJ[keep], "o-", ms=4, color=color, label=label)
        costs.update({f"{label}/iteration": it, f"{label}/cost": J, f"{label}/cost_minus_min": dJ})
    costs["j_min"] = np.asarray(j_min)
    if reference_history is not None:
        Jr = np.asarray(reference_history, dtype=float)
        itr = np.arange(Jr.size)
        keep = Jr - j_min > 0
        ref_curve = (reference_label or "reference") + " per iteration"
        ax_j.plot(itr, Jr, "--", color="k", label=ref_curve)
        ax_dj.semilogy(itr[keep], (Jr - j_min)[keep], "--", color="k", label=ref_curve)
        costs["reference/cost"] = Jr
    if reference_cost is not None:
        ref_label = (reference_label or "reference") + (" final" if reference_history is not None else "")
        costs["reference_cost"] = np.asarray(float(reference_cost))
        ax_j.axhline(reference_cost, ls="--", color="k", label=ref_label)
        if reference_cost - j_min > 0:
            ax_dj.axhline(reference_cost - j_min, ls="--", color="k", label=ref_label)
        else:
            # At or below J_min the reference has no place on a log axis: say so instead.
            ax_dj.text(0.02, 0.02, f"{ref_label}: J = {reference_cost:.6g} <= J_min",
                       transform=ax_dj.transAxes, fontsize="small")
    ax_j.set(xlabel="iteration $i$", ylabel="$J_i$", title="Cost")
    ax_dj.set(xlabel="iteration $i$", ylabel=r"$J_i - J_{min}$", title=f"Cost above $J_{{min}}$ = {j_min:.6g}")
    for ax in (ax_j, ax_dj):
        ax.grid(alpha=0.3, which="both")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize="small")
    figs.add("cost_history", FigureData(_save(fig, out / "cost_history.png"), costs))
    return figs
