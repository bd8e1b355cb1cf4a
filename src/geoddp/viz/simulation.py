"""Figures of a Monte Carlo study (:class:`geoddp.simulate.MonteCarloResult`): the bundles of
simulated trajectories and the distributions of their terminal errors, per policy.

Drawn like :mod:`.figures` (object API on an Agg canvas, headless); every function returns the
arrays it plotted next to the paths.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from ..output_files import output_folder
from .figures import FigureData, Figures, _save

POLICY_COLORS = {"open": "tab:red", "feedback": "tab:blue", "mpc": "tab:green"}
LABELS = {"attitude_rad": "attitude error to target [rad]", "position_m": "frame position error [m]",
          "state": "tangent distance to the plan's final state"}


def plot_simulation(mc: Any, out_dir: str | Path) -> Figures:
    """Write ``bundles.png`` and ``errors.png`` into ``out_dir`` (created if needed).

    - ``bundles.png``: the distance to the target (``target_measure`` of the runs: rad for an
      attitude, m for a frame position) against time, every sample of every policy as a thin line
      (log scale), the plan in black.
    - ``errors.png``: histograms of the terminal value of that measure per policy (log-spaced bins
      shared by the policies), the means as dashed lines.

    Returns:
        :class:`Figures` with ``.data``: bundles: ``t (N+1,)``, ``<policy> (samples, N+1)``,
        ``plan (H+1,)``; errors: ``<policy> (samples,)``, ``bins``.
    """
    out = output_folder(out_dir)
    figs = Figures()
    first = mc.runs[mc.policies[0]][0]
    measure = first.target_measure
    t = np.asarray(first.times)

    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot()
    arrays: dict[str, np.ndarray] = {"t": t}
    floor = 1e-12
    for p in mc.policies:
        E = np.array([r.target_error for r in mc.runs[p]])
        arrays[p] = E
        color = POLICY_COLORS.get(p, "tab:gray")
        alpha = max(0.08, min(0.6, 6.0 / len(E)))
        for e in E:
            ax.plot(t, np.maximum(e, floor), color=color, lw=0.6, alpha=alpha)
        ax.plot([], [], color=color, label=f"{p} ({len(E)} samples)")
    if mc.plan_target_error is not None:
        arrays["plan"] = np.asarray(mc.plan_target_error)
        ax.plot(mc.plan_times, np.maximum(arrays["plan"], floor), color="k", lw=1.5, label="plan")
    ax.set_yscale("log")
    ax.set(xlabel="time [s]", ylabel=LABELS.get(measure, measure), title="Simulated trajectories")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize="small")
    figs.add("bundles", FigureData(_save(fig, out / "bundles.png"), arrays))

    finals = {p: np.array([r.target_error[-1] for r in mc.runs[p]]) for p in mc.policies}
    allv = np.concatenate(list(finals.values()))
    lo, hi = max(np.min(allv), floor), max(np.max(allv), 2 * floor)
    bins = np.logspace(np.log10(lo) - 0.05, np.log10(hi) + 0.05, 40)
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot()
    for p, x in finals.items():
        color = POLICY_COLORS.get(p, "tab:gray")
        ax.hist(np.maximum(x, floor), bins=bins, color=color, alpha=0.6, label=f"{p}: mean {np.mean(x):.3g}")
        ax.axvline(np.mean(x), color=color, ls="--", lw=1.2)
    ax.set_xscale("log")
    ax.set(xlabel="terminal " + LABELS.get(measure, measure), ylabel="samples", title="Terminal error distribution")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    figs.add("errors", FigureData(_save(fig, out / "errors.png"), {**finals, "bins": bins}))
    return figs
