"""Scale-free stopping: the default stopping tests and the optimality certificate are relative to
|J| (rtol), an absolute ``tol`` (the paper's Table I criterion) replaces them where it is set, and
every satellite scene sets it, so their solves are the paper's.
"""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from geoddp import solve_scene
from geoddp.problem import satellite_problem
from geoddp.scene import load_scene, parse_scene, scene_file, solver_options
from geoddp.scene.satellite import SceneSpec
from geoddp.solver import SolverOptions, solve
from geoddp.solver.options import DEFAULT_GRAD_RTOL, DEFAULT_GRAD_TOL, DEFAULT_RTOL, ZERO_COST
from geoddp.validate import InputError


def test_thresholds_resolve_as_documented():
    d = SolverOptions()
    assert (d.tol, d.rtol, d.grad_tol, d.grad_rtol) == (None, None, None, None) and not d.absolute()
    assert DEFAULT_RTOL == 1e-11 and DEFAULT_GRAD_RTOL == 1e-12 and ZERO_COST == 1e-12
    assert d.cost_tolerance(2.0) == 2.0 * 1e-11 and d.cost_tolerance(-2.0e6) == 2.0e6 * 1e-11
    assert d.grad_tolerance(2.0) == 2.0 * 1e-12
    # |J| is measured from ZERO_COST |J_0| up: J* = 0 problems stop
    assert d.cost_tolerance(0.0, 4.0) == 1e-11 * 1e-12 * 4.0 and d.cost_tolerance(1.0, 4.0) == 1e-11
    # an absolute tol alone: the paper's test, and the gradient test absolute with it (as before)
    a = SolverOptions(tol=1e-8)
    assert a.absolute() and a.cost_tolerance(1e6) == 1e-8 and a.cost_tolerance(0.0) == 1e-8
    assert a.grad_tolerance(1e6) == DEFAULT_GRAD_TOL == 1e-10
    assert SolverOptions(tol=1e-8, grad_rtol=1e-9).grad_tolerance(10.0) == pytest.approx(1e-8, rel=1e-15)
    # both: either test suffices
    b = SolverOptions(tol=1e-8, rtol=1e-10)
    assert not b.absolute() and b.cost_tolerance(1.0) == 1e-8
    assert b.cost_tolerance(1e3) == pytest.approx(1e-7, rel=1e-15)
    assert SolverOptions(grad_tol=1e-6).grad_tolerance(1e9) == 1e-6  # an explicit grad_tol is absolute
    # the fields keep what was given: replace() means what it says
    assert dataclasses.replace(d, tol=1e-8).absolute() and not dataclasses.replace(a, rtol=1e-9).absolute()
    for name in ("tol", "rtol", "grad_tol", "grad_rtol"):
        with pytest.raises(InputError) as e:
            SolverOptions(**{name: -1.0})
        assert e.value.parameter == name


def test_every_satellite_scene_file_keeps_the_papers_absolute_tol():
    """Each satellite scene file (the paper's, the hard cases) sets tol = 1e-8 and grad_tol = 1e-10:
    their solves stay bit for bit the paper's (benchmarks/histories.py compare). The multibody,
    robot and legged scenes leave them unset: the relative default."""
    import geoddp

    root = scene_file("satellite_paper").parent
    files = sorted(p for p in root.rglob("*.toml") if "sweeps" not in p.parts)
    kinds = {}
    for path in files:
        spec = load_scene(path)
        kinds[path.stem] = type(spec).__name__
        opt = solver_options(spec)
        if isinstance(spec, SceneSpec):
            assert (spec.tol, spec.grad_tol, spec.rtol, spec.grad_rtol) == (1e-8, 1e-10, None, None), path
            assert opt.absolute() and opt.cost_tolerance(510.0) == 1e-8 and opt.grad_tolerance(510.0) == 1e-10
        else:
            assert spec.tol is None and spec.rtol is None and not opt.absolute(), path
    assert sum(k == "SceneSpec" for k in kinds.values()) == 18 and len(kinds) == 30, kinds
    assert geoddp  # the package data was found


