"""geoddp.solve_scene (geoddp.scene.solve): the problem built from a spec is reused while the spec
lives, and every key of the [solver] table is a keyword that reaches the solve."""
from __future__ import annotations

import gc

import numpy as np
import pytest

from geoddp import SolverOptions, load_scene, solve, solve_scene
from geoddp.models.actuation import hover_inputs
from geoddp.scene import build_problem, parse_scene
from geoddp.scene import solve as api
from geoddp.scene.common import TABLES
from geoddp.validate import InputError


def _count_builds(monkeypatch) -> list:
    calls = []
    real = api.build_problem

    def counting(spec):
        calls.append(spec.name)
        return real(spec)

    monkeypatch.setattr(api, "build_problem", counting)
    return calls


def test_a_spec_is_built_once_and_solves_the_same(monkeypatch):
    calls = _count_builds(monkeypatch)
    spec = load_scene("coarse_dt_0p1")
    a = solve_scene(spec, verbose=False)
    b = solve_scene(spec, verbose=False)
    assert calls == ["coarse_dt_0p1"]
    np.testing.assert_array_equal(a.cost_history, b.cost_history)
    np.testing.assert_array_equal(a.controls, b.controls)
    assert a.iterations == b.iterations and a.converged and b.converged


def test_solver_overrides_reuse_the_problem_and_problem_keys_build_their_own(monkeypatch):
    calls = _count_builds(monkeypatch)
    spec = load_scene("coarse_dt_0p1")
    first = solve_scene(spec, verbose=False, expansion="first")
    switch = solve_scene(spec, verbose=False, initial_controls=np.zeros((spec.horizon, 3)), max_iter=50)
    assert calls == ["coarse_dt_0p1"]  # the solver's keys leave the spec's problem as built
    assert first.expansion == "first" and switch.expansion == "switch"
    assert abs(first.cost - switch.cost) <= 1e-9 * abs(switch.cost)
    paper = solve_scene(spec, second_order="paper")  # the model's expansion: a problem of its own
    assert calls == ["coarse_dt_0p1", "coarse_dt_0p1"]
    assert paper.converged and abs(paper.cost - switch.cost) <= 1e-9 * abs(switch.cost)


def test_the_cache_lets_a_spec_go(monkeypatch):
    _count_builds(monkeypatch)
    spec = load_scene("coarse_dt_0p1")
    solve_scene(spec, verbose=False)
    key = id(spec)
    assert key in api._BUILT
    del spec
    gc.collect()
    assert key not in api._BUILT


# ------------------------------------------------------------------ every [solver] key as a keyword

def _same_run(a, b) -> None:
    """Two solves made the same iterations, bit for bit."""
    assert a.iterations == b.iterations and a.status == b.status
    np.testing.assert_array_equal(a.cost_history, b.cost_history)
    np.testing.assert_array_equal(a.controls, b.controls)


def test_every_solver_table_key_is_a_keyword_of_solve_scene():
    """The keywords are the table's keys: a key added to [solver] is a keyword without more code."""
    assert set(api.SCENE_KEYS) == set(TABLES["solver"]) == {
        "expansion", "switch_ratio", "tol", "rtol", "grad_tol", "grad_rtol", "max_iter", "second_order",
        "initial_controls", "constraint_tol"}


@pytest.mark.parametrize("key, value", [
    ("expansion", "first"), ("switch_ratio", 0.01), ("tol", 1.0), ("rtol", 1e-4), ("grad_tol", 1.0),
    ("grad_rtol", 1e-2), ("max_iter", 2)])
def test_a_solver_option_keyword_solves_as_the_option_does(key, value):
    """solve_scene(spec, key=value) is solve(problem, SolverOptions(key=value)) bit for bit, and
    not the default's run (so an ignored keyword would fail)."""
    spec = load_scene("satellite_paper")
    got = solve_scene(spec, **{key: value})
    want = solve(build_problem(spec), SolverOptions(**{"tol": spec.tol, key: value}))
    _same_run(got, want)
    default = solve_scene(spec)
    assert (got.iterations, got.expansion_history, list(got.cost_history), got.message) != \
        (default.iterations, default.expansion_history, list(default.cost_history), default.message)


def test_second_order_keyword_reaches_the_model():
    spec = load_scene("satellite_paper")
    paper = solve_scene(spec, second_order="paper")
    _same_run(paper, solve(build_problem(spec.with_overrides(second_order="paper")), SolverOptions(tol=spec.tol)))
    exact = solve_scene(spec)
    assert not np.array_equal(paper.cost_history, exact.cost_history)  # the eta-eta term changes the steps
    assert abs(paper.cost - exact.cost) <= 1e-9 * exact.cost  # the same optimum
    with pytest.raises(InputError, match=r"^second_order: expected one of exact, got 'paper'$"):
        solve_scene("quadrotor", second_order="paper")  # "paper" exists on TSO(3) only, as in a file


