"""The few-lines entry point: scene file, built-in scene name (or spec) in, :class:`~geoddp.solver.result.Result`
out (:func:`solve_scene`; the public facade ``geoddp.solve_scene``)."""
from __future__ import annotations

import weakref
from pathlib import Path
from typing import Any

from ..solver import solve
from ..solver.result import Result
from .build import AnySceneSpec, build_problem, initial_controls, solver_options
from .common import TABLES
from .legged import LeggedSceneSpec
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


# Keywords of solve_scene that are [solver] keys of the scene (geoddp.scene.common.TABLES): they
# replace the spec's fields (re-validated by with_overrides, as the reader checks them). Of those,
# the ones the built problem depends on: the model's expansion of the reconstruction and the
# constraints' tolerance; the others leave the problem as built (see built_problem).
SCENE_KEYS = tuple(TABLES["solver"])
PROBLEM_KEYS = ("second_order", "constraint_tol")


def solve_scene(scene: str | Path | AnySceneSpec, *, verbose: bool = False, **options: Any) -> Result:
    """Load (if a path or a built-in scene's name, see :func:`geoddp.scene.load_scene`), build and
    solve a scene: satellite, multibody or legged (``[model] kind``).

    Keyword options override the scene's ``[solver]`` table, checked as the table is (the error
    names the keyword): ``expansion``, ``switch_ratio``, ``tol``, ``rtol``, ``grad_tol``,
    ``grad_rtol``, ``max_iter``, ``second_order``, ``constraint_tol`` and ``initial_controls``.
    Any other field of :class:`~geoddp.solver.SolverOptions` is passed to the solver
    (``record_controls=True``, ``callbacks=[...]``, ``stream``, ``switch_after``, ...).

    Args:
        scene: a scene file, a built-in scene's name or a spec from :func:`geoddp.load_scene`.
        verbose: print the per-iteration table (and, for a scene with constraints, one line per
            outer iteration); False by default (silent).
        initial_controls: the start. A multibody scene takes an (H, m) sequence, an (m,) input
            held over the horizon, or a name: ``"quasi_static"`` (the default start: the inputs
            that hold the initial posture against gravity where the actuation can, least
            squares), ``"gravity_compensation"`` (the same), ``"hover"`` (the same where it
            balances gravity exactly, else an error) or ``"zero"`` (zeros, clipped into the
            limits). A satellite scene takes an (H, m) sequence of torques, N m. Inside the
            scene's ``[limits]``.
        second_order: "exact" or "paper" (the paper's expansion of the reconstruction: the
            satellite on TSO(3) only).
        constraint_tol: the tolerance the scene's ``[[constraints]]`` are met to, in each
            constraint's units (>= 0).
        options: the other ``[solver]`` keys and :class:`~geoddp.solver.SolverOptions` fields.

    Returns:
        The :class:`~geoddp.solver.result.Result` (a satellite or a multibody result);
        ``result.extra["scene"]`` is the scene's name.

    Raises:
        InputError: naming the keyword for a bad value (``initial_controls: expected ...``) or an
            unknown keyword (with the closest known one), or the scene's key path and file.

    Example: ``solve_scene("ur5_reach", initial_controls="zero", max_iter=50, verbose=True)``.
    """
    import dataclasses
    import os

    from ..solver.options import SolverOptions
    from ..validate import InputError, closest

    if not isinstance(scene, (SceneSpec, MultibodySceneSpec, LeggedSceneSpec, str, os.PathLike)):
        raise InputError("scene", f"expected a scene file path, a built-in scene's name or a spec from "
                         f"geoddp.scene.load_scene, got {type(scene).__name__}"
                         + (" (write the table to a TOML file and pass its path)" if isinstance(scene, dict) else ""))
    known = {f.name for f in dataclasses.fields(SolverOptions)} | set(SCENE_KEYS)
    for key in options:
        if key not in known:
            hint = closest(key, known)
            raise InputError(key, "unknown option of solve_scene" + (f" (did you mean {hint!r}?)" if hint else "")
                             + f"; known: {', '.join(sorted(known))}")
    spec = scene if isinstance(scene, (SceneSpec, MultibodySceneSpec, LeggedSceneSpec)) else load_scene(scene)
    overrides = {k: v for k, v in options.items() if k in SCENE_KEYS}
    if "initial_controls" in overrides:  # a name or an array, as the [solver] table takes it
        overrides["initial_controls"] = spec.read_initial_controls(overrides["initial_controls"])
    problem_spec = spec
    if overrides:  # with_overrides re-validates the whole spec: only when something changes
        spec = spec.with_overrides(**overrides)
        if any(k in overrides for k in PROBLEM_KEYS):
            problem_spec = spec
    rest = {k: v for k, v in options.items() if k not in SCENE_KEYS}
    # the solver's own keys leave the problem as built: a spec's problem serves every solve of it
    problem = built_problem(problem_spec)
    # a scene with constraints solves by its outer loop (geoddp.constraints.solve_constrained)
    run = getattr(problem, "solve_constrained", None) or (lambda opt, U0: solve(problem, opt, initial_controls=U0))
    result = run(solver_options(spec, verbose=verbose, **rest), initial_controls(spec))
    result.extra["scene"] = spec.name
    return result
