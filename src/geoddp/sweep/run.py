"""Running a sweep: every case validated first, then solved in this process, on a Dask
``LocalCluster`` (all local cores) or on an existing ``dask.distributed`` scheduler; rows streamed
to disk as cases finish; ``resume`` solves only what the folder lacks (issue 17, items 2-4).

Nothing in the cases changes between the three executors: each case is the same plain payload
given to :func:`geoddp.sweep.case.run_case`, so the tables are equal (timing columns aside).
"""
from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from ..outputs import write_atomic
from ..validate import InputError
from . import case as case_mod
from .spec import Case, Sweep, expand, load_sweep
from .table import MANIFEST, PartWriter, done_hashes, part_files, read_parts, write_manifest, write_table

# In flight per worker thread: enough to keep every worker busy while a result travels back,
# few enough that 10^5 cases never sit in the scheduler at once (memory stays flat).
IN_FLIGHT_PER_THREAD = 4
RETRIES = 2  # Dask re-runs a task this many times if it raises out of run_case (it never should)


@dataclass
class SweepRun:
    """What a run did. ``total``: cases in the sweep; ``skipped``: already on disk (resume);
    ``solved``: cases run now; ``failed``: of those, rows with status "error"; ``complete``: every
    case of the sweep is in the table; ``table``: DIR/results.parquet (None if not complete)."""

    total: int
    skipped: int
    solved: int
    failed: int
    complete: bool
    table: Path | None
    wall_time_s: float


def flatten(params: dict[str, Any]) -> dict[str, Any]:
    """Parameter columns: a scalar keeps its key path; a list becomes one column per entry
    (``target.quaternion[0]`` ... ``[3]``, nested lists ``[i][j]``)."""
    out: dict[str, Any] = {}

    def put(key: str, val: Any) -> None:
        if isinstance(val, list):
            for i, x in enumerate(val):
                put(f"{key}[{i}]", x)
        else:
            out[key] = val

    for k, val in params.items():
        put(k, val)
    return out


def make_row(case: Case, outcome: dict[str, Any]) -> dict[str, Any]:
    """The table row of a finished case: case, hash, draw, kind, parameters, then the outcome."""
    row: dict[str, Any] = {"case": case.index, "hash": case.hash, "draw": case.draw, "kind": case.kind}
    row.update(flatten(case.params))
    row.update(outcome)
    row["error"] = row.pop("error", "")  # last column
    return row


def error_outcome(exc: BaseException) -> dict[str, Any]:
    """The outcome of a case whose task died (a worker killed more often than Dask allows)."""
    return {"status": "error", "converged": False, "J": math.nan, "iterations": -1, "gradient_norm": math.nan,
            "solve_time_s": math.nan, "case_time_s": math.nan,
            "error": f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:2000]}


class Progress:
    """One status line on a terminal stream: done / failed / running of the total, rate and ETA.

    Dask's own progress bars count finished futures only, so done, failed and running are
    counted here as results arrive; the line is redrawn at most twice a second."""

    def __init__(self, total: int, done: int, stream: TextIO | None) -> None:
        self.total, self.start_done, self.stream = total, done, stream
        self.t0 = self.last = time.monotonic()

    def update(self, done: int, failed: int, running: int, final: bool = False) -> None:
        if self.stream is None:
            return
        now = time.monotonic()
        if not final and now - self.last < 0.5:
            return
        self.last = now
        rate = (done - self.start_done) / max(now - self.t0, 1e-9)
        left = self.total - done
        eta = _duration(left / rate) if rate > 0 else "?"
        self.stream.write(f"\rsweep: {done}/{self.total} done, {failed} failed, {running} running, "
                          f"{rate:.1f} cases/s, ETA {eta}   " + ("\n" if final else ""))
        self.stream.flush()


