"""The keep-out satellite (Table I with its body x axis kept 20 degrees from (0.849, 0.482, 0.215))
against IPOPT through CasADi on the same discrete problem (benchmarks/keep_out_ipopt.py: multiple
shooting, exact Hessian, tol 1e-12): the two formulations are one problem (the CasADi cost of
geoddp's controls is geoddp's J to 1e-12), and every expansion converges to IPOPT's optimum to
1e-7 relative in J (measured 2.8e-9: what the constraint tolerance 1e-8 allows; 1e-12 at 1e-11),
the cone holding at every node. casadi is in the test extra: this test does not skip."""
from __future__ import annotations

import sys
from pathlib import Path

import casadi  # noqa: F401  (the test extra installs it; a missing casadi must fail, not skip)
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from keep_out_ipopt import EXPANSIONS, casadi_cost, keep_out_problem, min_angle_deg, solve_geoddp, solve_ipopt  # noqa: E402

from geoddp.constraints import STATUS_KKT  # noqa: E402


@pytest.fixture(scope="module")
def problem_and_ipopt():
    cp = keep_out_problem()
    return cp, solve_ipopt(cp)


def test_ipopt_solves_the_same_discrete_problem(problem_and_ipopt):
    cp, ip = problem_and_ipopt
    assert ip["status"] == "Solve_Succeeded"
    assert ip["dynamics_residual"] <= 1e-12 and ip["max_cone"] <= 1e-10
    # IPOPT's controls rolled out by geoddp give IPOPT's states and cost: the same dynamics and J
    traj = cp.problem.trajectory(ip["U"])
    np.testing.assert_allclose(traj.q[1:], ip["R"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.v[1:], ip["Omega"], rtol=0, atol=1e-11)
    assert cp.problem.trajectory_cost(traj) == pytest.approx(ip["J"], rel=1e-12)
    assert min_angle_deg(cp, ip["R"]) >= 20.0 - 1e-8


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_every_expansion_converges_to_the_ipopt_optimum(problem_and_ipopt, expansion):
    cp, ip = problem_and_ipopt
    r = solve_geoddp(cp, expansion)
    assert r.status == STATUS_KKT
    assert casadi_cost(cp, r.controls) == pytest.approx(r.cost, rel=1e-12)  # one problem, two formulations
    assert abs(r.cost - ip["J"]) <= 1e-7 * abs(ip["J"])
    assert r.extra["constraints"]["max_violation"] <= 1e-8
    assert min_angle_deg(cp, r.q) >= 20.0 - 1e-6  # cos(angle) - cos(20 deg) <= 1e-8 at every node
    # the same trajectory, not only the same J
    assert np.abs(r.controls - ip["U"]).max() <= 1e-5 * np.abs(ip["U"]).max()  # measured 3.6e-5 of 11.3 N m


def test_the_gap_to_ipopt_is_the_constraint_tolerance(problem_and_ipopt):
    cp, ip = problem_and_ipopt
    r = solve_geoddp(cp, "second", constraint_tol=1e-11)
    assert r.status == STATUS_KKT and r.extra["constraints"]["max_violation"] <= 1e-11
    assert abs(r.cost - ip["J"]) <= 1e-10 * abs(ip["J"])  # measured 1.1e-12
    assert np.abs(r.controls - ip["U"]).max() <= 1e-7 * np.abs(ip["U"]).max()  # measured 7.8e-8 of 11.3
