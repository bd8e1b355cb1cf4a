"""Sweeps across processes (issue 17): a LocalCluster of 2 workers, a scheduler and workers
started here with Dask's own CLI (``dask scheduler``, ``dask worker``) on 127.0.0.1, a worker
killed mid-sweep, and a sweep interrupted with SIGINT then resumed.

Every table is compared with the same cases solved serially in this process, column by column
and exactly (timing columns aside). Every process started here listens on 127.0.0.1 only and is
stopped by its PID."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from geoddp.sweep import TIMING_COLUMNS, read_table, run_sweep
from geoddp.sweep.table import part_files
from processes import env, stop

distributed = pytest.importorskip("distributed")

DASK = Path(sys.executable).parent / "dask"

SMALL = """
[sweep]
scene = "satellite_paper"
seed = 11
samples = 4
[scene]
horizon.tf = 0.5
horizon.dt = 0.05
[grid]
cost.control = [0.1, 1.0]
[[random]]
key = "target.quaternion"
distribution = "haar"
"""

# Slower cases (H = 1500 steps): a kill or a SIGINT lands while cases are running.
SLOW = """
[sweep]
scene = "satellite_paper"
seed = 5
samples = 24
[scene]
horizon.tf = 1.5
horizon.dt = 0.001
solver.max_iter = 30
[[random]]
key = "target.quaternion"
distribution = "haar"
"""


def comparable(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=[c for c in TIMING_COLUMNS if c in df.columns])


def write(tmp_path: Path, text: str, name: str) -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def start_worker(scheduler_file: Path, name: str, log: Path) -> subprocess.Popen:
    # --no-nanny: the worker is this very process, so killing its PID kills the worker
    return subprocess.Popen([str(DASK), "worker", "--scheduler-file", str(scheduler_file), "--host", "127.0.0.1",
                             "--no-dashboard", "--nthreads", "1", "--no-nanny", "--name", name],
                            env=env(), stdout=subprocess.DEVNULL, stderr=open(log, "wb"))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler and 2 workers, each a separate process started with Dask's CLI on 127.0.0.1."""
    d = tmp_path_factory.mktemp("dask")
    sfile = d / "scheduler.json"
    procs = [subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sfile)], env=env(), stdout=subprocess.DEVNULL,
                              stderr=open(d / "scheduler.log", "wb"))]
    try:
        deadline = time.monotonic() + 60
        while not sfile.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert sfile.exists(), (d / "scheduler.log").read_text()
        procs += [start_worker(sfile, f"w{i}", d / f"w{i}.log") for i in range(2)]
        with distributed.Client(scheduler_file=str(sfile), timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
            address = c.scheduler.address
        assert address.startswith("tcp://127.0.0.1:")
        yield {"address": address, "file": sfile, "dir": d}
    finally:
        for p in reversed(procs):
            stop(p)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    d = tmp_path_factory.mktemp("small")
    path = write(d, SMALL, "small.toml")
    run_sweep(path, d / "serial", serial=True)
    return path, comparable(read_table(d / "serial"))


def test_local_cluster_of_two_workers_equals_serial(small, tmp_path):
    path, serial = small
    run = run_sweep(path, tmp_path / "local", workers=2)
    assert run.complete and run.solved == len(serial) == 8
    pd.testing.assert_frame_equal(comparable(read_table(tmp_path / "local")), serial, check_exact=True)


def _worker_log_level() -> int:
    import logging

    return logging.getLogger("distributed.worker").getEffectiveLevel()


def test_our_cluster_workers_go_quiet_before_it_closes():
    """quiet_teardown, which run_sweep calls on its own LocalCluster once every case is in: each
    worker's Dask loggers drop to CRITICAL, so a heartbeat caught by the closing scheduler does
    not print a traceback after a sweep that succeeded (dask/distributed#7192: 1 CLI sweep in 12
    on 2 workers did before); on a client whose workers are gone it does nothing and raises
    nothing."""
    import logging

    from geoddp.sweep.run import local_cluster, quiet_teardown

    with local_cluster(2) as c, distributed.Client(c) as client:
        client.wait_for_workers(2, timeout=60)
        before = client.run(_worker_log_level)
        assert len(before) == 2 and all(level < logging.CRITICAL for level in before.values())
        quiet_teardown(client)
        after = client.run(_worker_log_level)
        assert set(after) == set(before) and all(level == logging.CRITICAL for level in after.values())
        assert logging.getLogger("distributed.worker").getEffectiveLevel() < logging.CRITICAL  # not this process's
    quiet_teardown(client)  # closed: nothing to reach


def test_scheduler_address_gives_the_same_table(small, cluster, tmp_path):
    path, serial = small
    out = tmp_path / "remote"
    proc = subprocess.run([sys.executable, "-m", "geoddp.cli", "sweep", str(path), "--out", str(out),
                           "--scheduler", cluster["address"], "--quiet"], env=env(), capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    pd.testing.assert_frame_equal(comparable(read_table(out)), serial, check_exact=True)
    with distributed.Client(cluster["address"], timeout=30) as c:  # the cases ran on the workers
        assert len(c.nthreads()) >= 2


def hashes_on_disk(out: Path) -> list[str]:
    return [h for p in part_files(out) for h in pd.read_parquet(p, columns=["hash"])["hash"]]


@pytest.fixture(scope="module")
def slow(tmp_path_factory):
    d = tmp_path_factory.mktemp("slow")
    path = write(d, SLOW, "slow.toml")
    run_sweep(path, d / "serial", serial=True)
    return path, comparable(read_table(d / "serial"))


def test_a_worker_killed_mid_sweep_loses_no_case(slow, cluster, tmp_path):
    path, serial = slow
    victim = start_worker(cluster["file"], "victim", tmp_path / "victim.log")
    out = tmp_path / "out"
    sweep = None
    try:
        with distributed.Client(cluster["address"], timeout=30) as c:
            c.wait_for_workers(3, timeout=120)
            addr = next(a for a, w in c.scheduler_info()["workers"].items() if w["name"] == "victim")
            sweep = subprocess.Popen([sys.executable, "-m", "geoddp.cli", "sweep", str(path), "--out", str(out),
                                      "--scheduler", cluster["address"], "--quiet", "--flush-rows", "1"],
                                     env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            deadline = time.monotonic() + 120
            while not c.processing(workers=[addr]).get(addr) and time.monotonic() < deadline:
                time.sleep(0.02)
            assert c.processing(workers=[addr]).get(addr), "the victim never got a case"
            os.kill(victim.pid, signal.SIGKILL)  # mid-case: it holds at least one task
            victim.wait(timeout=30)
        stdout, stderr = sweep.communicate(timeout=300)
        assert sweep.returncode == 0, stderr
    finally:
        stop(victim)
        if sweep is not None:
            stop(sweep)
    on_disk = hashes_on_disk(out)
    assert sorted(on_disk) == sorted(serial["hash"])  # every case once: none lost, none twice
    df = comparable(read_table(out))
    assert (df["status"] != "error").all()
    pd.testing.assert_frame_equal(df, serial, check_exact=True)


def test_sigint_then_resume_equals_uninterrupted(slow, tmp_path):
    path, serial = slow
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "geoddp.cli", "sweep", str(path), "--out", str(out), "--workers", "2", "--quiet",
           "--flush-rows", "1"]
    # SIGINT at its default in the child (a suite started as a background job inherits it ignored)
    proc = subprocess.Popen(cmd, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 180
        while len(part_files(out)) < 3 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the sweep ended before it could be interrupted"
        os.kill(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        stop(proc)
    assert proc.returncode == 130, stderr
    first = hashes_on_disk(out)
    assert 3 <= len(first) < len(serial) and len(set(first)) == len(first)
    assert not (out / "results.parquet").exists()
    again = subprocess.run(cmd + ["--resume"], env=env(), capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert f"{len(first)} already done, {len(serial) - len(first)} solved now" in again.stdout
    on_disk = hashes_on_disk(out)
    assert sorted(on_disk) == sorted(serial["hash"])  # each case recorded once over both runs
    pd.testing.assert_frame_equal(comparable(read_table(out)), serial, check_exact=True)


def test_local_workers_share_the_cores_and_run_without_the_profiler(monkeypatch):
    # The sweep's own LocalCluster: GEODDP_THREADS = cores // workers in each worker (two workers
    # on two cores must not start two compiled threads each), Dask's profiler off, and glibc's
    # malloc left to its dynamic mmap threshold (Dask's MALLOC_TRIM_THRESHOLD_ made every large
    # array a fresh mmap: solves 20-30 % slower in a worker, benchmarks/sweep.py).
    import dask

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)

    from geoddp.sweep.run import local_cluster, worker_env

    assert worker_env(2, cores=2) == {"GEODDP_THREADS": "1"}
    assert worker_env(1, cores=2) == {"GEODDP_THREADS": "2"} and worker_env(3, cores=2) == {"GEODDP_THREADS": "1"}
    cluster = local_cluster(2)
    try:
        with distributed.Client(cluster) as c:
            seen = c.run(lambda: (os.environ.get("GEODDP_THREADS"),
                                  dask.config.get("distributed.worker.profile.enabled"),
                                  os.environ.get("MALLOC_TRIM_THRESHOLD_")))
    finally:
        cluster.close()
    want = str(max(1, (os.cpu_count() or 1) // 2))
    assert len(seen) == 2 and all(v == (want, False, None) for v in seen.values()), seen
    assert all(a.startswith("tcp://127.0.0.1:") for a in seen)