def _duration(s: float) -> str:
    s = int(round(s))
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def run_sweep(sweep: Sweep | str | Path, out: str | Path, *, workers: int | None = None, scheduler: str | None = None,
              serial: bool = False, resume: bool = False, csv: bool = False, full: bool = False,
              limit: int | None = None, flush_rows: int = 200, flush_seconds: float = 5.0,
              progress: TextIO | None = None, dashboard: bool = False) -> SweepRun:
    """Run every case of a sweep and write its table to ``out``.

    Args:
        sweep: a sweep file or a :class:`~geoddp.sweep.spec.Sweep`.
        out: output folder (see :mod:`geoddp.sweep.table`); must hold no results unless ``resume``.
        workers: local worker processes (default: every core); ignored with ``scheduler``.
        scheduler: address of a running ``dask.distributed`` scheduler (``tcp://host:8786``).
        serial: solve in this process, one case after another (no Dask).
        resume: solve only the cases whose rows are not in ``out`` yet.
        csv: also write DIR/results.csv.
        full: also write each case's full Result as DIR/cases/<hash>.json (the folder must be
            writable by every worker).
        limit: solve at most this many cases now (the rest later with ``resume``).
        flush_rows, flush_seconds: a part file is written every so many rows or seconds.
        progress: a stream for the status line (e.g. sys.stderr), or None.
        dashboard: start the LocalCluster's dashboard on 127.0.0.1 (a free port).

    Returns:
        :class:`SweepRun`.

    Raises:
        InputError: a bad sweep file (before any case runs), ``out`` holds results without
            ``resume``, bad ``workers`` / ``limit``.
    """
    t0 = time.perf_counter()
    if not isinstance(sweep, Sweep):
        sweep_path = Path(sweep)
        sweep = load_sweep(sweep_path)
    else:
        sweep_path = Path(sweep.source) if sweep.source != "<dict>" else None
    cases = expand(sweep)  # every case validated before anything runs
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InputError("--workers", f"expected a number of worker processes >= 1, got {workers!r}")
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 0):
        raise InputError("--limit", f"expected a number of cases >= 0, got {limit!r}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("--out", f"expected a folder, got the file {str(out)!r}")
    if part_files(out) and not resume:
        raise InputError("--out", f"{str(out)!r} already holds sweep results: pass --resume to finish them, "
                         "or choose another folder")
    out.mkdir(parents=True, exist_ok=True)
    if sweep_path is not None and sweep_path.is_file():
        write_atomic(out / "sweep.toml", sweep_path.read_bytes())
    done = done_hashes(out) if resume else set()
    pending = [c for c in cases if c.hash not in done]
    skipped = len(cases) - len(pending)
    if limit is not None:
        pending = pending[:limit]
    full_dir = str((out / "cases").resolve()) if full else None
    writer = PartWriter(out, len(cases), flush_rows=flush_rows, flush_seconds=flush_seconds)
    bar = Progress(len(cases), skipped, progress)
    write_manifest(out, {"name": sweep.name, "total": len(cases), "finished": False})

    def record(c: Case, outcome: dict[str, Any], running: int) -> None:
        writer.add(make_row(c, outcome))
        bar.update(skipped + writer.written, writer.failed, running)

    try:
        if serial:
            for c in pending:
                record(c, run_case(case_mod.payload(c, full_dir)), 1)
        else:
            _run_dask(pending, record, full_dir, workers=workers, scheduler=scheduler, dashboard=dashboard)
    finally:
        writer.flush()  # what finished is on disk, whatever ended the run
    bar.update(skipped + writer.written, writer.failed, 0, final=True)
    hashes = [c.hash for c in cases]
    df = read_parts(out, hashes)
    complete = len(df) == len(cases)
    table = None
    if complete:
        table = write_table(out, df, csv=csv)[0]
    failed = int((df["status"] == "error").sum()) if len(df) else 0
    write_manifest(out, {"name": sweep.name, "total": len(cases), "done": len(df), "failed": failed,
                         "finished": complete})
    return SweepRun(len(cases), skipped, writer.written, writer.failed, complete, table, time.perf_counter() - t0)


def run_case(p: dict[str, Any]) -> dict[str, Any]:
    """:func:`geoddp.sweep.case.run_case` (the serial executor's indirection, so a test can count calls)."""
    return case_mod.run_case(p)


def _run_dask(pending: list[Case], record: Callable[[Case, dict[str, Any], int], None], full_dir: str | None, *,
              workers: int | None, scheduler: str | None, dashboard: bool) -> None:
    """Submit ``pending`` to a Dask cluster in a sliding window; ``record`` each finished case."""
    import logging

    from distributed import Client, LocalCluster, as_completed

    if not pending:
        return
    cluster = None
    if scheduler is None:
        n = workers or os.cpu_count() or 1
        # host 127.0.0.1: nothing of the local cluster listens beyond this machine. The scheduler's
        # HTTP server starts even without the dashboard, on port 8787 unless told otherwise: a free
        # loopback port, so two sweeps (or a sweep beside a cluster) never collide or warn.
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": dashboard},
                               silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError("--scheduler", f"cannot reach a Dask scheduler at {scheduler!r} ({exc})") from None
    try:
        threads = max(1, sum(client.nthreads().values()))
        window = max(2, IN_FLIGHT_PER_THREAD * threads)
        run_id = f"{os.getpid()}-{time.time_ns()}"
        todo = iter(pending)
        inflight: dict[str, Case] = {}
        ac = as_completed()

        def submit() -> bool:
            c = next(todo, None)
            if c is None:
                return False
            f = client.submit(case_mod.run_case, case_mod.payload(c, full_dir), key=f"geoddp-case-{c.hash[:16]}-{run_id}",
                              pure=False, retries=RETRIES)
            inflight[f.key] = c
            ac.add(f)
            return True

        for _ in range(window):
            if not submit():
                break
        for f in ac:
            c = inflight.pop(f.key)
            try:
                outcome = f.result()
            except Exception as exc:  # KilledWorker: the case's workers kept dying; recorded, not fatal
                outcome = error_outcome(exc)
            f.release()
            record(c, outcome, min(len(inflight), threads))
            submit()
    finally:
        try:
            client.close()
        finally:
            if cluster is not None:
                cluster.close()


__all__ = ["SweepRun", "run_sweep", "make_row", "flatten", "MANIFEST", "Progress"]
