"""Issue 13, items 2-4: validation at the boundary, no NaN or traceback out, nothing lost."""
from __future__ import annotations

import dataclasses
import io
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from geoddp import solve_scene
from geoddp.cli import main
from geoddp.output_files import check_outputs, strict_json, write_atomic
from geoddp.data import urdf_path
from geoddp.problem.limits import ControlLimits
from geoddp.models.multibody import Multibody
from geoddp.problem import Problem, paper_problem
from geoddp import Result
from geoddp.solver import SolverOptions, solve
from geoddp.validate import InputError


def _strict(text: str):
    def refuse(c):
        raise AssertionError(f"non-finite constant {c}")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize("kw, name", [
    (dict(reg_increase=0.5), "reg_increase"), (dict(reg_increase=1.0), "reg_increase"),
    (dict(reg_min=1.0, reg_max=0.1), "reg_min"), (dict(step_factor=2.0), "step_factor"),
    (dict(step_factor=1.0), "step_factor"), (dict(stream=5), "stream"), (dict(verbose="yes"), "verbose"),
    (dict(min_step=2.0), "min_step"), (dict(reg_init=1e11), "reg_init"),
])
def test_solver_options_refuse_bad_values_by_name(kw, name):
    with pytest.raises(InputError) as e:
        SolverOptions(**kw)
    assert e.value.parameter == name


def test_solver_options_refuse_an_unknown_keyword_with_the_closest_option():
    """A misspelt option is an InputError naming it, not the dataclass's TypeError; every real
    option is still a keyword, and replace/copies of options keep working."""
    for typo, meant in (("maxiter", "max_iter"), ("regmin", "reg_min"), ("expansions", "expansion")):
        with pytest.raises(InputError, match=f"unknown keyword of SolverOptions; did you mean '{meant}'") as e:
            SolverOptions(**{typo: 5})
        assert e.value.parameter == typo
    o = SolverOptions(max_iter=7, verbose=False)
    assert dataclasses.replace(o, tol=1e-3).max_iter == 7 and SolverOptions(**dataclasses.asdict(o)).max_iter == 7
    # the same for the model, the problem and the limits a user builds by keywords
    p = paper_problem(horizon=5)
    with pytest.raises(InputError, match="unknown keyword of Problem; did you mean 'horizon'") as e:
        Problem(p.model, p.q0, p.v0, running=p.running, terminal=p.terminal, horizn=5)
    assert e.value.parameter == "horizn"
    with pytest.raises(InputError, match="unknown keyword of ControlLimits; did you mean 'upper'") as e:
        ControlLimits(lower=-1.0, uper=1.0)
    assert e.value.parameter == "uper"
    with pytest.raises(InputError, match="unknown keyword of Multibody; did you mean 'integrator'") as e:
        Multibody(urdf_path("satellite.urdf"), root="spherical", dt=0.01, integator="euler")
    assert e.value.parameter == "integator"
    assert dataclasses.replace(p, horizon=3).horizon == 3 and p.with_limits((-1.0, 1.0)).limits is not None


def test_total_cost_takes_the_horizon_s_controls_only():
    """J(U) of 19 controls on a 20-step problem had failed in numpy's broadcasting."""
    p = paper_problem(horizon=20)
    with pytest.raises(InputError, match=r"expected shape \(20, 3\), got shape \(19, 3\)") as e:
        p.total_cost(np.zeros((19, 3)))
    assert e.value.parameter == "controls"
    assert p.total_cost([[0.0, 0.0, 0.0]] * 20) == p.total_cost(np.zeros((20, 3)))


def test_solve_refuses_wrong_types_by_name():
    p = paper_problem()
    for bad in ("fast", {"tol": 1e-3}):
        with pytest.raises(InputError) as e:
            solve(p, bad)
        assert e.value.parameter == "options"
    with pytest.raises(InputError) as e:
        solve(None)
    assert e.value.parameter == "problem" and "missing nx" in str(e.value)
    with pytest.raises(InputError) as e:
        solve_scene({"model": {}})
    assert e.value.parameter == "scene"
    with pytest.raises(InputError) as e:
        solve_scene("satellite_paper", verbose=False, tool=1e-3)
    assert e.value.parameter == "tool" and "'tol'" in str(e.value)
    with pytest.raises(InputError) as e:
        solve_scene("satellite_paper", verbose=False, max_iter="big")
    assert e.value.parameter == "max_iter"


