"""Cost terms: each term evaluates on all N nodes at once and adds its value, left-trivialised
gradient and (0)-Hessian (paper eqs. leftell, trivdif) into a :class:`CostDerivatives`.

    tso3.py       terms on TSO(3) x R^m (the satellite's closed forms): attitude (chordal or
                  geodesic), angular velocity, control; :class:`CostSum`
    multibody.py  terms on a Pinocchio multibody's states: frame placement, rotation and
                  translation, state and control regularisation; :class:`MultibodyCostSum`
                  (every term in one compiled call)

Both modules' public names are importable from here.
"""
from .multibody import (
    ControlRegularisation,
    FramePlacement,
    FrameRotation,
    FrameRotationChordal,
    FrameTranslation,
    MultibodyCostSum,
    MultibodyCostTerm,
    StateRegularisation,
    tracking_costs,
)
from .tso3 import (
    AngularVelocityQuadratic,
    AttitudeChordal,
    AttitudeGeodesic,
    ControlQuadratic,
    CostDerivatives,
    CostSum,
    CostTerm,
)

__all__ = ["AngularVelocityQuadratic", "AttitudeChordal", "AttitudeGeodesic", "ControlQuadratic", "CostDerivatives",
           "CostSum", "CostTerm", "ControlRegularisation", "FramePlacement", "FrameRotation", "FrameRotationChordal",
           "FrameTranslation", "MultibodyCostSum", "MultibodyCostTerm", "StateRegularisation", "tracking_costs"]
