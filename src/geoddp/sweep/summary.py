"""What a sweep found: convergence rate, the distributions of iterations and J*,
the slowest and the failed cases, and parameter-vs-outcome figures."""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from ..output_files import write_atomic

FIXED_COLUMNS = ("case", "hash", "draw", "kind", "status", "converged", "J", "iterations", "gradient_norm",
                 "solve_time_s", "case_time_s", "error")


def parameter_columns(df: Any) -> list[str]:
    """The table's parameter columns (key paths), in table order."""
    return [c for c in df.columns if c not in FIXED_COLUMNS and not c.startswith(("sim.", "terminal."))
            and c not in ("attitude_error_deg", "angular_velocity_error")]


def _quantiles(x: np.ndarray) -> str:
    x = x[np.isfinite(x)]
    if not x.size:
        return "no finite values"
    q = np.quantile(x, [0.0, 0.5, 0.9, 1.0])
    return f"min {q[0]:.6g}  median {q[1]:.6g}  p90 {q[2]:.6g}  max {q[3]:.6g}  mean {x.mean():.6g}"


def summary(df: Any, top: int = 5) -> str:
    """Plain-text summary of a results table (:func:`geoddp.sweep.read_table`).

    Lists: cases, converged count and rate, statuses, iterations and J* (min, median, p90, max,
    mean over solved cases), the ``top`` slowest cases by solve time and every failed case
    (status "error") with its error (the first ``top``, then a count)."""
    n = len(df)
    if n == 0:
        return "no cases in the table yet"
    params = parameter_columns(df)
    conv = int(df["converged"].sum())
    lines = [f"cases: {n}", f"converged: {conv}/{n} ({100.0 * conv / n:.1f} %)", "status:"]
    for status, count in df["status"].value_counts().items():
        lines.append(f"  {count:>7d}  {status}")
    solved = df[df["status"] != "error"]
    lines.append("iterations: " + _quantiles(solved["iterations"].to_numpy(float)))
    lines.append("J*:         " + _quantiles(solved["J"].to_numpy(float)))
    lines.append("solve time: " + _quantiles(solved["solve_time_s"].to_numpy(float)) + " (s)")
    sim_cols = [c for c in df.columns if c.startswith("sim.") and c.endswith(".max")]
    for c in sim_cols[:6]:
        lines.append(f"{c}: " + _quantiles(df[c].to_numpy(float)))

    def describe(row: Any) -> str:
        ps = ", ".join(f"{p} = {row[p]:.6g}" if isinstance(row[p], (float, np.floating)) else f"{p} = {row[p]}"
                       for p in params[:6])
        return f"case {int(row['case'])} ({ps})" if ps else f"case {int(row['case'])}"

    lines.append(f"slowest {min(top, len(solved))}:")
    for _, row in solved.sort_values("solve_time_s", ascending=False).head(top).iterrows():
        lines.append(f"  {row['solve_time_s']:.4g} s  {row['iterations']} iterations  {describe(row)}")
    failed = df[df["status"] == "error"]
    not_conv = df[(df["status"] != "error") & (~df["converged"].astype(bool))]
    lines.append(f"failed (raised): {len(failed)}")
    for _, row in failed.head(top).iterrows():
        lines.append(f"  {describe(row)}: {row['error']}")
    lines.append(f"not converged: {len(not_conv)}")
    for _, row in not_conv.head(top).iterrows():
        lines.append(f"  {describe(row)}: {row['status']}")
    return "\n".join(lines)


def plots(df: Any, out: str | Path) -> list[Path]:
    """Figures of a results table as PNG files in ``out`` (atomic): iterations and J* over every
    numeric parameter (converged cases dots, the others crosses; one series per value of the
    first text parameter with at most 8 values, e.g. solver.expansion), and histograms of iterations
    and of each closed-loop ``sim.*.mean`` statistic. Returns the paths."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out = Path(out)
    paths: list[Path] = []

    def save(fig: Any, name: str) -> None:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths.append(write_atomic(out / name, buf.getvalue()))

    from pandas.api.types import is_numeric_dtype

    solved = df[df["status"] != "error"]
    params = parameter_columns(df)
    # a text parameter with few values (solver.expansion) splits every figure into series
    groups = [p for p in params if not is_numeric_dtype(df[p]) and 1 < df[p].nunique() <= 8]
    by = groups[0] if groups else None
    for p in params:
        if not is_numeric_dtype(df[p]) or df[p].dtype == bool or solved[p].nunique() < 2:
            continue
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
        series = [(str(g), solved[solved[by] == g]) for g in solved[by].unique()] if by else [("", solved)]
        for i, (label, part) in enumerate(series):
            ok = part["converged"].astype(bool)
            for ax, col in ((axes[0], "iterations"), (axes[1], "J")):
                ax.plot(part[p][ok], part[col][ok], "o", ms=3, color=f"C{i}",
                        label=f"{by} = {label}" if by else "converged")
                if (~ok).any():
                    ax.plot(part[p][~ok], part[col][~ok], "x", ms=5, color=f"C{i}",
                            label=(f"{by} = {label}, " if by else "") + "not converged")
        for ax, label in ((axes[0], "iterations"), (axes[1], "J*")):
            ax.set_xlabel(p)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
        axes[1].set_yscale("log" if (solved["J"] > 0).all() else "linear")
        axes[0].legend(fontsize=8)
        save(fig, f"outcome_vs_{_slug(p)}.png")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.hist(solved["iterations"], bins=min(50, max(5, solved["iterations"].nunique())))
    ax.set_xlabel("iterations")
    ax.set_ylabel("cases")
    save(fig, "iterations_hist.png")
    for c in [c for c in df.columns if c.startswith("sim.") and c.endswith(".mean")]:
        vals = df[c].to_numpy(float)
        vals = vals[np.isfinite(vals)]
        if vals.size < 2:
            continue
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.hist(vals, bins=min(50, max(5, vals.size // 10)))
        ax.set_xlabel(c[4:])
        ax.set_ylabel("cases")
        save(fig, f"hist_{_slug(c)}.png")
    return paths


def _slug(s: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in s).strip("_")
