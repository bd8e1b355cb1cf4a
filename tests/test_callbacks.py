"""The solver's callbacks (geoddp.solver.callbacks), its expansion policy (geoddp.solver.policy)
and the Result's kinds (geoddp.solver.result): what each reports, decides and holds."""
from __future__ import annotations

import io
import json
import re

import numpy as np
import pytest

from geoddp import Result, solve, solve_scene
from geoddp.data import scene_dir
from geoddp.problem import paper_problem
from geoddp.scene.builtin import quadrotor
from geoddp.solver import SolverOptions
from geoddp.solver.callbacks import Callback, Finish, History, Start, Step, VerboseTable
from geoddp.solver.policy import ExpansionPolicy
from geoddp.solver.result import MultibodyResult, SatelliteResult, result_class
from geoddp.validate import InputError


class Recorder(Callback):
    def __init__(self) -> None:
        self.starts: list[Start] = []
        self.grads: list[float] = []
        self.steps: list[Step] = []
        self.ends: list[Finish] = []

    def on_start(self, start: Start) -> None:
        self.starts.append(start)

    def on_gradient(self, grad_norm: float) -> None:
        self.grads.append(grad_norm)

    def on_iteration(self, step: Step) -> None:
        self.steps.append(step)

    def on_finish(self, end: Finish) -> None:
        self.ends.append(end)


# ----------------------------------------------------------------------------- callbacks


@pytest.mark.parametrize("expansion", ["first", "second", "switch"])
def test_a_callback_hears_what_the_result_records(expansion):
    rec = Recorder()
    r = solve(paper_problem(), SolverOptions(expansion=expansion, verbose=False, record_controls=True,
                                             callbacks=[rec]))
    (start,), (end,) = rec.starts, rec.ends
    assert start.cost == r.cost_history[0] and np.array_equal(start.controls, r.control_history[0])
    assert rec.grads == list(r.grad_norm_history)  # once per iterate, the first value computed there
    assert [s.iteration for s in rec.steps] == list(range(r.iterations))
    assert [s.new_cost for s in rec.steps] == list(r.cost_history[1:])
    assert [s.cost for s in rec.steps] == list(r.cost_history[:-1])
    assert [s.grad_norm for s in rec.steps] == list(r.grad_norm_history[:r.iterations])
    assert [s.reg for s in rec.steps] == list(r.reg_history) and [s.step for s in rec.steps] == list(r.step_history)
    assert [s.expansion for s in rec.steps] == r.expansion_history and not any(s.escape for s in rec.steps)
    for s, U in zip(rec.steps, r.control_history[1:]):
        assert np.array_equal(s.controls, U)
    assert (end.status, end.message, end.converged, end.cost, end.iterations) == \
        (r.status, r.message, r.converged, r.cost, r.iterations)
    assert end.grad_norm == r.extra["optimality"]["grad_norm"] and 0.0 < end.solve_time <= r.solve_time_s
    assert [s.time for s in rec.steps] == list(r.time_history[1:])


def test_a_saddle_escape_is_an_iteration_the_callbacks_see_as_one():
    rec = Recorder()
    r = solve_scene(scene_dir() / "hard" / "target_180deg_x.toml", verbose=False, callbacks=[rec])
    assert r.extra["saddle_escapes"] and rec.steps[0].escape and rec.steps[0].expansion == "second"
    assert rec.steps[0].step == abs(r.extra["saddle_escapes"][0]["alpha"]) and rec.steps[0].rungs == 0
    assert not any(s.escape for s in rec.steps[1:]) and len(rec.steps) == r.iterations
    assert rec.grads == list(r.grad_norm_history)


def test_verbose_is_the_verbose_table_callback_on_the_stream():
    """verbose=True prints what a VerboseTable prints: the header, one row per step (the escape's
    marked "escape"), the final line; the rows hold the recorded histories."""
    path = scene_dir() / "hard" / "target_180deg_x.toml"
    table, own = io.StringIO(), io.StringIO()
    r = solve_scene(path, verbose=True, stream=table)
    solve_scene(path, verbose=False, callbacks=[VerboseTable(own)])
    ms = re.compile(r"[0-9.]+ ms\n")
    assert ms.sub("", table.getvalue()) == ms.sub("", own.getvalue())
    lines = table.getvalue().splitlines()
    assert lines[0] == "iter                 cost     |grad|          dJ    lambda   gamma    exp    rungs"
    assert len(lines) == r.iterations + 2 and lines[-1].startswith(f"{r.status} ({r.message}); J = {r.cost:.12e}")
    rows = [line.split() for line in lines[1:-1]]
    assert rows[0][6] == "escape" and [row[6] for row in rows[1:]] == r.expansion_history[1:]
    for k, row in enumerate(rows):
        assert int(row[0]) == k and float(row[1]) == float(f"{r.cost_history[k]:.14e}")
        assert float(row[2]) == float(f"{r.grad_norm_history[k]:.3e}")
        assert float(row[5]) == float(f"{r.step_history[k]:.4f}")


