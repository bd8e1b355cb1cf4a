"""Running a sweep: every case validated first, then solved in this process, on a Dask
``LocalCluster`` (all local cores) or on an existing ``dask.distributed`` scheduler; rows streamed
to disk as cases finish; ``resume`` solves only what the folder lacks.

Nothing in the cases changes between the three executors: each case is the same plain payload
given to :func:`geoddp.sweep.case.run_case`, so the tables are equal (timing columns aside).
"""
from __future__ import annotations

import itertools
import math
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from .. import interrupts
from ..output_files import write_atomic
from ..validate import THREADS_ENV, InputError
from . import case as case_mod
from .spec import Case, Sweep, load_sweep, validate_all
from .table import MANIFEST, PARTS, PartWriter, done_hashes, part_files, read_parts, write_manifest, write_table

# Tasks in flight per worker thread: enough to keep every worker busy while a result travels
# back, few enough that 10^5 cases never sit in the scheduler at once (memory stays flat).
IN_FLIGHT_PER_THREAD = 3
RETRIES = 2  # Dask re-runs a task this many times if it raises out of run_cases (it never should)
# Cases per task: a Dask task costs ~1.5-3 ms of scheduler, client and worker time, which the
# cores share with the solves; grouping cases into tasks of ~TASK_SECONDS makes that cost about
# 1 % of the work. At most MAX_CHUNK cases, so a lost worker costs little to redo and memory
# stays flat.
TASK_SECONDS = 0.25
MAX_CHUNK = 64


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


class SweepInterrupted(interrupts.Interrupted):
    """A sweep stopped by SIGINT, SIGTERM or SIGHUP (or Ctrl-C in Python) once every case that
    had finished was written to its folder: ``on_disk`` of the ``total`` cases of the sweep are in
    ``out``/parts (``solved`` of them in this run). Running the sweep again on the same folder with
    ``resume`` solves only the others."""

    def __init__(self, signum: int, out: Path, on_disk: int, total: int, solved: int) -> None:
        super().__init__(signum, f"{on_disk} of {total} cases on disk in {out / PARTS} ({solved} solved in this run)")
        self.out, self.on_disk, self.total, self.solved = out, on_disk, total, solved

    def __str__(self) -> str:
        return f"{signal.Signals(self.signum).name}: {self.note}; resume with run_sweep(..., resume=True)"


# Seconds an interrupted sweep waits for the outcomes of tasks its workers have finished but not
# yet sent back: they are recorded with the rest (a task still running is solved again on resume).
HARVEST_SECONDS = 10.0


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
    """The sweep's progress bar on a stream (tqdm's): cases done of the total with rate and time
    left, and the failed and running counts beside it. Cases already on disk (resume) start the
    bar; the rate and the estimate count only the cases run now."""

    def __init__(self, total: int, done: int, stream: TextIO | None) -> None:
        self.bar = None
        if stream is not None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=done, file=stream, unit="case", desc="sweep", mininterval=0.5,
                            dynamic_ncols=True, smoothing=0.05)
        self.done = done

    def close(self) -> None:
        """End the bar where it stands (an interrupted run)."""
        if self.bar is not None:
            self.bar.close()

    def update(self, done: int, failed: int, running: int, final: bool = False) -> None:
        if self.bar is None:
            return
        self.bar.set_postfix_str(f"{failed} failed, {running} running", refresh=False)
        self.bar.update(done - self.done)
        self.done = done
        if final:
            self.bar.close()


