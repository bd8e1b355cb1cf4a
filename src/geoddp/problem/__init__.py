"""The problem layer: what the solver solves, and the contract it solves it through.

    problem.py   :class:`Problem` (a model, running and terminal costs, a horizon, an initial
                 state, optional control limits; paper eq. optprob), :func:`satellite_problem`,
                 :func:`paper_problem`
    contract.py  the contract between a problem and the solver: :class:`OptimalControlProblem`,
                 :class:`Trajectory`, :class:`Linearisation` (it imports nothing else from geoddp)
    limits.py    control limits: :class:`ControlLimits`, the box arithmetic the solver uses

``from geoddp.problem import Problem, paper_problem, satellite_problem`` is the public route.
"""
from .contract import Linearisation, OptimalControlProblem, Trajectory
from .limits import ControlLimits
from .problem import ATTITUDE_KINDS, Problem, paper_problem, satellite_problem

__all__ = ["ATTITUDE_KINDS", "ControlLimits", "Linearisation", "OptimalControlProblem", "Problem", "Trajectory",
           "paper_problem", "satellite_problem"]
