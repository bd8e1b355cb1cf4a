"""Hard constraints on the state (path and terminal, equality and inequality), solved by an
augmented Lagrangian outer loop around the exact second-order DDP.

    kinds.py       the constraint kinds: values, Jacobians and contracted Hessians on the group
    kinematics.py  frame kinematics with first and contracted second derivatives (Pinocchio)
    contact_forces.py  the friction cone on a legged problem's contact forces (state and controls)
    augmented.py   the PHR augmented Lagrangian terms and the inner problem that adds them
    problem.py     ConstrainedProblem (a problem, its constraints, ConstraintOptions)
    outer.py       solve_constrained: the outer loop, its statuses and the constraints' report

From Python::

    from geoddp.constraints import ConstrainedProblem, PointingKeepOut, solve_constrained
    cp = ConstrainedProblem(problem, [PointingKeepOut([1, 0, 0], d, 20.0)])
    result = solve_constrained(cp, SolverOptions(expansion="second"))
"""
from .augmented import AugmentedLagrangianProblem, Placed
from .contact_forces import FrictionCone
from .kinds import (KINDS, TERMINAL_ONLY, Bound, Constraint, FrameHalfspace, FramePlacementConstraint,
                    FrameSphereKeepOut, JointLimits, PointingKeepOut, StateConstraint)
from .outer import (CONSTRAINED_STATUSES, STATUS_INFEASIBLE, STATUS_INNER_FAILED, STATUS_KKT, STATUS_OUTER_MAX_ITER,
                    solve_constrained)
from .problem import ConstrainedProblem, ConstraintOptions

__all__ = ["KINDS", "TERMINAL_ONLY", "Bound", "Constraint", "FrameHalfspace", "FramePlacementConstraint",
           "FrameSphereKeepOut", "JointLimits", "PointingKeepOut", "StateConstraint", "FrictionCone", "AugmentedLagrangianProblem",
           "Placed", "ConstrainedProblem", "ConstraintOptions", "solve_constrained", "STATUS_KKT", "STATUS_INFEASIBLE",
           "STATUS_OUTER_MAX_ITER", "STATUS_INNER_FAILED", "CONSTRAINED_STATUSES"]