def test_scene_files_spell_rtol_and_an_explicit_tol_keeps_its_meaning(tmp_path):
    path = scene_file("quadrotor")
    d = tomllib.loads(path.read_text())
    d["solver"]["rtol"], d["solver"]["grad_rtol"] = 1e-9, 1e-10
    spec = parse_scene(d, str(path))
    opt = solver_options(spec)
    assert (opt.tol, opt.rtol, opt.grad_rtol) == (None, 1e-9, 1e-10) and opt.cost_tolerance(2.0) == 2e-9
    d["solver"] = {"tol": 1e-8}
    opt = solver_options(parse_scene(d, str(path)))
    assert opt.absolute() and opt.grad_tolerance(2.0) == 1e-10
    d["solver"] = {"rtol": -1.0}
    with pytest.raises(InputError) as e:
        parse_scene(d, str(path))
    assert e.value.parameter == "[solver].rtol" and ">= 0" in str(e.value)
    d["solver"] = {"rtoll": 1e-9}
    with pytest.raises(InputError) as e:
        parse_scene(d, str(path))
    assert "rtol" in str(e.value)
    # solve_scene takes them as keyword options too
    r = solve_scene("quadrotor", verbose=False, tol=1e-8)
    assert r.iterations == 9 and r.extra["optimality"]["newton_threshold"] == 1e-8
    r = solve_scene("quadrotor", verbose=False)  # the file sets no tol: the relative default
    assert r.iterations == 10 and r.extra["optimality"]["newton_threshold"] == 1e-11 * r.cost


def _scaled(name: str, c: float):
    """The built-in scene ``name`` with every cost weight multiplied by c."""
    path = scene_file(name)
    d = tomllib.loads(path.read_text())
    for key in ("running_costs", "terminal_costs"):
        for t in d.get(key, []):
            for w in ("weight", "q_weight", "v_weight"):
                if w in t:
                    t[w] = (np.asarray(t[w], float) * c).tolist()
    return parse_scene(d, str(path))


@pytest.mark.parametrize("name", ["quadrotor", "quadrotor_thrust_limits", "spacecraft_docking", "ur5_reach",
                                  "solo12_reorient"])
def test_default_solve_is_invariant_to_scaling_the_cost(name):
    """Every weight x 1e-6 and x 1e6: the same iterations, the same controls to round-off, J* x c."""
    base = solve_scene(_scaled(name, 1.0), verbose=False)
    assert base.converged, base.message
    U = base.controls
    for c in (1e-6, 1e6):
        r = solve_scene(_scaled(name, c), verbose=False)
        assert r.converged and r.iterations == base.iterations, (c, r.iterations, base.iterations)
        assert np.abs(r.controls - U).max() <= 1e-12 * np.abs(U).max(), (c, np.abs(r.controls - U).max())
        assert r.cost / c == pytest.approx(base.cost, rel=1e-13)


def test_an_absolute_tol_is_not_scale_free():
    """The same test with the paper's absolute tol: scaling the cost changes the solve (the
    invariance above is the relative default's, not the scene's)."""
    its = [solve_scene(_scaled("ur5_reach", c), verbose=False, tol=1e-8).iterations for c in (1e-6, 1.0, 1e6)]
    assert its[0] < its[1] < its[2], its


def test_zero_optimal_cost_converges():
    """J* = 0 (a free spin reached exactly; started from random torques): the relative tests count
    J below ZERO_COST |J_0| as zero and stop, where rtol |J| alone shrank with J until round-off
    stalled the line search (68 iterations, "stalled")."""
    I, dt, H = np.diag([10.0, 11.1, 13.0]), 0.01, 100
    Om0 = np.array([0.3, -0.2, 0.5])
    free = satellite_problem(inertia=I, dt=dt, horizon=H, R_d=np.eye(3), Omega0=Om0)
    q, v = free.rollout(np.zeros((H, 3)))
    p = satellite_problem(inertia=I, dt=dt, horizon=H, R_d=q[-1], Omega0=Om0, Omega_d=v[-1])
    assert p.total_cost(np.zeros((H, 3))) < 1e-24
    U0 = 0.5 * np.random.default_rng(0).normal(size=(H, 3))
    r = solve(p, SolverOptions(verbose=False), initial_controls=U0)
    assert r.converged and r.iterations <= 4 and r.cost < 1e-20 * r.cost_history[0], (r.iterations, r.message)


def test_default_ends_at_or_below_the_absolute_tol():
    """On the multibody scenes the relative default ends at a J* no higher than the old absolute
    tol = 1e-8 did (to round-off), with at most one more iteration (switch)."""
    for name in ("quadrotor", "space_manipulator", "spacecraft_docking", "hector_fly", "ur5_reach",
                 "solo12_reorient"):
        new, old = solve_scene(name, verbose=False), solve_scene(name, verbose=False, tol=1e-8)
        assert new.converged and old.converged
        assert new.cost <= old.cost * (1.0 + 1e-15), (name, new.cost, old.cost)
        assert new.iterations <= old.iterations + 1, (name, new.iterations, old.iterations)
