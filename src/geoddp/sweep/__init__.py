"""Sweeps: thousands of solves (and closed-loop simulations) from one sweep file, on
all local cores or a Dask cluster, resumable, streamed to a Parquet table.

    spec.py     sweep files -> validated cases with content hashes (grids, seeded random draws)
    case.py     one case: plain payload in, plain row out (runs on any worker)
    table.py    part files, manifest, the results table (atomic writes)
    run.py      run_sweep: serial, LocalCluster or a scheduler address; resume
    summary.py  convergence rate, distributions, slowest and failed cases; figures
"""
from __future__ import annotations

from .run import SweepInterrupted, SweepRun, run_sweep
from .spec import Case, Sweep, case_hash, expand, load_sweep, parse_sweep
from .table import TIMING_COLUMNS, read_table

__all__ = ["Case", "Sweep", "SweepInterrupted", "SweepRun", "TIMING_COLUMNS", "case_hash", "expand", "load_sweep",
           "parse_sweep", "read_table", "run_sweep"]
