"""
ANYmal walks: contact and impulse dynamics
==========================================

Crocoddyl's ANYmal walk (its example quadrupedal_gaits_fwddyn.py), node for node: from "standing"
at rest, each leg in turn (right hind, right front half steps, then left hind, left front full
steps) swings 0.15 m high while the other three stand on rigid point contacts (Baumgarte gains
(0, 50)); every touch-down is an impulse node. 108 nodes of 0.01 s, 12 joint torques, the base
unactuated. The robot comes from example-robot-data (``pip install 'geoddp[robots]'``).
"""

# %%
# Build and solve
# ---------------
# ``anymal_walk()`` builds the schedule and Crocoddyl's costs; the solver starts from Crocoddyl's
# quasi-static controls (those that hold the posture on the feet in contact). The first-order
# expansion is FDDP's model (Gauss-Newton cost Hessians); the end point is checked with the exact
# second-order one.
import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

from geoddp.scene.legged import anymal_walk
from geoddp.solver import SolverOptions, solve

problem = anymal_walk()
J0 = problem.trajectory_cost(problem.trajectory(problem.quasi_static_controls()))
result = solve(problem, SolverOptions(expansion="first"))
print(result.status)
print(f"J = {J0:.1f} at the start, J* = {result.cost:.6f} after {result.iterations} iterations, "
      f"||dJ/dU|| = {result.grad_norm:.1e}")
assert result.converged and result.cost < 1e-3 * J0  # certified by the exact second-order check

# %%
# Feet and forces
# ---------------
# Each stance foot stays where it landed (Baumgarte damping keeps its velocity at zero; it moves
# under 0.05 mm per step) and pushes on the ground; the swing foot follows its arc. The friction
# cone and f_z >= 0 are costs (Crocoddyl's quadratic barrier, weight 10), not constraints: a foot
# about to lift may pull by a fraction of a newton.
model, data = problem.model, problem.model.createData()
names = ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"]
ids = [model.getFrameId(n) for n in names]
height = np.empty((problem.horizon + 1, 4))
for k, q in enumerate(result.q):
    pin.framesForwardKinematics(model, data, q)
    height[k] = [data.oMf[f].translation[2] for f in ids]
fz = np.full((problem.horizon, 4), np.nan)
slide = 0.0
for k, node in enumerate(problem.nodes):
    if node.kind != "contact":
        continue
    ev = problem.node(k, result.q[k], result.v[k], result.controls[k])[0]
    for i, f in enumerate(node.feet):
        fz[k, ids.index(f)] = ev.forces[3 * i + 2]
        pin.framesForwardKinematics(model, data, result.q[k])
        p = data.oMf[f].translation.copy()
        pin.framesForwardKinematics(model, data, result.q[k + 1])
        slide = max(slide, np.linalg.norm(data.oMf[f].translation - p))
print(f"largest stance-foot motion in one step: {1e3 * slide:.4f} mm; smallest normal force {np.nanmin(fz):.1f} N")
assert slide < 5e-5 and np.nanmin(fz) > -1.0

fig, ax = plt.subplots(1, 2, figsize=(11, 3.4))
ax[0].plot(result.times, height - height[0], label=names)
ax[0].set(xlabel="t [s]", ylabel="height above start [m]", title="foot heights")
ax[0].legend(fontsize=7)
ax[1].plot(result.times[:-1], fz, label=names)
ax[1].set(xlabel="t [s]", ylabel="f_z [N]", title="normal contact forces")
fig.tight_layout()
