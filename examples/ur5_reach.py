"""
A UR5 reaching a pose
=====================

The UR5 arm of example-robot-data (``pip install 'geoddp[robots]'``), fixed base, gravity on, six
joint torques: from a bent posture at rest, its tool frame ``tool0`` reaches (0.30, 0.35, 0.25) m
pointing straight down in 1 s (50 steps of semi-implicit Euler) and stops there. The scene is the
built-in ``ur5_reach`` (``examples/robots/ur5_reach.toml``): the robot is named, not copied, and its
URDF and meshes are found in example-robot-data.
"""

# %%
# Load, solve, check
# ------------------
import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

from geoddp import load_scene, solve_scene
from geoddp.scene import build_problem, terminal_frame_errors

spec = load_scene("ur5_reach")
result = solve_scene(spec)
print(result.status)
print(f"J* = {result.cost:.12f} in {result.iterations} iterations, {1e3 * result.solve_time_s:.1f} ms")

# The terminal frame term's distance from its target: position and rotation.
(err,) = [e for e in terminal_frame_errors(spec, result.q[-1]) if e["frame"] == "tool0"]
print(f"tool0 ends {1e3 * err['position_error_m']:.1f} mm and {err['rotation_error_deg']:.3f} deg from the target")

assert result.converged and result.iterations == 6
assert abs(result.cost - 0.850648648465) < 1e-9 * result.cost
assert err["position_error_m"] < 5e-3 and err["rotation_error_deg"] < 0.05

# %%
# The motion
# ----------
# ``Result.q`` holds Pinocchio configurations (H+1, nq) and ``Result.v`` velocities (H+1, nv);
# the tool's path comes from Pinocchio's forward kinematics on the solved model.
model = build_problem(spec).model.pin_model
data = model.createData()
tool = model.getFrameId("tool0")
path = []
for q in result.q:
    pin.framesForwardKinematics(model, data, q)
    path.append(data.oMf[tool].translation.copy())
path = np.array(path)  # (H+1, 3) m

fig, ax = plt.subplots(1, 3, figsize=(12, 3.4))
names = [model.names[j] for j in range(1, model.njoints)]
ax[0].plot(result.times, result.q, label=names)
ax[0].set(xlabel="t [s]", ylabel="q [rad]", title="joint positions")
ax[0].legend(fontsize=7)
ax[1].step(result.times[:-1], result.controls, where="post")
ax[1].set(xlabel="t [s]", ylabel="torque [N m]", title="joint torques")
ax[2].plot(result.times, path, label=["x", "y", "z"])
ax[2].plot(np.full(3, result.times[-1]), [0.30, 0.35, 0.25], "ko", mfc="none", label="target")
ax[2].set(xlabel="t [s]", ylabel="[m]", title="tool0 position")
ax[2].legend(fontsize=8)
fig.tight_layout()

# %%
# The arm arrives at rest: the terminal velocity term leaves only a small residual speed.
print(f"final joint speed: {np.linalg.norm(result.v[-1]):.2e} rad/s")
assert np.linalg.norm(result.v[-1]) < 0.05