def test_huge_horizon_is_refused_with_the_estimate(monkeypatch):
    from geoddp.solver import loop

    p = paper_problem()
    monkeypatch.setattr(loop, "_available_memory", lambda: 1000)
    monkeypatch.setattr(loop, "_MEMORY_CHECK_FROM", 0)  # the paper's problem needs far less than 64 MiB
    with pytest.raises(InputError) as e:
        solve(p, SolverOptions(verbose=False))
    assert e.value.parameter == "horizon" and "GiB" in str(e.value)
    # below the threshold the available memory is not read at all
    monkeypatch.setattr(loop, "_MEMORY_CHECK_FROM", loop.memory_estimate(p.horizon, p.nx, p.nu) + 1)
    monkeypatch.setattr(loop, "_available_memory", lambda: pytest.fail("read /proc/meminfo for a small problem"))
    assert solve(p, SolverOptions(verbose=False)).converged
    # the estimate: Theta, Gamma, Xi dominate (H nx^3 + H nx^2 m + H nx m^2) * 8 bytes
    assert loop.memory_estimate(1000, 6, 3) >= 8 * 1000 * (216 + 108 + 54)


def test_non_finite_initial_guess_is_bad_input_naming_initial_controls():
    p = paper_problem()
    with pytest.raises(InputError) as e:
        solve(p, SolverOptions(verbose=False), initial_controls=np.full((p.horizon, p.nu), 1e200))
    assert e.value.parameter == "initial_controls" and "non-finite cost" in str(e.value)


def test_json_is_strict_and_null_reads_back_as_nan(tmp_path):
    r = solve_scene("satellite_paper", verbose=False)
    r.grad_norm_history[0] = np.nan
    r.feedback[0, 0, 0] = np.inf
    path = r.write_json(tmp_path / "r.json")
    d = _strict(path.read_text())
    assert d["grad_norm_history"][0] is None and d["feedback"][0][0][0] is None
    back = Result.read_json(path)
    assert np.isnan(back.grad_norm_history[0]) and np.isnan(back.feedback[0, 0, 0])
    np.testing.assert_array_equal(back.controls, r.controls)
    assert _strict(strict_json({"a": [float("nan"), 1.0, float("-inf")]})) == {"a": [None, 1.0, None]}


