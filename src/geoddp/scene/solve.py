"""The few-lines entry point: scene file, built-in scene name (or spec) in, :class:`~geoddp.solver.result.Result`
out (:func:`solve_scene`; the public facade ``geoddp.solve_scene``)."""
from __future__ import annotations

import weakref
from pathlib import Path
from typing import Any

from ..solver import solve
from ..solver.result import Result
from .build import AnySceneSpec, build_problem, initial_controls, solver_options
from .load import load_scene
from .multibody import MultibodySceneSpec
from .satellite import SceneSpec


# A spec is frozen, arrays included, and the solver never changes a problem: the problem built
# from a spec is kept while the spec lives, so solving one spec again (a benchmark, a sweep, an
# MPC loop) neither re-reads its URDF nor re-validates its weights (the public route adds at
# most 10 % to the solve: benchmarks/api_overhead.py).
_BUILT: dict[int, tuple[weakref.ref, Any]] = {}


def built_problem(spec: AnySceneSpec) -> Any:
    """The problem of ``spec`` (:func:`geoddp.scene.build_problem`), built once per spec object (and
    shared by every solve of it: :func:`solve_scene`, :func:`geoddp.simulate.simulate_scene`)."""
    key = id(spec)
    hit = _BUILT.get(key)
    if hit is not None and hit[0]() is spec:
        return hit[1]
    problem = build_problem(spec)
    _BUILT[key] = (weakref.ref(spec, lambda _ref, key=key: _BUILT.pop(key, None)), problem)
    return problem


def solve_scene(scene: str | Path | AnySceneSpec, *, verbose: bool = True, **options: Any) -> Result:
    """Load (if a path or a built-in scene's name, see :func:`geoddp.scene.load_scene`), build and
    solve a scene: satellite or multibody (``[model] kind``).

    Keyword options override the scene's ``[solver]`` table (for example ``expansion="second"``,
    ``record_controls=True``, ``verbose=False``).
    """
    import dataclasses
    import os

    from ..solver.options import SolverOptions
    from ..validate import InputError, closest

    if not isinstance(scene, (SceneSpec, MultibodySceneSpec, str, os.PathLike)):
        raise InputError("scene", f"expected a scene file path, a built-in scene's name or a spec from "
                         f"geoddp.scene.load_scene, got {type(scene).__name__}"
                         + (" (write the table to a TOML file and pass its path)" if isinstance(scene, dict) else ""))
    known = {f.name for f in dataclasses.fields(SolverOptions)}
    for key in options:
        if key not in known:
            hint = closest(key, known)
            raise InputError(key, "unknown option of solve_scene" + (f" (did you mean {hint!r}?)" if hint else "")
                             + f"; known: {', '.join(sorted(known))}")
    spec = scene if isinstance(scene, (SceneSpec, MultibodySceneSpec)) else load_scene(scene)
    scene_keys = {"expansion", "switch_ratio", "tol", "rtol", "grad_tol", "grad_rtol", "max_iter"}
    overrides = {k: v for k, v in options.items() if k in scene_keys}
    if overrides:  # with_overrides re-validates the whole spec: only when something changes
        spec = spec.with_overrides(**overrides)
    rest = {k: v for k, v in options.items() if k not in scene_keys}
    problem = built_problem(spec)
    # a scene with constraints solves by its outer loop (geoddp.constraints.solve_constrained)
    run = getattr(problem, "solve_constrained", None) or (lambda opt, U0: solve(problem, opt, initial_controls=U0))
    result = run(solver_options(spec, verbose=verbose, **rest), initial_controls(spec))
    result.extra["scene"] = spec.name
    return result
