"""The robots guide's Python example of a multibody problem with a cost term of the user's own
(docs/guide/robots.md, "From Python: a problem from cost terms"): the block runs as printed, and
its custom term is checked against the built-in kernels in a whole solve and against finite
differences."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from geoddp.costs.multibody import MultibodyCostSum, StateRegularisation
from geoddp.problem import Problem
from geoddp.solver import SolverOptions, solve

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "robots.md"


def _example() -> str:
    """The guide's python block that defines JointSpeed."""
    blocks = re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), flags=re.S)
    (block,) = [b for b in blocks if "class JointSpeed(MultibodyCostTerm)" in b]
    return block


@pytest.fixture(scope="module")
def example():
    ns: dict = {"__name__": "readme_example"}
    exec(compile(_example(), "docs/guide/robots.md (JointSpeed example)", "exec"), ns)
    return ns


def test_the_example_runs_and_prints_what_the_guide_says(example):
    result = example["result"]
    assert result.converged and result.iterations == 6
    printed = f"{result.status} J* = {result.cost:.9f} {result.iterations} iterations"
    assert f"This prints `{printed}`." in GUIDE.read_text(encoding="utf-8")


def test_the_custom_term_solves_as_the_kernels_do(example):
    """The joint-speed penalty of the user's own against the same penalty as a built-in
    StateRegularisation on v (run by the kernels): the same iterations and J* to 1e-12."""
    ns = example
    pm, q0, p = ns["pm"], ns["q0"], ns["problem"]
    builtin = [t for t in p.running.terms if type(t).__name__ != "JointSpeed"]
    builtin.append(StateRegularisation(pm, q0, W=np.r_[np.zeros(6), np.full(6, 1e-2)]))
    twin = Problem(ns["ur5"], q0, np.zeros(6), p.horizon, MultibodyCostSum(builtin), p.terminal)
    U0 = np.tile(ns["tau_g"], (p.horizon, 1))
    r = solve(twin, SolverOptions(expansion="switch", verbose=False), initial_controls=U0)
    mine = ns["result"]
    assert r.iterations == mine.iterations
    assert abs(r.cost - mine.cost) <= 1e-12 * abs(r.cost)
    np.testing.assert_allclose(mine.controls, r.controls, rtol=0, atol=1e-9 * np.abs(r.controls).max())


def test_the_custom_terms_derivatives_match_finite_differences(example):
    """JointSpeed's accumulate against central differences of its value along (dq, dv)."""
    ns = example
    pm, term = ns["pm"], ns["JointSpeed"](1e-2)
    rng = np.random.default_rng(4)
    q = pin.integrate(pm, ns["q0"], rng.uniform(-0.5, 0.5, pm.nv))
    v = rng.normal(size=pm.nv)
    s = MultibodyCostSum([term], model=pm)
    d = s.derivatives(q[None], v[None], None)
    f = lambda z: s.value(pin.integrate(pm, q, z[:pm.nv])[None], (v + z[pm.nv:])[None], None)[0]  # noqa: E731
    h, n = 1e-5, 2 * pm.nv
    E = np.eye(n)
    grad = np.array([(f(h * e) - f(-h * e)) / (2 * h) for e in E])
    hess = np.array([[(f(h * (a + b)) - f(h * (a - b)) - f(h * (b - a)) + f(-h * (a + b))) / (4 * h * h) for b in E]
                     for a in E])
    assert np.abs(grad - d.lx[0]).max() < 1e-8 * max(1.0, np.abs(grad).max())
    assert np.abs(hess - d.lxx[0]).max() < 1e-5 * max(1.0, np.abs(hess).max())


# ------------------------------------------------------------------ the closed-loop guide's MPC by hand

CLOSED_LOOP = GUIDE.parent / "closed_loop.md"


def test_mpc_by_hand_runs_prints_what_the_guide_says_and_is_the_mpc_policy(capsys):
    """docs/guide/closed_loop.md, "MPC by hand": the block runs as printed, prints the error the
    guide quotes, leaves the window problem unchanged, and applies the controls geoddp.simulate.MPC
    applies with every=1 from the same warm start, bit for bit."""
    from geoddp.simulate import MPC, simulate

    blocks = re.findall(r"```python\n(.*?)```", CLOSED_LOOP.read_text(encoding="utf-8"), flags=re.S)
    (block,) = [b for b in blocks if "with_initial_state" in b]
    ns: dict = {"__name__": "closed_loop_example"}
    exec(compile(block, "docs/guide/closed_loop.md (MPC by hand)", "exec"), ns)
    printed = capsys.readouterr().out.strip()
    assert printed.startswith("attitude error after 5 s: ") and f"prints `{printed}`" in CLOSED_LOOP.read_text()
    window, plant = ns["window"], ns["plant"]
    np.testing.assert_array_equal(window.R0, np.eye(3))  # with_initial_state left it as built
    plan = solve(window, SolverOptions())
    mpc = MPC(window, horizon=100, every=1, max_iter=3)  # no plan: the first warm start is zeros, as above
    run = simulate(plan, window, mpc, plant=plant, steps=500)
    np.testing.assert_array_equal(np.array(ns["applied"]), run.u)
    np.testing.assert_array_equal(run.q[-1], ns["R"])


# ------------------------------------------------------------------ getting started

GETTING_STARTED = GUIDE.parents[1] / "getting_started.md"


def test_getting_started_python_blocks_run_and_say_what_they_get(tmp_path, monkeypatch, capsys):
    """Every python block of docs/getting_started.md runs as printed (in an empty folder: the first
    writes out/result.json), and the numbers its comments quote are the ones it gets."""
    text = GETTING_STARTED.read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 3
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "getting_started"}
    for i, block in enumerate(blocks):
        exec(compile(block, f"docs/getting_started.md (block {i})", "exec"), ns)
        if "hover" in block and "zero" in block:
            hover, zero = ns["hover"], ns["zero"]
            assert f"J = {hover.cost_history[0]:.2e} at the start, {hover.iterations} iterations to J* = " \
                   f"{hover.cost:.6g}" in block
            assert f"J = {zero.cost_history[0]:.2e} (it falls), {zero.status!r}" in block
            assert capsys.readouterr().out.startswith("iter ")  # verbose=True, and only it, printed
    assert (tmp_path / "out" / "result.json").is_file()
    assert f"J* = {str(ns['solve'](ns['moved']).cost)[:5]}..." in text
    np.testing.assert_array_equal(ns["problem"].R0, np.eye(3))  # with_initial_state left it as built
