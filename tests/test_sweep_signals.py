"""Sweeps lose nothing on SIGINT or SIGTERM: a real ``geoddp sweep`` process is signalled while
it runs (serially, on its own LocalCluster of 2 workers, and on an external scheduler with workers
started here as processes), once its progress bar shows finished cases. Parts are flushed only at
the end (``--flush-rows 100000 --flush-seconds 3600``), so every row on disk after the signal was
written because of it. Then: exit 130 / 143; one stderr line stating the rows on disk (the number
on disk), where, and the command that resumes; every case the bar had shown finished is on disk;
each row equals the case solved directly; the resume command solves exactly the other cases (each
hash once on disk over both runs).

Synchronisation polls with timeouts (the progress bar, the part files, the scheduler file); no
sleep stands in for an event. Every process started here listens on 127.0.0.1 and is stopped by
its PID.
"""
from __future__ import annotations

import importlib
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from geoddp import interrupts
from geoddp.sweep import expand, load_sweep
from geoddp.sweep.run import HARVEST_SECONDS, _harvest
from geoddp.sweep.table import part_files
from processes import env, stop

DASK = Path(sys.executable).parent / "dask"
TOTAL = 60
# ~50-100 ms a case: a signal after the first few rows lands with most of the sweep to go
SWEEP = f"""
[sweep]
scene = "satellite_paper"
seed = 13
samples = {TOTAL}
[scene]
horizon.tf = 3.0
horizon.dt = 0.001
solver.max_iter = 30
[[random]]
key = "target.quaternion"
distribution = "haar"
"""
NO_FLUSH = ["--flush-rows", "100000", "--flush-seconds", "3600"]
MESSAGE = re.compile(r"^geoddp: interrupted by (SIG[A-Z]+); (\d+) of (\d+) cases on disk in (.+) "
                     r"\((\d+) solved in this run\); resume with: (.+)$")
BAR = re.compile(rb"(\d+)/" + str(TOTAL).encode() + rb"\b")


def wait_for(what: str, predicate, timeout: float = 120.0, proc: subprocess.Popen | None = None) -> None:
    """Poll ``predicate`` every 20 ms until it holds; fail after ``timeout`` s (or when ``proc``
    has ended first)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert proc is None or proc.poll() is None, f"the process ended before {what}"
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


class Stderr:
    """Reads a process's stderr in a thread (the progress bar and the final line)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.buf = bytearray()
        self.thread = threading.Thread(target=self._read, args=(proc.stderr,), daemon=True)
        self.thread.start()

    def _read(self, stream) -> None:
        while chunk := stream.read1(4096):
            self.buf.extend(chunk)

    def finished_cases(self) -> int:
        """The last count of finished cases the progress bar showed."""
        found = BAR.findall(bytes(self.buf))
        return int(found[-1]) if found else 0

    def lines(self) -> list[str]:
        """The lines that are not the progress bar."""
        return [ln.decode() for ln in re.split(rb"[\r\n]", bytes(self.buf)) if ln.strip() and not BAR.search(ln)]


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("sweep") / "signals.toml"
    path.write_text(SWEEP)
    return path