def test_history_records_the_first_gradient_of_an_iterate_only():
    h = History(record_controls=False)
    h.on_start(Start(2.0, np.zeros((3, 1)), 0.0))
    h.on_gradient(0.5)
    h.on_iteration(Step(0, 2.0, 0.5, 1.0, 0.0, 1.0, "first", 0, False, np.zeros((3, 1)), 0.1))
    a = h.arrays()
    assert list(a["cost_history"]) == [2.0, 1.0] and list(a["grad_norm_history"]) == [0.5]
    assert a["control_history"] is None and a["expansion_history"] == ["first"] and list(a["time_history"]) == [0.0, 0.1]


@pytest.mark.parametrize("value, parameter", [("abc", "callbacks"), (3, "callbacks"), ([object()], "callbacks[0]"),
                                              ([Callback(), print], "callbacks[1]")])
def test_callbacks_that_are_not_callbacks_are_refused(value, parameter):
    with pytest.raises(InputError) as e:
        SolverOptions(callbacks=value)
    assert e.value.parameter == parameter


# ----------------------------------------------------------------------------- the policy


def _policy(expansion="switch", **options):
    return ExpansionPolicy(SolverOptions(expansion=expansion, verbose=False, **options), 100.0, None)


def test_the_paper_switch_hands_over_at_the_ratio_with_an_exact_first_order():
    p, U = _policy(switch_ratio=0.1), np.zeros((4, 1))
    p.linearised(1, gauss_newton=False)
    assert p.order(1, 11.0, U) == 1 and p.order(2, 9.0, U) == 2 and p.expansion == "second"
    assert _policy("first").order(50, 0.0, U) == 1 and _policy("second").order(0, 100.0, U) == 2


def test_gauss_newton_ignores_the_ratio_and_counts_full_steps_only():
    p, U = _policy(switch_after=2), np.zeros((4, 1))
    p.linearised(1, gauss_newton=True)
    assert p.order(1, 1.0, U) == 1  # J / J0 = 0.01: the paper's test does not apply
    p.stepped(10.0, 0.5, "first")
    p.stepped(9.0, 1.0, "first")
    assert p.order(2, 1.0, U) == 1  # one full step of two
    p.stepped(8.0, 1.0, "first")
    assert p.order(3, 1.0, U) == 2
    q = _policy(switch_after=2)
    q.linearised(1, gauss_newton=True)
    q.stepped(10.0, 1.0, "first")
    q.stepped(0.05, 1.0, "first")  # a full step that cut the decrease 200x: superlinear, switch waits
    assert q.superlinear() and q.order(2, 50.0, U) == 1 and q.order(8, 50.0, U) == 1 and not q.second


def test_hand_back_runs_first_order_until_a_full_unregularised_step():
    """An exact model indefinite beyond reg_max hands the iterations back to first order (second
    and switch alike) until a first-order step is full with lambda = 0; at first order it stops."""
    U = np.zeros((4, 1))
    for expansion in ("second", "switch"):
        p = _policy(expansion)
        p.second = True  # second from the start; switch after its hand-over
        p.stepped(6.0, 1.0, "first", lam=0.0)  # a full unregularised step before the hand back ...
        assert p.order(3, 50.0, U) == 2 and p.hand_back() and p.expansion == "first"
        assert p.order(3, 50.0, U) == 1  # ... does not count: one first-order step at least
        p.stepped(5.0, 1.0, "first", lam=1e-3)  # full but regularised
        assert p.order(4, 45.0, U) == 1
        p.stepped(4.0, 1.0 / 3.0, "first", lam=0.0)  # unregularised but damped
        assert p.order(5, 41.0, U) == 1
        p.stepped(3.0, 1.0, "first", lam=0.0)
        assert p.order(6, 38.0, U) == 2 and p.expansion == "second" and not p.handed_back
    first = _policy("first")
    assert not first.hand_back() and first.order(1, 50.0, U) == 1


