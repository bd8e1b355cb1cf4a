"""Sweeps in one process (issue 17): sweep files, validation before anything runs, content
hashes, the serial runner, resume (counting solves), recorded errors, the summary.

The multi-process tests (LocalCluster, a scheduler and workers, a killed worker, SIGINT) are in
tests/test_sweep_dask.py."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from geoddp import solve_scene
from geoddp.cli import main
from geoddp.scene import parse_scene
from geoddp.sweep import TIMING_COLUMNS, expand, load_sweep, read_table, run_sweep
from geoddp.sweep import run as run_mod
from geoddp.validate import InputError

SMALL = """
[sweep]
scene = "satellite_paper"
seed = 7
samples = 3

[scene]
horizon.tf = 0.5
horizon.dt = 0.05
target.euler_intrinsic = [["x", 0.0]]

[grid]
"target.euler_intrinsic[0][1]" = [20.0, 90.0]
cost.control = [0.1, 1.0]

[[random]]
key = "model.inertia"
distribution = "normal"
mean = [10.0, 11.1, 13.0]
std = 0.5
"""


def write(tmp_path: Path, text: str, name: str = "sweep.toml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def comparable(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=[c for c in TIMING_COLUMNS if c in df.columns])


# ------------------------------------------------------------------ sweep files


def test_cases_are_the_grid_times_the_draws_with_the_values_set(tmp_path):
    sweep = load_sweep(write(tmp_path, SMALL))
    cases = expand(sweep)
    assert len(cases) == 2 * 2 * 3
    # grid points outer (last key fastest), draws inner; common random numbers across grid points
    assert [c.params["target.euler_intrinsic[0][1]"] for c in cases[:6]] == [20.0] * 6
    assert [c.params["cost.control"] for c in cases[:6]] == [0.1] * 3 + [1.0] * 3
    assert [c.draw for c in cases[:6]] == [0, 1, 2, 0, 1, 2]
    assert cases[0].params["model.inertia"] == cases[3].params["model.inertia"] == cases[9].params["model.inertia"]
    assert cases[0].params["model.inertia"] != cases[1].params["model.inertia"]
    c = cases[4]
    assert c.scene["target"]["euler_intrinsic"] == [["x", 20.0]]
    assert c.scene["cost"]["control"] == 1.0 and c.scene["horizon"]["tf"] == 0.5
    assert c.scene["model"]["inertia"] == c.params["model.inertia"]
    # every case is a full scene: the reader takes it as it is
    spec = parse_scene(c.scene, c.source)
    assert spec.horizon == 10 and np.allclose(np.diag(spec.inertia), c.params["model.inertia"])
    # the draw is reproducible and does not depend on the grid
    again = expand(load_sweep(write(tmp_path, SMALL.replace("[20.0, 90.0]", "[45.0]"), "b.toml")))
    assert [k.params["model.inertia"] for k in again[:3]] == [k.params["model.inertia"] for k in cases[:3]]


def test_hashes_identify_the_full_spec(tmp_path):
    cases = expand(load_sweep(write(tmp_path, SMALL)))
    hashes = [c.hash for c in cases]
    assert len(set(hashes)) == len(hashes)
    assert all(len(h) == 64 for h in hashes)
    # the same sweep read again hashes the same; changing a base value changes every hash
    assert [c.hash for c in expand(load_sweep(write(tmp_path, SMALL, "c.toml")))] == hashes
    other = expand(load_sweep(write(tmp_path, SMALL.replace("horizon.dt = 0.05", "horizon.dt = 0.025"), "d.toml")))
    assert not set(c.hash for c in other) & set(hashes)


def test_haar_rotations_are_uniform_on_so3(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        [sweep]
        scene = "satellite_paper"
        samples = 4000
        [[random]]
        key = "target.quaternion"
        distribution = "haar"
    """))
    qs = np.array([c.params["target.quaternion"] for c in sweep.cases()])
    assert np.allclose(np.linalg.norm(qs, axis=1), 1.0, atol=1e-14) and (qs[:, 3] >= 0).all()
    # Haar measure: E[R] = 0, and the rotation angle t has density (1 - cos t) / pi, so
    # E[cos t] = -1/2 and P(t < pi/2) = 1/2 - 1/pi.
    w = qs[:, 3]
    t = 2.0 * np.arccos(np.clip(w, -1, 1))
    n = len(qs)
    assert abs(np.mean(np.cos(t)) + 0.5) < 4 * np.std(np.cos(t)) / math.sqrt(n)
    p = 0.5 - 1.0 / math.pi
    assert abs(np.mean(t < math.pi / 2) - p) < 4 * math.sqrt(p * (1 - p) / n)
    x = np.mean(np.sign(qs[:, 0]))  # the axis has no preferred direction
    assert abs(x) < 4 / math.sqrt(n)
    # setting target.quaternion replaced the base scene's euler_intrinsic: the reader accepts it
    c = next(iter(sweep.cases()))
    assert "euler_intrinsic" not in c.scene["target"]
    assert np.allclose(parse_scene(c.scene, c.source).Rd @ parse_scene(c.scene, c.source).Rd.T, np.eye(3))


