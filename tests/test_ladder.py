"""The regularisation ladder's search (geoddp.solver.ladder; its C++ twin in cpp/riccati/ladder.hpp):
against the one-rung loop on monotone outcomes, on arbitrary ones, and rung for rung between the
two languages."""
from __future__ import annotations

import math

import numpy as np
import pinocchio  # noqa: F401  (before geoddp._core: its import loads the libpinocchio _core links)
import pytest

from geoddp import _core
from geoddp.solver.ladder import LadderSearch, ladder
from geoddp.solver.options import SolverOptions
from geoddp.validate import InputError


def run(top: int, two: bool, factorises) -> tuple[list[tuple[int, ...]], int, bool]:
    """The Python search against a table of outcomes: (rounds, hi, found)."""
    s = LadderSearch(top, two)
    rounds = []
    while probes := s.probes():
        rounds.append(probes)
        s.record(probes, [bool(factorises[p]) for p in probes])
    return rounds, s.hi, s.found


def test_ladder_is_the_one_rung_loops_values():
    o = SolverOptions()
    for lam0 in (0.0, 1e-9, 3e-4, 2.0, o.reg_max, 2 * o.reg_max):
        rungs = ladder(lam0, o.reg_increase, o.reg_min, o.reg_max)
        lam, expected = lam0, [lam0]
        while True:  # the paper's loop: lam <- max(1.9 lam, reg_min) until above reg_max
            lam = max(lam * o.reg_increase, o.reg_min)
            expected.append(lam)
            if lam > o.reg_max:
                break
        assert rungs == expected and len(rungs) >= 2
        assert all(r <= o.reg_max for r in rungs[1:-1]) and rungs[-1] > o.reg_max


@pytest.mark.parametrize("args, name", [
    ((float("nan"), 1.9, 1e-8, 1e10), "lam"), ((-1.0, 1.9, 1e-8, 1e10), "lam"),
    ((0.0, 1.0, 1e-8, 1e10), "reg_increase"), ((0.0, float("nan"), 1e-8, 1e10), "reg_increase"),
    ((0.0, 1.9, 0.0, 1e10), "reg_min"), ((0.0, 1.9, 1e-8, float("inf")), "reg_max"),
])
def test_a_ladder_that_would_not_end_is_refused(args, name):
    # options changed after SolverOptions validated them: never an endless loop
    with pytest.raises(InputError, match=name):
        ladder(*args)


@pytest.mark.parametrize("two", [False, True], ids=["one_at_a_time", "two_a_round"])
def test_monotone_outcomes_give_the_lowest_rung_that_factorises(two):
    """Monotone in lambda (every rung from t up factorises): the search ends on rung t, as the
    one-rung loop does, or gives up when no rung below the top factorises; galloping and
    bisection take about 2 log2(t) passes (rounds, two a round), not t."""
    for top in (1, 2, 3, 5, 8, 31, 40, 64):
        for t in range(1, top + 1):  # t = top: nothing below the top factorises
            rounds, hi, found = run(top, two, [j >= t for j in range(top)])
            assert (hi, found) == ((t, True) if t < top else (top, False)), (top, t, rounds)
            bound = 2 * math.ceil(math.log2(t + 1)) + 1
            assert len(rounds) <= bound, (top, t, rounds)
            probes = [p for r in rounds for p in r]
            assert len(set(probes)) == len(probes) and all(0 < p < top for p in probes)
            assert all(list(r) == sorted(r) for r in rounds)


def test_rounds_counted_on_the_first_iterations_ladder():
    # the first second-order iteration climbs ~30 rungs on the benchmark cases
    assert len(run(40, False, [j >= 30 for j in range(40)])[0]) == 9
    assert len(run(40, True, [j >= 30 for j in range(40)])[0]) == 6
    # and a first rung that factorises costs one pass, as before
    assert run(40, False, [j >= 1 for j in range(40)])[0] == [(1,)]
    assert run(40, True, [j >= 1 for j in range(40)])[0] == [(1, 2)]


@pytest.mark.parametrize("two", [False, True], ids=["one_at_a_time", "two_a_round"])
def test_any_outcomes_end_on_a_rung_that_factorises_above_one_that_fails(two):
    rng = np.random.default_rng(7)
    for _ in range(400):
        top = int(rng.integers(1, 50))
        table = [False] + list(rng.random(top - 1) < rng.random())
        rounds, hi, found = run(top, two, table)
        if found:
            assert table[hi] and not table[hi - 1], (table, rounds, hi)
        else:
            assert hi == top and not table[top - 1]


@pytest.mark.parametrize("two", [False, True], ids=["one_at_a_time", "two_a_round"])
def test_the_compiled_search_probes_the_same_rungs(two):
    """cpp/riccati/ladder.hpp (regularised_contracted's search) rung for rung against the Python one, on
    monotone and arbitrary outcome tables."""
    rng = np.random.default_rng(11)
    tables = [[j >= t for j in range(top)] for top in (1, 7, 40) for t in range(1, top + 1)]
    for _ in range(300):
        top = int(rng.integers(1, 60))
        tables.append([False] + list(rng.random(top - 1) < rng.random()))
    for table in tables:
        rounds, hi, found = _core.testing.ladder_search(len(table), two, table)
        assert ([tuple(r) for r in rounds], hi, found) == run(len(table), two, table), table
    with pytest.raises(ValueError, match="factorises"):
        _core.testing.ladder_search(3, two, [False, True])
