"""Hard constraints on the state (path and terminal, equality and inequality), solved by an
augmented Lagrangian outer loop around the exact second-order DDP."""
from .kinds import (KINDS, Bound, Constraint, FrameHalfspace, FramePlacementConstraint, FrameSphereKeepOut,
                    JointLimits, PointingKeepOut, StateConstraint)

__all__ = ["KINDS", "Bound", "Constraint", "FrameHalfspace", "FramePlacementConstraint", "FrameSphereKeepOut",
           "JointLimits", "PointingKeepOut", "StateConstraint"]