def test_constraint_tol_keyword_reaches_the_outer_loop():
    spec = load_scene("satellite_keep_out")
    loose = solve_scene(spec, constraint_tol=1e-3)
    assert loose.extra["constraints"]["constraint_tol"] == 1e-3
    assert spec.constraint_tol == 1e-8 and solve_scene(spec).extra["constraints"]["constraint_tol"] == 1e-8
    assert loose.extra["constraints"]["max_violation"] <= 1e-3
    with pytest.raises(InputError, match=r"^constraint_tol: expected a number >= 0, got -1.0$"):
        solve_scene(spec, constraint_tol=-1)


@pytest.fixture(scope="module")
def quadrotor():
    spec = load_scene("quadrotor")
    return spec, build_problem(spec)


def test_initial_controls_array_is_the_start(quadrotor):
    """J at the start (cost_history[0]) is J at the given controls: an (H, m) sequence, or an (m,)
    input held over the horizon; the whole run equals solve(problem, initial_controls=U)."""
    spec, p = quadrotor
    U = 3.0 + np.random.default_rng(0).normal(size=(p.horizon, p.nu))
    r = solve_scene(spec, initial_controls=U, max_iter=3)
    assert r.cost_history[0] == p.total_cost(U)
    _same_run(r, solve(p, SolverOptions(max_iter=3), initial_controls=U))
    u = np.array([3.0, 3.5, 4.0, 3.2])
    r = solve_scene(spec, initial_controls=u, max_iter=1)
    assert r.cost_history[0] == p.total_cost(np.tile(u, (p.horizon, 1)))


def test_initial_controls_names_are_the_scene_files_names(quadrotor):
    spec, p = quadrotor
    hover = hover_inputs(p.model.pin_model, p.model.actuation, p.q0)
    assert np.all(hover > 0)  # the four rotors' share of m g: a start other than zero
    starts = {"zero": np.zeros((p.horizon, p.nu)), "hover": np.tile(hover, (p.horizon, 1)),
              "quasi_static": p.quasi_static_controls(), "gravity_compensation": p.quasi_static_controls()}
    for name, U in starts.items():
        r = solve_scene(spec, initial_controls=name, max_iter=1)
        assert r.cost_history[0] == p.total_cost(U), name
    assert p.total_cost(starts["zero"]) > 100 * p.total_cost(starts["hover"])  # the starts differ
    # the same names in the file: the same starts
    for name in starts:
        data = _quadrotor_dict(initial_controls=name)
        r = solve_scene(parse_scene(data), max_iter=1)
        assert r.cost_history[0] == p.total_cost(starts[name]), name


def _quadrotor_dict(**solver):
    import tomllib

    from geoddp.scene import scene_file

    path = scene_file("quadrotor")
    data = tomllib.loads(path.read_text())
    data.setdefault("solver", {}).update(solver)
    return data


def test_initial_controls_keyword_replaces_the_files_start(quadrotor):
    spec, p = quadrotor
    zero = parse_scene(_quadrotor_dict(initial_controls="zero"))
    assert solve_scene(zero, max_iter=1).cost_history[0] == p.total_cost(np.zeros((p.horizon, p.nu)))
    back = solve_scene(zero, initial_controls="quasi_static", max_iter=1)  # the default start again
    assert back.cost_history[0] == p.total_cost(p.quasi_static_controls())


@pytest.mark.parametrize("value, message", [
    ("hovr", r"^initial_controls: expected one of gravity_compensation \| hover \| quasi_static \| zero, got 'hovr'; "
             r"did you mean 'hover'\?$"),
    (np.zeros(3), r"^initial_controls: expected one of 'quasi_static', 'gravity_compensation', 'hover', 'zero', a "
                  r"constant input of shape \(4,\) or a sequence of shape \(150, 4\), got shape \(3,\)$"),
    (np.full(4, np.nan), r"^initial_controls: expected finite numbers, got nan"),
    ([1.0, "a", 2.0, 3.0], r"^initial_controls: "),
])
def test_bad_initial_controls_keyword_names_it_as_the_file_names_its_key(value, message):
    with pytest.raises(InputError, match=message) as kw:
        solve_scene("quadrotor", initial_controls=value)
    with pytest.raises(InputError) as file:
        parse_scene(_quadrotor_dict(initial_controls=value.tolist() if isinstance(value, np.ndarray) else value))
    assert file.value.parameter == "[solver].initial_controls" and file.value.detail == kw.value.detail


