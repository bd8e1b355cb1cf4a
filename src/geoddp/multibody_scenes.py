"""Old home of the built-in multibody scene builders: now :mod:`geoddp.scene.builtin` (re-exported here)."""
from .scene.builtin import (NAMES, hover_controls, quadrotor, scene_path, scene_spec, space_manipulator,
                            spacecraft_docking)

__all__ = ["NAMES", "hover_controls", "quadrotor", "scene_path", "scene_spec", "space_manipulator",
           "spacecraft_docking"]