def test_certification_thresholds():
    p, U = _policy(tol=1e-8), np.zeros((4, 1))
    assert not p.certifies_early(U)  # an exact first order keeps the paper's rules
    p.linearised(1, gauss_newton=True)
    assert p.certifies_early(U) and p.certifies(1e-9, 1.0, U) and not p.certifies(2e-9, 1.0, U)
    assert p.newton_threshold(1e10) == 16 * np.finfo(float).eps * 1e10
    bounded = ExpansionPolicy(SolverOptions(verbose=False, tol=1e-8), 1.0, (np.full((4, 1), -1.0), np.full((4, 1), 1.0)))
    bounded.linearised(1, gauss_newton=True)
    on = np.array([[1.0], [0.0], [0.0], [0.0]])
    assert bounded.on_a_bound(on) and not bounded.certifies_early(on) and not bounded.on_a_bound(U)
    assert bounded.certifies(1e-11, 1.0, on) and not bounded.certifies(1e-10, 1.0, on)  # CERTIFY_WITH_LIMITS


# ----------------------------------------------------------------------------- the Result's kinds


def test_each_problem_gets_its_kind_of_result(tmp_path):
    sat = solve(paper_problem(horizon=20), SolverOptions(verbose=False, max_iter=3))
    mb = solve(quadrotor(horizon=5), SolverOptions(verbose=False, max_iter=2))
    assert type(sat) is SatelliteResult and type(mb) is MultibodyResult
    assert isinstance(sat, Result) and isinstance(mb, Result)
    assert sat.rotations is sat.q and mb.configurations is mb.q and mb.multibody["root"] == "free_flyer"
    for r in (sat, mb):
        back = Result.read_json(r.write_json(tmp_path / f"{r.model['kind']}.json"))
        assert type(back) is type(r) and np.array_equal(back.q, r.q) and np.array_equal(back.rotations, r.rotations)


def test_a_result_of_another_kind_is_the_generic_result(tmp_path):
    sat = solve(paper_problem(horizon=10), SolverOptions(verbose=False, max_iter=2))
    assert result_class({"kind": "pendulum"}) is Result and result_class(sat.model) is SatelliteResult
    fields = {k: getattr(sat, k) for k in ("times", "controls", "feedforward", "feedback", "cost", "iterations",
                                           "converged", "status", "message", "cost_history", "grad_norm_history",
                                           "reg_history", "step_history", "expansion_history", "solve_time_s",
                                           "timings", "expansion", "dt")}
    r = Result(q=np.zeros((11, 2)), v=np.zeros((11, 2)), model={"kind": "pendulum", "integrator": "euler"}, **fields)
    # no root body it knows of: identity attitudes, zero rates (as a fixed root's)
    assert np.array_equal(r.rotations, np.tile(np.eye(3), (11, 1, 1))) and not r.angular_velocities.any()
    assert r.attitude_error_deg == 0.0 and r.model == {"kind": "pendulum", "integrator": "euler", "dt": sat.dt}
    d = json.loads(r.write_json(tmp_path / "p.json").read_text())
    assert d.keys() == sat.to_dict().keys() and d["configurations"] is None and d["model"]["kind"] == "pendulum"


def test_with_trajectory_keeps_the_kind_and_derives_its_views_again():
    mb = solve(quadrotor(horizon=5), SolverOptions(verbose=False, max_iter=2))
    mb.rotations = np.zeros((6, 3, 3))  # an assigned view ...
    q = np.array(mb.q)
    q[:, 3:7] = [0.0, 0.0, np.sin(0.25), np.cos(0.25)]  # yawed 0.5 rad
    run = mb.with_trajectory(mb.times, q, mb.v, mb.controls, simulation={"policy": "open"})
    assert type(run) is MultibodyResult and run.extra["simulation"] == {"policy": "open"} and "simulation" not in mb.extra
    assert run.model == mb.model and run.model is not mb.model
    np.testing.assert_allclose(run.rotations[2], [[np.cos(0.5), -np.sin(0.5), 0.0], [np.sin(0.5), np.cos(0.5), 0.0],
                                                  [0.0, 0.0, 1.0]], atol=1e-15)  # ... derived again from q


def test_relative_certification_threshold_scales_with_J():
    """At the default (relative) stopping rule the threshold is rtol |J|: scaling the cost scales it."""
    p = ExpansionPolicy(SolverOptions(verbose=False), 1.0, None)
    p.linearised(1, gauss_newton=True)
    U = np.zeros((4, 1))
    assert p.newton_threshold(1.0) == 1e-11 and np.isclose(p.newton_threshold(1e6), 1e-5, rtol=1e-15, atol=0)
    assert p.certifies(1e-12, 1.0, U) and not p.certifies(2e-12, 1.0, U)  # CERTIFY_EARLY = 0.1
    assert p.certifies(1e-6, 1e6, U) and not p.certifies(2e-6, 1e6, U)
