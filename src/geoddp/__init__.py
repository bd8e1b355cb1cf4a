"""geoddp: Differential Dynamic Programming on Lie groups over Pinocchio.

The public facade (nothing inside the package imports it)::

    solve_scene(scene, **options) -> Result    a scene file, a built-in scene's name or a spec
    load_scene(scene) -> spec                  read and validate a scene without solving it
    solve(problem, options, initial_controls)  Algorithm 1 on any Problem
    Problem, SolverOptions, Result             the problem, the solver's options, its result

The layers underneath, each importing only from those below it: :mod:`geoddp.validate`,
:mod:`geoddp.lie`, :mod:`geoddp.models`, :mod:`geoddp.costs`, :mod:`geoddp.problem`,
:mod:`geoddp.solver`, :mod:`geoddp.scene`, :mod:`geoddp.simulate`, :mod:`geoddp.sweep`,
:mod:`geoddp.viz` and the command line :mod:`geoddp.cli`.
"""
from .problem import Problem
from .scene import load_scene, solve_scene
from .solver import SolverOptions, solve
from .solver.result import Result

__all__ = ["solve", "solve_scene", "load_scene", "Problem", "SolverOptions", "Result", "__version__"]
__version__ = "0.1.0"
