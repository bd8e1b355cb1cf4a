"""Compatibility name: the multibody problem is :class:`geoddp.problem.Problem` (issue 11)."""
from .problem import MultibodyProblem, Problem

__all__ = ["MultibodyProblem", "Problem"]