def require_extra(*, dask: bool, progress: bool) -> None:
    """Refuse at once, naming the extra, when a package of ``geoddp[sweep]`` is missing (the
    table needs pandas and pyarrow, a cluster distributed, the progress bar tqdm)."""
    import importlib.util

    wanted = ["pandas", "pyarrow"] + (["distributed"] if dask else []) + (["tqdm"] if progress else [])
    missing = []
    for name in wanted:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a module set to None in sys.modules, or a broken one
            found = False
        if not found:
            missing.append(name)
    if missing:
        raise InputError("geoddp sweep", f"needs the 'sweep' extra, which is not installed (missing: "
                         f"{', '.join(missing)}): pip install 'geoddp[sweep]'")


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
        SweepInterrupted: SIGINT, SIGTERM or SIGHUP (as raised by the CLI's handler) or
            KeyboardInterrupt during the run, after every finished case was written: those
            received from the workers, those the workers had finished (fetched for up to
            :data:`HARVEST_SECONDS`), before the cluster is closed; a further signal does not
            cut that write short. It says how many cases are on disk.
    """
    t0 = time.perf_counter()
    if not isinstance(sweep, Sweep):
        sweep_path = Path(sweep)
        sweep = load_sweep(sweep_path)
    else:
        sweep_path = Path(sweep.source) if sweep.source != "<dict>" else None
    # Every case validated before anything runs; only the hashes are kept, and the cases are
    # generated again as they are submitted (memory stays flat). Serial: the specs validated
    # here are the ones solved (a serial sweep is one process's work anyway).
    specs: list[Any] | None = [] if serial else None
    hashes = validate_all(sweep, specs)
    require_extra(dask=not serial, progress=progress is not None)
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
    total = len(hashes)
    writer = PartWriter(out, total, flush_rows=flush_rows, flush_seconds=flush_seconds)
    bar: Progress | None = None

    def record(c: Case, outcome: dict[str, Any], running: int) -> None:
        writer.add(make_row(c, outcome))
        if bar is not None:
            bar.update(skipped + writer.written, writer.failed, running)

    try:
        if sweep_path is not None and sweep_path.is_file():
            write_atomic(out / "sweep.toml", sweep_path.read_bytes())
        done = done_hashes(out) if resume else set()
        n_pending = sum(h not in done for h in hashes)
        skipped = total - n_pending
        if limit is not None:
            n_pending = min(n_pending, limit)
        pending = itertools.islice((c for c in sweep.cases() if c.hash not in done), n_pending)
        full_dir = str((out / "cases").resolve()) if full else None
        bar = Progress(total, skipped, progress)
        write_manifest(out, {"name": sweep.name, "total": total, "finished": False})
        if serial:
            spec_of = dict(zip(hashes, specs or []))
            for c in pending:
                record(c, run_case(case_mod.payload(c, full_dir, spec_of.get(c.hash))), 1)
                interrupts.check()  # a Ctrl-C whose exception a gc callback swallowed ends the run here
        else:
            _run_dask(pending, n_pending, record, full_dir, workers=workers, scheduler=scheduler, dashboard=dashboard,
                      flush=writer.flush)
        writer.flush()
        bar.update(skipped + writer.written, writer.failed, 0, final=True)
        df = read_parts(out, hashes)
        complete = len(df) == total
        table = None
        if complete:
            table = write_table(out, df, csv=csv)[0]
        failed = int((df["status"] == "error").sum()) if len(df) else 0
        write_manifest(out, {"name": sweep.name, "total": total, "done": len(df), "failed": failed,
                             "finished": complete})
    except KeyboardInterrupt as exc:
        # Whatever was running (a case, the cluster, the final table): every finished case is
        # written, with further signals deferred, then counted on disk for the message.
        try:
            with interrupts.deferred():  # a second Ctrl-C does not cut the write short
                writer.flush()
                if bar is not None:
                    bar.close()
                on_disk = len(done_hashes(out) & set(hashes))
                write_manifest(out, {"name": sweep.name, "total": total, "done": on_disk, "finished": False})
        except KeyboardInterrupt:  # a second signal, held until the write ended: the first is reported
            pass
        signum = exc.signum if isinstance(exc, interrupts.Interrupted) else signal.SIGINT
        raise SweepInterrupted(signum, out, on_disk, total, writer.written) from None
    finally:
        writer.flush()  # what finished is on disk, whatever ended the run
    return SweepRun(total, skipped, writer.written, writer.failed, complete, table, time.perf_counter() - t0)


def run_case(p: dict[str, Any]) -> dict[str, Any]:
    """:func:`geoddp.sweep.case.run_case` (the serial executor's indirection, so a test can count calls)."""
    return case_mod.run_case(p)


def local_cluster(workers: int, dashboard: bool = False) -> Any:
    """The sweep's own Dask ``LocalCluster``: ``workers`` processes of one thread each, everything
    on 127.0.0.1, the cores shared out among the workers (:func:`worker_env`) and no statistical
    profiler in them (it samples every thread's stack 100 times a second: a few % of a 2-core
    machine's solves) unless a dashboard would show it."""
    import logging

    import dask
    from distributed import LocalCluster

    # host 127.0.0.1: nothing of the local cluster listens beyond this machine. The scheduler's
    # HTTP server starts even without the dashboard, on port 8787 unless told otherwise: a free
    # loopback port, so two sweeps (or a sweep beside a cluster) never collide or warn.
    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in every worker (against fragmentation in
    # long-lived data workers). Setting any of glibc's malloc thresholds switches off its dynamic
    # mmap threshold, so every array above 128 KiB (a 1500-step trajectory's Jacobians) is a fresh
    # mmap, page-faulted in and unmapped on free: 2.6x the page faults and solves 20-30 % slower
    # in a worker than in the main process (benchmarks/sweep.py). None unsets it (Dask's rule).
    with dask.config.set({"distributed.worker.profile.enabled": dashboard,
                          "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": dashboard},
                            silence_logs=logging.ERROR, env=worker_env(workers))


def worker_env(workers: int, cores: int | None = None) -> dict[str, str]:
    """Environment of a local cluster's worker processes: the cores shared out among them
    (GEODDP_THREADS = cores // workers, at least 1), so that the compiled passes of two workers
    on two cores run on one thread each instead of two each."""
    cores = cores or os.cpu_count() or 1
    return {THREADS_ENV: str(max(1, cores // max(1, workers)))}


def run_cases(payloads: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One Dask task: several cases in a row, their outcomes in the same order (a case that
    raises is an "error" row, so one bad case never costs its neighbours)."""
    return [case_mod.run_case(p) for p in payloads]


class ChunkSizer:
    """How many cases the next task gets.

    One case a task until a case's time is known, then enough cases for about
    :data:`TASK_SECONDS` (the mean case time so far), but never more than an even share of
    what is left over twice the worker threads, so the sweep's tail stays balanced, and never
    more than :data:`MAX_CHUNK`."""

    def __init__(self, threads: int) -> None:
        self.threads = max(1, threads)
        self.n = 0
        self.seconds = 0.0

    def observe(self, case_time_s: float) -> None:
        if math.isfinite(case_time_s) and case_time_s >= 0.0:
            self.n += 1
            self.seconds += case_time_s

    def size(self, remaining: int) -> int:
        if self.n == 0 or remaining <= 0:
            return 1
        mean = max(self.seconds / self.n, 1e-6)
        want = int(TASK_SECONDS / mean)
        share = remaining // (2 * self.threads)
        return max(1, min(want, share, MAX_CHUNK))


def _run_dask(pending: Iterator[Case], n_pending: int, record: Callable[[Case, dict[str, Any], int], None],
              full_dir: str | None, *, workers: int | None, scheduler: str | None, dashboard: bool,
              flush: Callable[[], None] = lambda: None) -> None:
    """Submit the ``n_pending`` cases of ``pending`` (generated as they go) to a Dask cluster in a
    sliding window of tasks; ``record`` each finished case.

    Interrupted (KeyboardInterrupt), it records, with further signals deferred, the outcomes in
    hand and those of tasks the workers have finished (:func:`_harvest`), then calls ``flush``,
    all before the cluster is closed (which takes seconds), and raises again."""
    from distributed import Client, as_completed

    if n_pending == 0:
        return
    cluster = None
    if scheduler is None:
        cluster = local_cluster(workers or os.cpu_count() or 1, dashboard)
        client = Client(cluster)
        try:
            # Ctrl-C in a terminal signals the whole process group, our workers too: they leave
            # it to this process, which records what they finished and closes them (each worker
            # died of it mid-task before, printing a ~30-line traceback).
            client.run(ignore_sigint)
        except BaseException:
            client.close()
            cluster.close()
            raise
    else:
        try:
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError("--scheduler", f"cannot reach a Dask scheduler at {scheduler!r} ({exc})") from None
    inflight: dict[str, tuple[Any, list[Case]]] = {}  # task key -> (future, its cases)
    in_hand: list[tuple[Case, dict[str, Any]]] = []  # outcomes received, not yet recorded
    try:
        threads = max(1, sum(client.nthreads().values()))
        window = max(2, IN_FLIGHT_PER_THREAD * threads)
        run_id = f"{os.getpid()}-{time.time_ns()}"
        sizer = ChunkSizer(threads)
        left = n_pending
        ac = as_completed()

        def submit() -> bool:
            nonlocal left
            if left == 0:
                return False
            group = list(itertools.islice(pending, min(sizer.size(left), left)))
            left -= len(group)
            f = client.submit(run_cases, [case_mod.payload(c, full_dir) for c in group],
                              key=f"geoddp-cases-{group[0].hash[:16]}-{len(group)}-{run_id}", pure=False,
                              retries=RETRIES)
            inflight[f.key] = (f, group)
            ac.add(f)
            return True

        for _ in range(window):
            if not submit():
                break
        for f in ac:
            group = inflight[f.key][1]
            try:
                outcomes = f.result()
            except Exception as exc:  # KilledWorker: the task's workers kept dying; recorded, not fatal
                interrupts.check()  # ... unless an interruption surfaced as another exception
                outcomes = [error_outcome(exc)] * len(group)
            in_hand.extend(zip(group, outcomes))
            del inflight[f.key]
            f.release()
            running = min(sum(len(g) for _, g in inflight.values()), threads)
            while in_hand:
                c, outcome = in_hand[0]
                sizer.observe(outcome.get("case_time_s", math.nan))
                record(c, outcome, running)
                in_hand.pop(0)
            interrupts.check()  # a Ctrl-C whose exception a gc callback swallowed ends the run here
            submit()
    except KeyboardInterrupt:
        try:
            with interrupts.deferred():  # a second Ctrl-C does not cut the write short
                in_hand.extend(_harvest([f for f, _ in inflight.values()], {k: g for k, (_, g) in inflight.items()}))
                for c, outcome in in_hand:
                    record(c, outcome, 0)  # the writer ignores a case it already has
                flush()  # before the cluster closes (seconds)
        except KeyboardInterrupt:  # a second signal, held until the write ended: the first one goes on
            pass
        raise
    finally:
        try:
            if cluster is not None:
                quiet_teardown(client)
            client.close()
        finally:
            if cluster is not None:
                cluster.close()


def _harvest(futures: list[Any], groups: dict[str, list[Case]], seconds: float = HARVEST_SECONDS
             ) -> list[tuple[Case, dict[str, Any]]]:
    """The (case, outcome) pairs of the tasks among ``futures`` that a worker has finished (the
    scheduler knows it) but whose results this process has not fetched yet: fetched now, within
    ``seconds`` in all. A task that failed, or whose result cannot be fetched in time, is left out
    (resume solves its cases)."""
    out: list[tuple[Case, dict[str, Any]]] = []
    deadline = time.monotonic() + seconds
    for f in futures:
        left = deadline - time.monotonic()
        if f.status != "finished" or left <= 0:
            continue
        try:
            out.extend(zip(groups[f.key], f.result(timeout=left)))
        except Exception:  # lost with its worker, or too slow to fetch: solved again on resume
            continue
    return out


def ignore_sigint() -> bool:
    """Run on the workers of the sweep's own LocalCluster (``client.run``, in the worker's
    event-loop thread, its main thread): the worker process ignores SIGINT. True if it was set
    (False where the worker does not own its process's main thread: nothing is changed)."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:
        return False
    return True


def quiet_teardown(client: Any) -> None:
    """Before our own LocalCluster closes, once every case is in: its workers stop logging below
    CRITICAL. Closing the cluster removes each worker from the scheduler while the worker may have
    a heartbeat in flight; the worker then logs "Failed to communicate with scheduler during
    heartbeat" with a 30-line traceback on stderr (a race: 1 CLI sweep in 12 on 2 workers here,
    then none in 30 more; Dask's open issue dask/distributed#7192), after a sweep that
    succeeded. Nothing is left for the workers to report then (every outcome was recorded), and
    a failure to reach them here is not one of the sweep's."""
    import logging

    try:
        client.run(_silence_worker, on_error="ignore")
    except Exception:  # the workers are gone already: nothing to silence
        logging.getLogger(__name__).debug("workers not reached before closing the cluster", exc_info=True)


def _silence_worker() -> None:
    import logging

    for name in ("distributed", "distributed.worker", "distributed.nanny", "distributed.core"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


__all__ = ["SweepRun", "SweepInterrupted", "HARVEST_SECONDS", "ignore_sigint", "run_sweep", "run_cases",
           "ChunkSizer", "require_extra", "local_cluster", "quiet_teardown", "worker_env", "make_row", "flatten",
           "MANIFEST", "Progress"]
