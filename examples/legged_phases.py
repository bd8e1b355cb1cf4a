"""
A contact schedule of one's own: ANYmal takes three trot steps
===============================================================

A legged scene file (``[model] kind = "legged"``) names the robot (example-robot-data's ANYmal,
``pip install 'geoddp[robots]'``), its feet, the contact nodes' time step and Baumgarte gains, and
the schedule: here ``[[phases]]``, each the feet on the ground for some knots and, for the feet
that swing, a step (length along x, height of the arc). A swing foot that is down in the next
phase lands by an impulse node. The costs are Crocoddyl's quadruped gait costs. The built-in
scenes ``anymal_walk``, ``anymal_trot`` and ``anymal_jump`` are Crocoddyl's gaits written with a
``[gait]`` table instead (``geoddp run anymal_trot``).
"""

# %%
# The scene file
# --------------
# A half step of the right front and left hind feet, a full step of the other diagonal pair, a
# half step of the first pair to bring the feet together again, with two-knot four-foot support
# between the steps: 75 nodes, three of them touch-down impulses.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import geoddp

FOUR = '["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]'
SCENE = f"""
name = "anymal_three_steps"
[model]
kind = "legged"
robot = "anymal"
feet = {FOUR}
posture = "standing"

[contact]
dt = 0.01
baumgarte = [0.0, 50.0]

[[phases]]
contacts = {FOUR}
knots = 4
[[phases]]
contacts = ["LF_FOOT", "RH_FOOT"]     # RF and LH swing: a half step
knots = 20
step_length = 0.05
step_height = 0.08
[[phases]]
contacts = {FOUR}                     # RF and LH are down again: their impulse node came first
knots = 2
[[phases]]
contacts = ["RF_FOOT", "LH_FOOT"]
knots = 20
step_length = 0.1
step_height = 0.08
[[phases]]
contacts = {FOUR}
knots = 2
[[phases]]
contacts = ["LF_FOOT", "RH_FOOT"]
knots = 20
step_length = 0.05
step_height = 0.08
[[phases]]
contacts = {FOUR}
knots = 4

[solver]
expansion = "first"                   # Gauss-Newton cost Hessians, as Crocoddyl's FDDP
"""

# %%
# Solve
# -----
# ``geoddp.solve_scene`` reads, builds and solves it (the same as ``geoddp run FILE --json
# OUT.json``); the start is Crocoddyl's quasi-static controls.
folder = Path(tempfile.mkdtemp())
path = folder / "anymal_three_steps.toml"
path.write_text(SCENE)
result = geoddp.solve_scene(path)
print(result.status)
print(f"J* = {result.cost:.6f} after {result.iterations} iterations")
assert result.converged

# %%
# The result and its schedule
# ---------------------------
# The result JSON has configurations (H+1, 19), velocities (H+1, 18), controls (H, 12) with zero
# rows at the impulse nodes, and the contact schedule under ``model.contact_schedule``: per node
# the feet on the ground (at an impulse node, the feet that touch down) and which nodes are
# impulses.
saved = geoddp.Result.read_json(result.write_json(folder / "three_steps.json"))
schedule = saved.model["contact_schedule"]
contact, impulse = np.array(schedule["contact"]), np.array(schedule["impulse"])
print(f"{len(impulse)} nodes, impulses at nodes {np.flatnonzero(impulse).tolist()}")
assert saved.controls.shape == (75, 12) and np.all(saved.controls[impulse] == 0.0)

import pinocchio as pin  # noqa: E402  (the feet's heights from the configurations)

model = pin.buildModelFromXML(saved.model["urdf_xml"], pin.JointModelFreeFlyer())
data = model.createData()
ids = [model.getFrameId(f) for f in schedule["feet"]]
height = np.array([[(pin.framesForwardKinematics(model, data, q), data.oMf[i].translation[2])[1] for i in ids]
                   for q in saved.configurations])
fig, ax = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
ax[0].plot(saved.times, height - height[0], label=schedule["feet"])
ax[0].set(ylabel="height above start [m]", title="foot heights")
ax[0].legend(fontsize=7, ncol=4)
ax[1].imshow(contact.T, aspect="auto", cmap="Greys", interpolation="nearest",
             extent=(saved.times[0], saved.times[-1], len(ids) - 0.5, -0.5))
ax[1].vlines(saved.times[:-1][impulse], -0.5, len(ids) - 0.5, colors="tab:red", label="impulse nodes")
ax[1].set(yticks=range(len(ids)), yticklabels=schedule["feet"], xlabel="t [s]", title="contact schedule")
ax[1].legend(fontsize=7, loc="upper right")
fig.tight_layout()