@pytest.fixture(scope="module")
def direct(sweep_file) -> dict[str, tuple[float, int, str]]:
    """Every case solved directly (solve_scene on its scene, no sweep machinery): hash -> (J,
    iterations, status)."""
    from geoddp import solve_scene
    from geoddp.scene import parse_scene

    out = {}
    for c in expand(load_sweep(sweep_file)):
        r = solve_scene(parse_scene(c.scene, c.source), verbose=False)
        out[c.hash] = (r.cost, r.iterations, str(r.status))
    assert len(out) == TOTAL
    return out


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """An external scheduler (``dask scheduler --host 127.0.0.1 --dashboard-address 127.0.0.1:0``)
    and 2 workers (``dask worker``), each a process started here, stopped by its PID."""
    pytest.importorskip("distributed")
    d = tmp_path_factory.mktemp("dask")
    sfile = d / "scheduler.json"
    procs = [subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
                               "127.0.0.1:0", "--scheduler-file", str(sfile)], env=env(),
                              stdout=subprocess.DEVNULL, stderr=open(d / "scheduler.log", "wb"))]
    try:
        wait_for("the scheduler file", sfile.exists, 60, procs[0])
        for i in range(2):  # --no-nanny: the worker is this very process, stopped by its PID
            procs.append(subprocess.Popen([str(DASK), "worker", "--scheduler-file", str(sfile), "--host", "127.0.0.1",
                                           "--no-dashboard", "--nthreads", "1", "--no-nanny", "--name", f"w{i}"],
                                          env=env(), stdout=subprocess.DEVNULL, stderr=open(d / f"w{i}.log", "wb")))
        import distributed

        with distributed.Client(scheduler_file=str(sfile), timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
            address = c.scheduler.address
        assert address.startswith("tcp://127.0.0.1:")
        yield address
    finally:
        for p in reversed(procs):
            stop(p)


def hashes_on_disk(out: Path) -> list[str]:
    return [h for p in part_files(out) for h in pd.read_parquet(p, columns=["hash"])["hash"]]


def interrupt(sweep_file: Path, out: Path, executor: list[str], sig: int, group: bool = False
              ) -> tuple[subprocess.Popen, Stderr, int, int]:
    """Start ``geoddp sweep`` and send it ``sig`` once its bar shows 3 finished cases (to its whole
    process group if ``group``: Ctrl-C in a terminal); (process, its stderr, cases shown finished
    before the signal, part files on disk before it)."""
    cmd = [sys.executable, "-m", "geoddp.cli", "sweep", str(sweep_file), "--out", str(out), *executor, *NO_FLUSH]

    def child() -> None:
        # SIGINT at its default (a suite started as a background job inherits it ignored); a
        # process group of its own, so a signal to the group reaches the sweep and its workers only
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.setsid()

    proc = subprocess.Popen(cmd, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=child)
    err = Stderr(proc)
    try:
        wait_for("3 finished cases", lambda: err.finished_cases() >= 3, 180, proc)
        seen, parts_before = err.finished_cases(), len(part_files(out))
        (os.killpg if group else os.kill)(proc.pid, sig)
        proc.wait(timeout=120)
        err.thread.join(timeout=30)
    finally:
        stop(proc)
    return proc, err, seen, parts_before


def resume(command: str) -> subprocess.CompletedProcess:
    argv = shlex.split(command)
    assert argv[:2] == ["geoddp", "sweep"] and "--resume" in argv
    return subprocess.run([sys.executable, "-m", "geoddp.cli", *argv[1:], "--quiet"], env=env(), capture_output=True,
                          text=True, timeout=600)


EXECUTORS = {"serial": ["--serial"], "local cluster": ["--workers", "2"], "scheduler": None}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("executor", list(EXECUTORS))
def test_a_signalled_sweep_keeps_every_finished_case_and_resumes(request, sweep_file, direct, tmp_path, executor,
                                                                 sig):
    if executor == "scheduler":
        run_on = ["--scheduler", request.getfixturevalue("scheduler")]
    else:
        if executor == "local cluster":
            pytest.importorskip("distributed")
        run_on = EXECUTORS[executor]
    out = tmp_path / "out"
    proc, err, seen, parts_before = interrupt(sweep_file, out, run_on, sig)
    check_interrupted(proc, err, seen, parts_before, out, sig, direct)
    check_resumed(err, out, direct)


def test_ctrl_c_in_a_terminal_signals_the_workers_too_and_loses_nothing(sweep_file, direct, tmp_path):
    # The terminal sends SIGINT to the whole foreground process group: our LocalCluster's worker
    # processes ignore it (they printed a traceback each and dropped their task before) and the
    # sweep writes what they finished.
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    proc, err, seen, parts_before = interrupt(sweep_file, out, ["--workers", "2"], signal.SIGINT, group=True)
    check_interrupted(proc, err, seen, parts_before, out, signal.SIGINT, direct)
    check_resumed(err, out, direct)


def check_interrupted(proc, err: Stderr, seen: int, parts_before: int, out: Path, sig: int,
                      direct: dict[str, tuple[float, int, str]]) -> None:
    assert proc.returncode == 128 + sig, err.lines()
    lines = err.lines()
    assert len(lines) == 1, lines  # the one line, no traceback (a worker's included)
    m = MESSAGE.match(lines[0])
    assert m, lines[0]
    name, stated, total, where, solved = m.group(1), int(m.group(2)), int(m.group(3)), m.group(4), int(m.group(5))
    assert name == signal.Signals(sig).name and total == TOTAL and where == str(out / "parts")
    on_disk = hashes_on_disk(out)
    assert len(on_disk) == stated == solved  # the number stated is the number on disk
    assert len(set(on_disk)) == len(on_disk)  # each case once
    assert parts_before == 0  # nothing was flushed before the signal: every row is there because of it
    assert seen <= stated < TOTAL  # every case the bar had shown finished, and the sweep was cut short
    rows = pd.concat([pd.read_parquet(p) for p in part_files(out)])
    for _, row in rows.iterrows():  # each row is its case solved directly
        assert (row["J"], row["iterations"], row["status"]) == direct[row["hash"]], row["case"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["done"] == stated and manifest["finished"] is False and manifest["total"] == TOTAL
    assert not (out / "results.parquet").exists()


def check_resumed(err: Stderr, out: Path, direct: dict[str, tuple[float, int, str]]) -> None:
    m = MESSAGE.match(err.lines()[0])
    stated, command = int(m.group(2)), m.group(6)
    again = resume(command)
    assert again.returncode == 0, again.stderr
    # the resumed run solved exactly the other cases: none on disk solved again
    assert f"{TOTAL} cases: {stated} already done, {TOTAL - stated} solved now (0 raised)" in again.stdout
    on_disk = hashes_on_disk(out)
    assert len(on_disk) == TOTAL and set(on_disk) == set(direct)  # each case once over both runs
    table = pd.read_parquet(out / "results.parquet")
    assert len(table) == TOTAL
    assert all((r.J, r.iterations, r.status) == direct[r.hash] for r in table.itertuples())


# ------------------------------------------------------------------ in this process


def test_deferred_holds_a_signal_until_the_block_ends():
    # The CLI's handler records the signal and, while deferring, does not raise: the block runs
    # to its end, then the signal is raised.
    cli = importlib.import_module("geoddp.cli.main")  # the module (geoddp.cli.main is also the function)

    interrupts.clear()
    reached = []
    try:
        with pytest.raises(interrupts.Interrupted) as exc:
            with interrupts.deferred():
                assert interrupts.deferring()
                cli._on_signal(signal.SIGTERM, None)  # as if SIGTERM arrived here
                reached.append("end of block")
        assert reached == ["end of block"] and exc.value.signum == signal.SIGTERM
        assert not interrupts.deferring()
        with pytest.raises(interrupts.Interrupted):
            cli._on_signal(signal.SIGINT, None)  # outside a deferred block: raised at once
    finally:
        interrupts.clear()


def test_deferred_holds_a_real_ctrl_c_of_a_library_user():
    # Python's own SIGINT handler (no CLI): a real SIGINT in the block is noted and raised after.
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT is not at Python's default handler in this process (a background job)")
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler runs here, between bytecodes; the block goes on
            reached.append("end of block")
    assert reached == ["end of block"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


class FakeFuture:
    def __init__(self, key: str, status: str, result=None, error: Exception | None = None, delay: float = 0.0):
        self.key, self.status, self._result, self._error, self._delay = key, status, result, error, delay

    def result(self, timeout=None):
        if self._delay > (timeout or 0):
            raise TimeoutError
        if self._error is not None:
            raise self._error
        return self._result


def test_harvest_fetches_what_the_workers_finished_and_nothing_else():
    groups = {"a": ["c1", "c2"], "b": ["c3"], "c": ["c4"], "d": ["c5"], "e": ["c6"]}
    futures = [FakeFuture("a", "finished", [{"J": 1.0}, {"J": 2.0}]), FakeFuture("b", "pending"),
               FakeFuture("c", "finished", error=RuntimeError("worker lost")), FakeFuture("d", "error"),
               FakeFuture("e", "finished", [{"J": 6.0}], delay=2 * HARVEST_SECONDS)]
    got = _harvest(futures, groups)
    assert got == [("c1", {"J": 1.0}), ("c2", {"J": 2.0})]


def test_a_second_signal_during_the_final_write_does_not_cut_it_short(tmp_path, monkeypatch):
    # SIGINT during the 5th case; then SIGTERM (the CLI's handler) while the finished rows are
    # being written: the write completes, the first signal is the one reported, nothing is lost.
    cli = importlib.import_module("geoddp.cli.main")  # the module (geoddp.cli.main is also the function)
    from geoddp.sweep import run as run_mod
    from geoddp.sweep.run import SweepInterrupted
    from geoddp.sweep.table import PartWriter

    path = tmp_path / "small.toml"
    path.write_text(SWEEP.replace(f"samples = {TOTAL}", "samples = 8").replace("horizon.tf = 3.0", "horizon.tf = 0.3")
                    .replace("horizon.dt = 0.001", "horizon.dt = 0.05"))
    real_case, real_flush = run_mod.run_case, PartWriter.flush
    solved: list[str] = []

    def case(p):
        if len(solved) == 4:
            cli._on_signal(signal.SIGINT, None)  # raises Interrupted, as the handler does
        solved.append(p["hash"])
        return real_case(p)

    def flush(self):
        if self.rows:
            cli._on_signal(signal.SIGTERM, None)  # recorded, not raised: the write is deferred
        real_flush(self)

    monkeypatch.setattr(run_mod, "run_case", case)
    monkeypatch.setattr(PartWriter, "flush", flush)
    interrupts.clear()
    try:
        with pytest.raises(SweepInterrupted) as exc:
            run_mod.run_sweep(path, tmp_path / "out", serial=True, flush_rows=100, flush_seconds=3600)
    finally:
        interrupts.clear()
    assert exc.value.signum == signal.SIGINT and exc.value.on_disk == exc.value.solved == 4
    assert sorted(hashes_on_disk(tmp_path / "out")) == sorted(solved[:4])
    assert "4 of 8 cases on disk" in exc.value.note