def test_initial_controls_keyword_is_checked_against_the_limits():
    spec = load_scene("satellite_wheel_limits")  # |u_i| <= 5 N m
    U = np.zeros((spec.horizon, 3))
    U[7, 2] = 6.0
    with pytest.raises(InputError, match=r"^initial_controls: the control at node 7, input 2 is 6.0, outside the limits "
                                         r"\[-5.0, 5.0\]"):
        solve_scene(spec, initial_controls=U)
    with pytest.raises(InputError, match=r"^initial_controls: expected shape \(300, 3\)"):
        solve_scene(spec, initial_controls=np.zeros(3))  # a satellite scene takes (H, m), as its file does
    r = solve_scene(spec, initial_controls=np.full((spec.horizon, 3), 1.0), max_iter=1)
    assert r.cost_history[0] == build_problem(spec).total_cost(np.full((spec.horizon, 3), 1.0))


def test_unknown_keyword_suggests_the_closest():
    with pytest.raises(InputError, match=r"^initial_control: unknown option of solve_scene \(did you mean "
                                         r"'initial_controls'\?\); known: callbacks, constraint_tol, "):
        solve_scene("coarse_dt_0p1", initial_control=np.zeros((30, 3)))
    with pytest.raises(InputError, match=r"^second_ordr: .*did you mean 'second_order'"):
        solve_scene("coarse_dt_0p1", second_ordr="paper")


# ------------------------------------------------------------------ silent unless verbose=True

# satellite_paper's table as verbose=True prints it (the time in the last line masked): the text
# the command line has always printed, unchanged by the silent default
PAPER_TABLE = """\
iter                 cost     |grad|          dJ    lambda   gamma    exp    rungs
   0 1.49575632016387e+04  4.683e+02  -1.426e+04  0.00e+00  0.3333  first        0
   1 7.02141918170731e+02  6.672e+01  -1.918e+02  0.00e+00  1.0000 second        0
   2 5.10390239994382e+02  6.009e-01  -1.760e-02  0.00e+00  1.0000 second        0
   3 5.10372636558986e+02  2.593e-05  -1.589e-10  0.00e+00  1.0000 second        0
converged: |J_i - J_(i-1)| <= tol (|dJ| = 1.589e-10 <= tol; verified at the returned iterate: Newton decrement \
1.2e-25 <= 1.0e-08, reduced Hessian positive definite (min eig Q_uu = 1.012e-01)); J = 5.103726365588e+02, \
||grad|| = 7.293e-13, 4 iterations, MS
"""


def _masked(text: str) -> str:
    import re

    return re.sub(r"[0-9.]+ ms\n", "MS\n", text)


def test_python_solves_are_silent_by_default(capfd):
    from geoddp.constraints import solve_constrained
    from geoddp.problem import paper_problem

    assert SolverOptions().verbose is False
    p = paper_problem()
    solve(p)
    solve(p, SolverOptions(expansion="second"))
    r = solve_scene("satellite_paper")
    solve_constrained(build_problem(load_scene("satellite_keep_out")), SolverOptions(max_iter=2))
    solve_scene("satellite_keep_out", max_iter=2)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert r.converged and r.iterations == 4  # they did solve


def test_verbose_true_prints_the_table_the_command_line_prints(capfd):
    from geoddp.cli import main

    solve_scene("satellite_paper", verbose=True)
    assert _masked(capfd.readouterr().out) == PAPER_TABLE
    spec = load_scene("satellite_paper")
    solve(build_problem(spec), SolverOptions(tol=spec.tol, verbose=True))
    assert _masked(capfd.readouterr().out) == PAPER_TABLE
    assert main(["run", "satellite_paper"]) == 0  # the command line passes verbose itself
    out = capfd.readouterr().out
    assert _masked(out).startswith(PAPER_TABLE) and out.count("\n") == PAPER_TABLE.count("\n") + 2
    assert main(["run", "satellite_paper", "--quiet"]) == 0
    out = capfd.readouterr().out
    assert "iter " not in out and out.startswith("J* = 510.3726365588")


def test_verbose_true_prints_the_outer_loop_of_a_constrained_scene(capfd):
    solve_scene("satellite_keep_out", verbose=True, max_iter=2)
    lines = capfd.readouterr().out.splitlines()
    assert lines[0].split() == ["outer", "inner", "tol", "max", "mu", "J", "violation", "feasibility", "inner",
                                "inner", "status"]
    assert [int(line.split()[0]) for line in lines[1:-1]] == list(range(len(lines) - 2))


def test_a_scene_file_cannot_set_verbose():
    import tomllib

    from geoddp.scene import scene_file

    data = tomllib.loads(scene_file("satellite_paper").read_text())
    data["solver"]["verbose"] = True
    with pytest.raises(InputError, match=r"^\[solver\]\.verbose: unknown key in \[solver\]; allowed keys: expansion, "):
        parse_scene(data)