def test_uniform_normal_and_perturb_draws(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        [sweep]
        scene = "space_manipulator"
        samples = 2000
        seed = 3
        [postures]
        bent = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.6, -0.5, 0.8]
        [[random]]
        key = "horizon.dt"
        distribution = "uniform"
        low = 0.01
        high = 0.03
        [[random]]
        key = "initial.q"
        distribution = "perturb"
        around = "bent"
        std = 0.1
        indices = [7, 8, 9]
        [[random]]
        key = "solver.switch_ratio"
        distribution = "normal"
        mean = 0.2
        std = 0.01
    """))
    cases = list(sweep.cases())
    dt = np.array([c.params["horizon.dt"] for c in cases])
    q = np.array([c.params["initial.q"] for c in cases])
    sr = np.array([c.params["solver.switch_ratio"] for c in cases])
    n = len(cases)
    assert dt.min() >= 0.01 and dt.max() <= 0.03
    assert abs(dt.mean() - 0.02) < 4 * (0.02 / math.sqrt(12)) / math.sqrt(n)
    assert (q[:, :7] == [0, 0, 0, 0, 0, 0, 1]).all()  # only the listed entries move
    assert np.all(np.abs(q[:, 7:].mean(axis=0) - [0.6, -0.5, 0.8]) < 4 * 0.1 / math.sqrt(n))
    assert np.all(np.abs(q[:, 7:].std(axis=0) / 0.1 - 1) < 0.1)
    assert abs(sr.mean() - 0.2) < 4 * 0.01 / math.sqrt(n) and abs(sr.std() / 0.01 - 1) < 0.1


BAD = [  # (sweep file body after [sweep] scene = ..., the key path the error must name, a phrase)
    ('[grid]\n"target.bogus" = [1.0]', "[grid].target.bogus", "unknown key"),
    ('[grid]\n"tagret.quaternion" = [[0.0, 0.0, 0.0, 1.0]]', "[grid].tagret.quaternion", "unknown section"),
    ("[grid]\nhorizon.tf = []", "[grid].horizon.tf", "empty grid"),
    ("[grid]\nhorizon.dt = [0.05, -0.01]", "[grid].horizon.dt", "case 1"),
    ("[grid]\ncost.control = 3.0", "[grid].cost.control", "list of values"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "normal"\nmean = 1.0\nstd = -0.5', "random[0].std", ">= 0"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "uniform"\nlow = 2.0\nhigh = 1.0', "random[0].high",
     "high >= low"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "haar"', "random[0].key", ".quaternion or .rotation"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "poisson"', "random[0].distribution", "poisson"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "normal"\nmean = 1.0', "random[0].std", "missing"),
    ('[[random]]\nkey = "cost.control"\ndistribution = "perturb"\nstd = 0.1\naround = "crouch"', "random[0].around",
     "crouch"),
    ('[[random]]\nkey = "model.inertia"\ndistribution = "normal"\nmean = [10.0, 11.0]\nstd = 0.1',
     "random[0]", "case 0"),
    ("[scene]\nhorizon.tff = 1.0", "[horizon].tff", "did you mean"),
    ("[sweep.extra]\nx = 1", "[sweep].extra", "unknown key"),
    ("[grids]\nhorizon.tf = [1.0]", "[grids]", "did you mean [grid]"),
]


@pytest.mark.parametrize("body, where, phrase", BAD)
def test_bad_sweep_files_are_refused_before_any_case_runs(tmp_path, monkeypatch, body, where, phrase):
    calls = []
    monkeypatch.setattr(run_mod, "run_case", lambda p: calls.append(p) or {})
    text = '[sweep]\nscene = "satellite_paper"\n' + body + "\n"
    if body.startswith("[sweep."):
        text = '[sweep]\nscene = "satellite_paper"\nextra = 1\n'
    path = write(tmp_path, text)
    with pytest.raises(InputError) as err:
        run_sweep(path, tmp_path / "out", serial=True)
    assert err.value.parameter.startswith(where), str(err.value)
    assert phrase in str(err.value)
    assert calls == [] and not (tmp_path / "out").exists()
    # the command line: exit 2, one line naming the key, nothing written
    assert main(["sweep", str(path), "--out", str(tmp_path / "out2"), "--serial", "--quiet"]) == 2
    assert not (tmp_path / "out2").exists()


def test_missing_base_scene_and_samples_without_draws(tmp_path):
    with pytest.raises(InputError, match=r"\[sweep\]\.scene"):
        load_sweep(write(tmp_path, '[sweep]\nscene = "no_such_scene"\n'))
    with pytest.raises(InputError, match=r"\[sweep\]\.samples"):
        load_sweep(write(tmp_path, '[sweep]\nscene = "satellite_paper"\nsamples = 3\n'))


# ------------------------------------------------------------------ running


def test_serial_rows_equal_direct_solves(tmp_path):
    out = tmp_path / "out"
    run = run_sweep(write(tmp_path, SMALL), out, serial=True)
    assert run.complete and run.solved == 12 and run.failed == 0
    df = read_table(out)
    assert list(df["case"]) == list(range(12))
    for c in expand(load_sweep(tmp_path / "sweep.toml"))[::5]:
        r = solve_scene(parse_scene(c.scene, c.source), verbose=False)
        row = df[df["hash"] == c.hash].iloc[0]
        assert row["J"] == r.cost and row["iterations"] == r.iterations and row["status"] == r.status
        assert row["gradient_norm"] == r.grad_norm and row["converged"] == r.converged
        assert row["attitude_error_deg"] == r.attitude_error_deg
        assert row["model.inertia[1]"] == c.params["model.inertia"][1]
        assert row["target.euler_intrinsic[0][1]"] == c.params["target.euler_intrinsic[0][1]"]


def test_resume_after_interrupt_solves_each_case_once(tmp_path, monkeypatch):
    path = write(tmp_path, SMALL)
    whole = comparable(read_table(run_sweep(path, tmp_path / "whole", serial=True).table.parent))
    solved: list[str] = []
    real = run_mod.run_case

    def counting(p):
        if len(solved) == 7:
            raise KeyboardInterrupt  # Ctrl-C during the 8th case
        solved.append(p["hash"])
        return real(p)

    monkeypatch.setattr(run_mod, "run_case", counting)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_sweep(path, out, serial=True, flush_rows=3)
    assert len(solved) == 7
    assert len(read_table(out)) == 7  # the finished rows were flushed on the way out
    monkeypatch.setattr(run_mod, "run_case", lambda p: solved.append(p["hash"]) or real(p))
    run = run_sweep(path, out, serial=True, resume=True)
    assert run.skipped == 7 and run.solved == 5 and run.complete
    assert sorted(solved) == sorted(whole["hash"])  # every case solved exactly once over both runs
    pd.testing.assert_frame_equal(comparable(read_table(out)), whole, check_exact=True)
    # resuming a finished sweep solves nothing and keeps the table
    n = len(solved)
    assert run_sweep(path, out, serial=True, resume=True).solved == 0 and len(solved) == n
    # without --resume the folder is refused
    with pytest.raises(InputError, match="--out"):
        run_sweep(path, out, serial=True)


def test_an_interrupt_whose_exception_was_swallowed_still_ends_the_sweep(tmp_path, monkeypatch):
    # The CLI's handler records the signal, then raises; Python drops an exception raised inside
    # a gc callback (Dask's client has one), and a sweep then ran on to its end (seen in CI).
    # The record alone must stop the sweep after the case in hand, which is kept.
    import signal

    from geoddp import interrupts
    from geoddp.interrupts import Interrupted

    path = write(tmp_path, SMALL)
    real = run_mod.run_case
    solved: list[str] = []

    def swallowed(p):
        solved.append(p["hash"])
        if len(solved) == 4:
            interrupts.record(signal.SIGINT)  # the handler ran; its exception never arrived
        return real(p)

    monkeypatch.setattr(run_mod, "run_case", swallowed)
    out = tmp_path / "out"
    try:
        with pytest.raises(Interrupted) as exc:
            run_sweep(path, out, serial=True, flush_rows=3)
    finally:
        interrupts.clear()
    assert exc.value.signum == signal.SIGINT and len(solved) == 4
    assert len(read_table(out)) == 4  # the case in hand is recorded before the run ends


def test_the_cli_forgets_its_signals_when_it_returns(monkeypatch):
    # A signal recorded during one CLI run (its exception swallowed, the run finished) must not
    # stop a later sweep in the same process.
    import signal

    from geoddp import cli, interrupts
    from geoddp.cli import commands

    def run_that_swallows_a_sigint(args):
        interrupts.record(signal.SIGINT)
        return cli.EXIT_CONVERGED

    monkeypatch.setitem(commands.COMMANDS, "run", run_that_swallows_a_sigint)
    assert cli.main(["run", "satellite_paper", "--quiet"]) == cli.EXIT_CONVERGED
    assert interrupts.received() == []
    interrupts.check()  # nothing to raise


def test_limit_then_resume_and_csv(tmp_path):
    path = write(tmp_path, SMALL)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--serial", "--limit", "5", "--quiet"]) == 1
    assert len(read_table(out)) == 5 and not (out / "results.parquet").exists()
    assert main(["sweep", str(path), "--out", str(out), "--serial", "--resume", "--csv", "--full", "--quiet"]) == 0
    df = read_table(out)
    csv = pd.read_csv(out / "results.csv", keep_default_na=False)
    assert list(csv["hash"]) == list(df["hash"]) and np.array_equal(csv["J"].to_numpy(), df["J"].to_numpy())
    # full results on request: the 7 cases solved with --full
    assert len(list((out / "cases").glob("*.json"))) == 7


def test_a_raising_case_is_recorded_not_fatal(tmp_path, monkeypatch):
    import geoddp.scene.solve

    real = geoddp.scene.solve.solve_scene

    def flaky(spec, **kw):
        if float(spec.S_u[0, 0]) == 1.0:  # the cases with cost.control = 1
            raise RuntimeError("solver blew up")
        return real(spec, **kw)

    monkeypatch.setattr(geoddp.scene.solve, "solve_scene", flaky)
    run = run_sweep(write(tmp_path, SMALL), tmp_path / "out", serial=True)
    df = read_table(tmp_path / "out")
    assert run.complete and len(df) == 12 and run.failed == 6
    bad = df[df["cost.control"] == 1.0]
    assert (bad["status"] == "error").all() and (bad["error"] == "RuntimeError: solver blew up").all()
    assert bad["J"].isna().all() and (bad["iterations"] == -1).all()
    good = df[df["cost.control"] == 0.1]
    assert (good["error"] == "").all() and good["converged"].all()


def test_summary_and_plots(tmp_path, capsys):
    out = tmp_path / "out"
    run_sweep(write(tmp_path, SMALL), out, serial=True)
    df = read_table(out)
    capsys.readouterr()
    assert main(["sweep", "--summary", str(out), "--plots", str(tmp_path / "figs")]) == 0
    text = capsys.readouterr().out
    assert f"converged: {int(df['converged'].sum())}/12" in text
    assert f"max {df['iterations'].max()}" in text
    slowest = df.sort_values("solve_time_s", ascending=False).iloc[0]
    assert f"case {int(slowest['case'])} (" in text.split("slowest")[1].splitlines()[1]
    figs = sorted(p.name for p in (tmp_path / "figs").glob("*.png"))
    assert "outcome_vs_target_euler_intrinsic_0__1.png" in figs and "iterations_hist.png" in figs


def test_builtin_sweeps_validate_and_the_slew_sweep_sets_its_angle():
    from geoddp.sweep.spec import sweep_names

    assert "satellite_slew" in sweep_names()
    for name in sweep_names():
        assert len(expand(load_sweep(name))) >= 1
    cases = expand(load_sweep("satellite_slew"))
    assert len(cases) == 18 * 3
    spec = parse_scene(cases[-1].scene, cases[-1].source)  # 180 degrees about x
    assert np.allclose(spec.Rd, np.diag([1.0, -1.0, -1.0]), atol=1e-15) and spec.expansion == "switch"


def test_integer_draws(tmp_path):
    sweep = load_sweep(write(tmp_path, """
        [sweep]
        scene = "satellite_paper"
        samples = 500
        [[random]]
        key = "solver.max_iter"
        distribution = "integers"
        low = 5
        high = 9
    """))
    vals = [c.params["solver.max_iter"] for c in sweep.cases()]
    assert all(isinstance(x, int) for x in vals) and set(vals) == {5, 6, 7, 8}
    with pytest.raises(InputError, match=r"random\[0\]\.high"):
        load_sweep(write(tmp_path, '[sweep]\nscene = "satellite_paper"\n[[random]]\nkey = "solver.max_iter"\n'
                         'distribution = "integers"\nlow = 5\nhigh = 5\n', "bad.toml"))


def test_builtin_noise_monte_carlo_sweep(tmp_path):
    # The authors' noise test as a sweep (examples/sweeps/satellite_noise_mc.toml): each case solves the
    # plan (J* = 6.0451953285) and flies it with its own simulation seed; 30 cases serially.
    out = tmp_path / "mc"
    run_sweep("satellite_noise_mc", out, serial=True, limit=30)
    df = pd.concat([pd.read_parquet(p) for p in sorted((out / "parts").glob("*.parquet"))])
    assert len(df) == 30 and df["converged"].all() and df["simulation.seed"].nunique() == 30
    assert np.allclose(df["J"], 6.0451953285, rtol=0, atol=1e-9)
    open_mean = df["sim.open.attitude_rad.max"].mean()
    closed_mean = df["sim.feedback.attitude_rad.max"].mean()
    # one sample per case, so each case's max is its terminal error; the gains cut it >= 20x
    assert closed_mean < open_mean / 20 and 3e-4 < closed_mean < 1.2e-3, (open_mean, closed_mean)


def test_builtin_ur5_reach_grid_sweep_builds_the_robot_once(tmp_path, monkeypatch):
    """The UR5 reach-target grid (examples/sweeps/ur5_reach_grid.toml, example-robot-data): 25
    cases, all converged, each row the J* of its own case solved directly, the tool within 3 cm of
    its target (0.7-26 mm over the grid: nearest the base is hardest); and the sweep builds the
    UR5's model at most once in this process (a case is read, then built: two builds a case
    before the memo of geoddp.models.urdf)."""
    import pinocchio as pin

    import geoddp.models.urdf as uc

    import example_robot_data  # noqa: F401  (the test extra: a missing install fails here, not skips)
    builds = []
    real = pin.buildModelFromXML
    monkeypatch.setattr(uc.pin, "buildModelFromXML", lambda *a: builds.append(1) or real(*a))
    cases = expand(load_sweep("ur5_reach_grid"))
    out = tmp_path / "reach"
    run_sweep("ur5_reach_grid", out, serial=True)
    df = read_table(out)
    assert len(df) == len(cases) == 25 and df["converged"].all() and len(builds) <= 1
    err = df["terminal.frame_placement.position_error_m"]
    assert err.max() < 0.03 and err.min() < 0.002
    for i in (0, 12, 24):  # a corner, the centre, the far corner: the row is the case's own solve
        direct = solve_scene(parse_scene(cases[i].scene, cases[i].source), verbose=False)
        assert df["J"].iloc[i] == direct.cost and df["iterations"].iloc[i] == direct.iterations
    assert df["J"].nunique() == 25  # every target is its own problem


# ------------------------------------------------------------------ tasks, progress, the extra


def test_chunk_sizes_follow_the_case_time_and_keep_the_tail_balanced():
    sizer = run_mod.ChunkSizer(threads=2)
    assert sizer.size(1000) == 1  # no case time known yet: one case a task
    for _ in range(4):
        sizer.observe(0.02)  # 20 ms cases
    sizer.observe(math.nan)  # a case whose task died carries no time: ignored
    assert sizer.size(1000) == int(run_mod.TASK_SECONDS / 0.02)  # ~0.25 s a task
    assert sizer.size(20) == 20 // 4  # the tail: an even share of what is left over 2 x threads
    assert sizer.size(3) == 1 and sizer.size(0) == 1
    fast = run_mod.ChunkSizer(threads=1)
    fast.observe(1e-5)
    assert fast.size(10**6) == run_mod.MAX_CHUNK  # capped: a lost worker costs little to redo
    slow = run_mod.ChunkSizer(threads=1)
    slow.observe(2.0)
    assert slow.size(10**6) == 1  # a case longer than a task's target time goes alone


def test_run_cases_keeps_order_and_records_a_bad_case(tmp_path):
    cases = expand(load_sweep(write(tmp_path, SMALL)))[:3]
    payloads = [run_mod.case_mod.payload(c) for c in cases]
    import copy

    bad = copy.deepcopy(payloads[1]["scene"])
    bad["model"]["inertia"] = "heavy"
    payloads[1] = dict(payloads[1], scene=bad)  # fails inside the task
    rows = run_mod.run_cases(payloads)
    direct = [run_mod.run_case(p) for p in payloads]
    assert [r["J"] for r in rows][::2] == [r["J"] for r in direct][::2]
    assert rows[1]["status"] == "error" and "inertia" in rows[1]["error"] and rows[0]["error"] == ""


def test_progress_bar_counts_done_failed_and_running(tmp_path, monkeypatch):
    import io

    import geoddp.scene.solve

    real = geoddp.scene.solve.solve_scene
    monkeypatch.setattr(geoddp.scene.solve, "solve_scene", lambda spec, **kw: (
        (_ for _ in ()).throw(RuntimeError("boom")) if float(spec.S_u[0, 0]) == 1.0 else real(spec, **kw)))
    stream = io.StringIO()
    run_sweep(write(tmp_path, SMALL), tmp_path / "out", serial=True, progress=stream)
    last = stream.getvalue().replace("\r", "\n").strip().splitlines()[-1]
    assert last.startswith("sweep: 100%") and "12/12" in last and "6 failed, 0 running" in last, last


def test_a_missing_sweep_extra_is_named(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "tqdm", None)  # as if tqdm were not installed
    with pytest.raises(InputError, match=r"geoddp\[sweep\].*") as exc:
        run_sweep(write(tmp_path, SMALL), tmp_path / "out", serial=True, progress=sys.stderr)
    assert "missing: tqdm" in str(exc.value)
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_validation_keeps_hashes_not_cases(tmp_path):
    # The runner validates every case first but keeps only their hashes (a case's scene table is
    # ~4 kB: 10^5 of them would be 400 MB); the cases are generated again as they are submitted.
    import tracemalloc

    from geoddp.sweep.spec import validate_all

    sweep = load_sweep(write(tmp_path, SMALL.replace("samples = 3", "samples = 30")))
    tracemalloc.start()
    try:
        hashes = validate_all(sweep)
        _, peak_hashes = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        cases = expand(sweep)
        _, peak_cases = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert hashes == [c.hash for c in cases] and len(hashes) == 120
    assert peak_hashes < peak_cases / 4, (peak_hashes, peak_cases)


def test_read_table_refuses_a_folder_no_sweep_wrote(tmp_path):
    """An empty table would look like a sweep with no results: a missing folder and one without
    results.parquet, manifest.json or parts/ are refused, naming out."""
    (tmp_path / "empty").mkdir()
    for where, words in ((tmp_path / "nope", "no such folder"), (tmp_path / "empty", "no results.parquet")):
        with pytest.raises(InputError, match=words) as e:
            read_table(where)
        assert e.value.parameter == "out"

