"""Shared fixtures: the paper's problem and its solves (session-scoped: solved once)."""
import numpy as np
import pytest

from geoddp.problem import paper_problem
from geoddp.solver import SolverOptions, solve


@pytest.fixture(scope="session")
def paper():
    return paper_problem()


@pytest.fixture(scope="session")
def paper_solves(paper):
    """Each expansion run past the default stopping test (tol = 0) with every iterate recorded."""
    out = {}
    for exp in ("first", "second", "switch"):
        out[exp] = solve(paper, SolverOptions(expansion=exp, verbose=False, tol=0.0, grad_tol=1e-11,
                                              max_iter=40, record_controls=True))
    return out


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)
