"""Issue 5, property tests (hypothesis) for the solver: invariants on random satellite problems.

Runs are bounded (max_examples) and deterministic (derandomize=True). The SO(3) property tests
are in test_lie_so3_properties.py.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoddp.problem import satellite_problem
from geoddp.solver import SolverOptions, cost_gradient, solve


@st.composite
def small_problems(draw):
    """Random valid satellite problems: inertia (triangle inequality), target anywhere (incl. near
    pi), tumbling starts, both integrators and attitude costs, H = 20."""
    moments = draw(st.lists(st.floats(1.0, 20.0), min_size=3, max_size=3))
    moments = sorted(moments)
    if moments[2] > moments[0] + moments[1]:
        moments[2] = moments[0] + moments[1]
    axis = np.array(draw(st.lists(st.floats(-1, 1), min_size=3, max_size=3))) + 1e-3
    angle = draw(st.floats(0.0, np.pi - 1e-3))
    R_d = pin.exp3(angle * axis / np.linalg.norm(axis))
    Omega0 = np.array(draw(st.lists(st.floats(-3, 3), min_size=3, max_size=3)))
    return satellite_problem(
        inertia=np.diag(moments), dt=0.05, horizon=20, R_d=R_d, Omega0=Omega0, S_u=0.1, S_R=100.0,
        S_Omega=100.0, attitude_kind=draw(st.sampled_from(["chordal", "geodesic"])),
        integrator=draw(st.sampled_from(["euler", "semi_implicit"])),
    )


@settings(max_examples=25, derandomize=True, deadline=None)
@given(small_problems(), st.sampled_from(["first", "second", "switch"]))
def test_solver_invariants(problem, expansion):
    r = solve(problem, SolverOptions(expansion=expansion, verbose=False, max_iter=300))
    assert np.all(np.diff(r.cost_history) <= 0.0)  # never rises between accepted iterates
    for a in (r.rotations, r.angular_velocities, r.controls, r.feedback, r.cost_history, r.grad_norm_history):
        assert np.all(np.isfinite(a))
    RtR = np.einsum("nji,njk->nik", r.rotations, r.rotations)
    assert np.abs(RtR - np.eye(3)).max() < 1e-12
    # the reported cost and gradient are those of the returned controls
    J, g = cost_gradient(problem, r.controls)
    assert J == pytest.approx(r.cost, rel=1e-12)
    assert np.linalg.norm(g) == pytest.approx(r.grad_norm, rel=1e-6, abs=1e-12)
    if r.converged:
        assert r.grad_norm <= 1e-4 * max(1.0, r.grad_norm_history[0])
    else:
        assert r.status != "" and r.message != ""