def test_sigkill_during_a_write_leaves_the_previous_file_intact(tmp_path):
    target = tmp_path / "result.json"
    target.write_text("previous good result")
    code = textwrap.dedent(f"""
        import sys
        from geoddp.output_files import write_atomic
        print("start", flush=True)
        while True:
            write_atomic({str(target)!r}, b"x" * (300 * 2**20))
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=os.environ.copy())
    assert proc.stdout.readline().strip() == b"start"
    deadline = time.time() + 30
    while not list(tmp_path.glob(".result.json.*.tmp")) and time.time() < deadline:
        time.sleep(0.005)
    assert list(tmp_path.glob(".result.json.*.tmp")), "the writer never started a temp file"
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    # either the previous file or a complete new one, never a partial file
    size = target.stat().st_size
    assert target.read_bytes() == b"previous good result" or size == 300 * 2**20


def test_write_atomic_keeps_the_old_file_when_the_write_fails(tmp_path, monkeypatch):
    target = tmp_path / "r.json"
    target.write_text("old")

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", boom)
    with pytest.raises(InputError):
        write_atomic(target, "new")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.json"]


def test_write_atomic_refuses_a_folder_before_any_temporary_file(tmp_path):
    (tmp_path / "out").mkdir()
    with pytest.raises(InputError, match="it is a folder; expected a file path") as e:
        write_atomic(tmp_path / "out", "x")
    assert e.value.parameter == str(tmp_path / "out")
    assert [p.name for p in tmp_path.iterdir()] == ["out"] and not any((tmp_path / "out").iterdir())


def test_reading_a_result_names_the_file_and_the_field(tmp_path):
    """A result file that is missing, not JSON or not a result, and a dict that is not one: each an
    InputError naming the file (or ``result``) and what is wrong, where json, KeyError or
    AttributeError had surfaced."""
    r = solve(paper_problem(horizon=10), SolverOptions(verbose=False, max_iter=2))
    good = r.write_json(tmp_path / "r.json")
    assert Result.read_json(good).cost == r.cost
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "list.json").write_text("[1, 2]")
    (tmp_path / "partial.json").write_text('{"controls": [[1, 2]]}')
    for name, words in (("missing.json", "expected a readable result JSON file"), ("bad.json", "invalid JSON (Expecting"),
                        ("list.json", "got list"), ("partial.json", "the field 'times' is missing")):
        with pytest.raises(InputError, match=re.escape(words)) as e:
            Result.read_json(tmp_path / name)
        assert e.value.parameter == str(tmp_path / name)
    d = r.to_dict()
    d["cost"] = "low"
    with pytest.raises(InputError, match="a field does not convert") as e:
        Result.from_dict(d)
    assert e.value.parameter == "result"


def test_viewers_and_figures_name_a_wrong_result_and_a_file_for_a_folder(tmp_path):
    """Before: AttributeError from the first attribute read, FileExistsError from mkdir."""
    from geoddp.viz import export_html, replay
    from geoddp.viz.figures import plot_convergence, plot_trajectory

    r = solve(paper_problem(horizon=10), SolverOptions(verbose=False, max_iter=2))
    afile = tmp_path / "f.png"
    afile.write_bytes(b"")
    for call, name in ((lambda: export_html(None, tmp_path / "x.html"), "result"),
                       (lambda: export_html(r.to_dict(), tmp_path / "x.html"), "result"),
                       (lambda: replay("r.json"), "result"),
                       (lambda: plot_trajectory(None, tmp_path), "result"),
                       (lambda: plot_trajectory(r, afile), "out_dir"),
                       (lambda: plot_convergence({}, tmp_path), "results"),
                       (lambda: plot_convergence({"first": r, "second": None}, tmp_path), "results['second']")):
        with pytest.raises(InputError) as e:
            call()
        assert e.value.parameter == name
    assert not (tmp_path / "x.html").exists() and afile.read_bytes() == b""


def test_check_outputs_refuses_before_solving(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text("x")
    afile = tmp_path / "f"
    afile.write_text("")
    cases = [({"--json": scene}, "--json", "input of this run"), ({"--json": afile / "r.json"}, "--json", "not a folder"),
             ({"--json": tmp_path}, "--json", "is a folder"), ({"--json": "a\0b"}, "--json", "NUL"),
             ({"--json": tmp_path / "a", "--html": tmp_path / "a"}, "--html", "also the path")]
    for outs, name, words in cases:
        with pytest.raises(InputError) as e:
            check_outputs(outs, inputs=[scene])
        assert e.value.parameter == name and words in str(e.value), str(e.value)
    check_outputs({"--json": tmp_path / "new" / "deeper" / "r.json"}, inputs=[scene])  # created later


def test_cli_refuses_json_onto_its_scene_with_exit_2_and_one_line(tmp_path, capsys):
    from geoddp.data import scene_path as scene_file

    scene = tmp_path / "s.toml"
    scene.write_text(Path(scene_file("satellite_paper")).read_text())
    before = scene.read_text()
    assert main(["run", str(scene), "--quiet", "--json", str(scene)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--json" in err and "input of this run" in err
    assert scene.read_text() == before


def test_cli_exit_codes_converged_and_stalled(tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["run", "satellite_paper", "--quiet", "--json", str(out)]) == 0
    assert _strict(out.read_text())["converged"] is True
    hard = tmp_path / "t.toml"
    from geoddp.data import scene_path as scene_file

    text = Path(scene_file("tumbling_2rads")).read_text()
    hard.write_text(text)
    assert main(["run", str(hard), "--quiet", "--expansion", "first", "--json", str(out)]) == 1
    d = _strict(out.read_text())
    assert d["status"].startswith("stalled") and d["converged"] is False


def test_cli_sigterm_mid_solve_exits_143_and_says_what_was_written(tmp_path):
    # A solve long enough to be interrupted: first order, H = 3000, tol = 0 (runs to max_iter).
    from geoddp.data import scene_path as scene_file

    scene = tmp_path / "long.toml"
    text = Path(scene_file("long_horizon_H3000")).read_text()
    scene.write_text(text)
    proc = subprocess.Popen([sys.executable, "-m", "geoddp.cli", "run", str(scene), "--expansion", "first",
                             "--json", str(tmp_path / "r.json")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=os.environ.copy())
    line = proc.stdout.readline()  # the table's header: the solve has started
    assert b"iter" in line
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode in (143, 0, 1)  # 0/1 only if the solve had already finished
    if proc.returncode == 143:
        assert err.decode().strip().splitlines() == ["geoddp: interrupted by SIGTERM; no output written"]
        assert not (tmp_path / "r.json").exists()


def test_cli_says_which_outputs_exist_when_a_later_one_fails(tmp_path, capsys, monkeypatch):
    from geoddp import viz

    def fail(result, path, **kw):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(viz, "export_html", fail)
    out, page = tmp_path / "r.json", tmp_path / "r.html"
    assert main(["run", "satellite_paper", "--quiet", "--json", str(out), "--html", str(page)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left" in err[0] and f"(wrote {out})" in err[0]
    assert _strict(out.read_text())["converged"] is True and not page.exists()
