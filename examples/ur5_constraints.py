"""
A UR5 reach with hard constraints
=================================

The UR5 reach of :doc:`ur5_reach` (``pip install 'geoddp[robots]'``) with three kinds of hard
constraint instead of weights: velocity limits of 0.7 rad/s on the shoulder pan and elbow joints
(the unconstrained plan peaks at 0.87 and 0.92 rad/s) besides the URDF's position limits, a
sphere of 6 cm radius that the tool frame ``tool0`` must stay out of, placed on the path the
unconstrained plan takes, and the tool's final pose reached exactly (a terminal
``frame_placement`` equality instead of a weight of 1e3). The scene is the built-in
``ur5_constraints`` (``examples/robots/ur5_constraints.toml``); the augmented Lagrangian outer loop
around the exact second-order DDP meets every constraint to 1e-8.
"""

# %%
# Solve, with and without the constraints
# ---------------------------------------
import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

from geoddp import load_scene, solve_scene
from geoddp.scene import build_problem

spec = load_scene("ur5_constraints")
result = solve_scene(spec)
free = solve_scene("ur5_reach")  # the same task, the pose by a weight, no limits, no obstacle
report = result.extra["constraints"]
opt = result.extra["optimality"]
print(result.status)
print(f"J* = {result.cost:.10f} in {report['outer_iterations']} outer and {result.iterations} inner iterations, "
      f"{1e3 * result.solve_time_s:.0f} ms (unconstrained: J* = {free.cost:.10f}, {free.iterations} iterations, "
      f"{1e3 * free.solve_time_s:.0f} ms)")
for item in report["items"]:
    print(f"  {item['name']:12s} ({item['type']}, {item['where']}): max violation {item['max_violation']:.1e}, "
          f"active at {item['active_nodes']} of {len(item['nodes'])} nodes")
print(f"KKT: violation {opt['constraint_violation']:.1e}, complementarity {opt['complementarity']:.1e}, "
      f"Lagrangian stationarity {opt['lagrangian_stationarity']:.1e}")
assert result.converged and report["max_violation"] <= 1e-8
assert opt["complementarity"] <= 1e-8 and opt["lagrangian_stationarity"] < 1e-6

# %%
# Check each constraint on the returned trajectory
# ------------------------------------------------
# Recomputed here with Pinocchio from ``result.q`` and ``result.v``, not read from the report.
model = build_problem(spec).problem.model.pin_model
data = model.createData()
tool = model.getFrameId("tool0")
(sphere,) = [c for c in spec.constraints if c.type == "frame_sphere_keep_out"]
(pose,) = [c for c in spec.terminal_constraints if c.type == "frame_placement"]


def tool_path(r):
    out = []
    for q in r.q:
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[tool].translation.copy())
    return np.array(out)


path, free_path = tool_path(result), tool_path(free)
distance = np.linalg.norm(path - sphere.centre, axis=1)
free_distance = np.linalg.norm(free_path - sphere.centre, axis=1)
pan, elbow = model.joints[model.getJointId("shoulder_pan_joint")].idx_v, model.joints[model.getJointId("elbow_joint")].idx_v
pin.framesForwardKinematics(model, data, result.q[-1])
pose_error = pin.log6(pin.SE3(pose.placement).actInv(data.oMf[tool])).vector
print(f"tool0's distance to the sphere's centre: at least {distance[1:].min():.10f} m (radius {sphere.radius} m; "
      f"unconstrained: {free_distance.min():.4f} m)")
print(f"joint speeds: pan {np.abs(result.v[:, pan]).max():.10f}, elbow {np.abs(result.v[:, elbow]).max():.10f} rad/s "
      f"(unconstrained {np.abs(free.v[:, pan]).max():.3f}, {np.abs(free.v[:, elbow]).max():.3f})")
print(f"final pose error |log6| = {np.linalg.norm(pose_error):.1e} (unconstrained plan: the weight leaves "
      f"{1e3 * np.linalg.norm(free_path[-1] - pose.placement[:3, 3]):.1f} mm)")
# the unconstrained plan breaks the limits and goes through the obstacle; the constrained one does not
assert free_distance.min() < 0.5 * sphere.radius and np.abs(free.v[:, [pan, elbow]]).max() > 0.85
assert np.all(distance[1:] >= sphere.radius - 1e-8)
assert np.abs(result.v[:, [pan, elbow]]).max() <= 0.7 + 1e-8
assert np.all(result.q >= model.lowerPositionLimit - 1e-8) and np.all(result.q <= model.upperPositionLimit + 1e-8)
assert np.linalg.norm(pose_error) <= 1e-8 * np.sqrt(6)

# %%
# The detour and the limits
# -------------------------
# The tool passes over the sphere and touches it (its path in the x-z and x-y planes, the sphere
# as its outline), and the pan and elbow joints run at their speed limit for much of the motion.
# (The task has a second local optimum passing under the sphere, J* = 0.91425, which a first
# penalty of 1e3 instead of 1e2 reaches: ``geoddp.constraints.ConstraintOptions``.)
fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
t = np.linspace(0.0, 2.0 * np.pi, 200)
for a, (i, j, label) in zip(ax[:2], [(0, 2, "z"), (0, 1, "y")]):
    a.plot(free_path[:, i], free_path[:, j], "--", color="tab:orange", label="unconstrained (ur5_reach)")
    a.plot(path[:, i], path[:, j], color="tab:blue", lw=2, label="constrained")
    a.fill(sphere.centre[i] + sphere.radius * np.cos(t), sphere.centre[j] + sphere.radius * np.sin(t),
           color="tab:red", alpha=0.3, label="obstacle")
    a.plot(*pose.placement[[i, j], 3], "ko", mfc="none", label="target")
    a.set(xlabel="x [m]", ylabel=f"{label} [m]", aspect="equal", title=f"tool0, x-{label} plane")
ax[0].legend(fontsize=7, loc="lower right")
for idx, name, color in [(pan, "shoulder pan", "tab:green"), (elbow, "elbow", "tab:purple")]:
    ax[2].plot(free.times, free.v[:, idx], "--", color=color, alpha=0.6)
    ax[2].plot(result.times, result.v[:, idx], color=color, label=name)
ax[2].axhspan(-0.7, 0.7, color="0.9")
ax[2].axhline(0.7, color="tab:red", lw=1)
ax[2].axhline(-0.7, color="tab:red", lw=1)
ax[2].set(xlabel="t [s]", ylabel="v [rad/s]", title="joint speeds (dashed: unconstrained)")
ax[2].legend(fontsize=8)
fig.tight_layout()

# %%
# ``geoddp run ur5_constraints --html ur5_constraints.html`` replays the motion with the sphere and
# the target pose drawn (:doc:`html_replay`).
