"""Scene files: a TOML description of one optimal control problem, read once, built once.

::

    scene file | built-in name | dict
      -> reader.py     TOML -> plain table; Reader: key paths and did-you-mean in every error
      -> satellite.py  the satellite schema (paper Section VI) -> SceneSpec
         multibody.py  the general schema (any URDF, [model] kind = "multibody") -> MultibodySceneSpec
         legged.py     legged robots in contact ([model] kind = "legged": a gait or phases) -> LeggedSceneSpec
         common.py     the tables both kinds share ([solver]) and their spec fields (CommonSpec)
      -> load.py       load_scene / parse_scene: dispatch on [model].kind
      -> build.py      the one builder: build_problem, solver_options, initial_controls
         builtin.py    the built-in multibody scenes as problem builders
      -> solve.py      solve_scene: load, build and solve in one call (``geoddp.solve_scene``)

Every error is an :class:`~geoddp.validate.InputError` naming the key path (``[cost].attitude``,
``running_costs[1].frame``) and the file. Specs are frozen dataclasses of validated plain values;
only ``solve.py`` calls the solver.

Adding a table
--------------
* Shared by every kind (``[limits]``, ``[simulation]``): in ``common.py`` add its keys to
  :data:`~geoddp.scene.common.TABLES` (``"limits": {"control_min": False, ...}``), its fields
  (keyword-only, with defaults) to :class:`~geoddp.scene.common.CommonSpec` and their checks to
  ``CommonSpec._check_common`` (which knows nu, the number of inputs), and read it in
  :func:`~geoddp.scene.common.read_common` (``t = r.table("limits")``, then
  ``r.check(validator, t["control_min"], "[limits].control_min", ...)``: the reader names the key
  path; ``nu`` and, for a multibody scene, the ``pin.Model`` are passed in). Then use the fields in
  :func:`~geoddp.scene.build.build_problem` (the problem, once for both kinds) or
  :func:`~geoddp.scene.build.solver_options`. Both specs and both kinds' ``with_overrides`` take
  the new fields without further code.
* For one kind (``[model].robot``, ``package_dirs``, named postures under ``[initial]``): add the
  keys to that kind's ``SCHEMA`` and read them in its ``parse`` function next to the table's other
  keys; add a field to its spec and use it in its builder (``build._satellite`` / ``build._multibody``).
* Unknown keys, misplaced keys ("did you mean [horizon].dt?"), missing required keys and
  non-table tables are then reported by the reader without further code.
"""
from __future__ import annotations

from ..solver.options import (DEFAULT_EXPANSION, DEFAULT_GRAD_RTOL, DEFAULT_GRAD_TOL, DEFAULT_MAX_ITER, DEFAULT_RTOL,
                              DEFAULT_SWITCH_RATIO, EXPANSIONS)
from .build import AnySceneSpec, build_problem, frame_errors, initial_controls, solver_options, terminal_frame_errors
from .common import CommonSpec
from .legged import LeggedSceneSpec
from .load import SCENE_KINDS, load_scene, parse_scene
from .multibody import CostTermSpec, MultibodySceneSpec
from .reader import check_urdf, scene_file
from .satellite import ATTITUDE_KINDS, INTEGRATORS, SECOND_ORDER, SceneSpec
from .solve import solve_scene

__all__ = ["SceneSpec", "MultibodySceneSpec", "LeggedSceneSpec", "CostTermSpec", "CommonSpec", "AnySceneSpec", "SCENE_KINDS",
           "load_scene", "parse_scene", "solve_scene", "scene_file", "check_urdf", "build_problem", "solver_options",
           "initial_controls", "frame_errors", "terminal_frame_errors", "INTEGRATORS", "ATTITUDE_KINDS", "EXPANSIONS",
           "SECOND_ORDER", "DEFAULT_EXPANSION", "DEFAULT_GRAD_TOL", "DEFAULT_GRAD_RTOL", "DEFAULT_MAX_ITER",
           "DEFAULT_RTOL", "DEFAULT_SWITCH_RATIO"]
