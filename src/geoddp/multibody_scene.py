"""Old home of the multibody scene schema: now :mod:`geoddp.scene.multibody` (re-exported here)."""
from .scene.build import build_multibody_problem, terminal_frame_errors
from .scene.multibody import ACTUATION_TYPES, COST_TYPES, CostTermSpec, MultibodySceneSpec, parse_multibody_scene

__all__ = ["ACTUATION_TYPES", "COST_TYPES", "CostTermSpec", "MultibodySceneSpec", "build_multibody_problem",
           "parse_multibody_scene", "terminal_frame_errors"]
