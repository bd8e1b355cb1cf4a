"""A Panda pose reach scene (example-robot-data, fixed base) written for the optimality tests."""
from __future__ import annotations

from pathlib import Path

SCENE = """name = "panda_reach"
[model]
kind = "multibody"
urdf = "{urdf}"
root = "fixed"
gravity = true
[horizon]
dt = 0.05
steps = 40
integrator = "{integrator}"
[[running_costs]]
type = "control"
weight = 1e-4
[[running_costs]]
type = "state_regularisation"
q_reference = "initial"
q_weight = 1e-4
v_weight = 1e-3
[[terminal_costs]]
type = "frame_placement"
frame = "panda_hand"
at_configuration = [0.5, -0.3, 0.2, -2.0, 0.3, 1.8, 0.5, 0.02, 0.02]
weight = 1e3
[[terminal_costs]]
type = "state_regularisation"
q_reference = "initial"
v_weight = 1.0
[initial]
q = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02]
[solver]
initial_controls = "hover"
{solver}
"""


def panda_scene(folder: Path, solver: str = "", integrator: str = "semi_implicit") -> Path:
    """Write the scene into ``folder`` (the URDF stays in example-robot-data) and return its path."""
    import example_robot_data

    urdf = Path(example_robot_data.load("panda").urdf).resolve()
    path = folder / "panda_reach.toml"
    path.write_text(SCENE.format(urdf=urdf, solver=solver, integrator=integrator))
    return path
