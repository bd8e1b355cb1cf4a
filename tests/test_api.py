"""geoddp.solve_scene (geoddp.scene.solve): the problem built from a spec is reused while the spec lives."""
from __future__ import annotations

import gc

import numpy as np

from geoddp import load_scene, solve_scene
from geoddp.scene import solve as api


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


def test_overrides_and_other_specs_build_their_own_problem(monkeypatch):
    calls = _count_builds(monkeypatch)
    spec = load_scene("coarse_dt_0p1")
    first = solve_scene(spec, verbose=False, expansion="first")
    switch = solve_scene(spec, verbose=False)
    assert calls == ["coarse_dt_0p1", "coarse_dt_0p1"]  # with_overrides made a new spec
    assert first.expansion == "first" and switch.expansion == "switch"
    assert abs(first.cost - switch.cost) <= 1e-9 * abs(switch.cost)


def test_the_cache_lets_a_spec_go(monkeypatch):
    _count_builds(monkeypatch)
    spec = load_scene("coarse_dt_0p1")
    solve_scene(spec, verbose=False)
    key = id(spec)
    assert key in api._BUILT
    del spec
    gc.collect()
    assert key not in api._BUILT
