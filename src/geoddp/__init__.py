"""geoddp: Differential Dynamic Programming on Lie groups over Pinocchio.

The public facade: :func:`solve_scene` (a scene file or built-in name in, a :class:`Result` out),
:func:`load_scene`, and for problems built in Python :class:`Problem`, :func:`solve` and
:class:`SolverOptions`.
"""
from .api import solve_scene
from .problem import Problem
from .result import Result
from .scene import load_scene
from .solver import SolverOptions, solve

__all__ = ["Problem", "Result", "SolverOptions", "load_scene", "solve", "solve_scene"]
__version__ = "0.1.0"
