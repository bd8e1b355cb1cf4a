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
import os
import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from geoddp.scene.legged import anymal_walk
from geoddp.solver import SolverOptions, solve
from geoddp.viz import export_legged_html, legged_forces, plot_legged

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
# :func:`geoddp.viz.legged_forces` re-evaluates every node along the solution: the forces of the
# feet on the ground at the contact nodes (N, world frame), the impulses of the feet that land at
# the impulse nodes (N s), the feet's positions and velocities, and m (a_com - g), which the forces
# sum to (Newton's law for the whole robot). Each stance foot stays where it landed (Baumgarte
# damping keeps its velocity near zero; semi-implicit Euler leaves it millimetres per second) and
# pushes on the ground; the swing foot follows its arc. The friction cone and f_z >= 0 are costs
# (Crocoddyl's quadratic barrier, weight 10), not constraints: a foot about to lift may pull by a
# fraction of a newton, and the force may leave the four-facet cone by as much.
forces = legged_forces(result, problem)
stance = forces.active & ~forces.impulse[:, None]
newton = np.abs(forces.total - forces.momentum_change).max()
speed = np.linalg.norm(forces.velocities[:-1], axis=-1)[stance].max()
T = (~forces.impulse).sum() * forces.dt
mean_fz = forces.dt * forces.total[~forces.impulse, 2].sum() / T
print(f"sum of the forces - m (a_com - g): {newton:.1e} N at most; mean vertical force {mean_fz:.2f} N, "
      f"weight {forces.mass * 9.81:.2f} N")
print(f"stance feet: speed {1e3 * speed:.2f} mm/s at most, smallest normal force {forces.normal[stance].min():.2f} N, "
      f"smallest margin to the 4-facet cone {forces.facet_margin[stance].min():.2f} N")
assert newton < 1e-9 * forces.mass * 9.81 and abs(mean_fz / (forces.mass * 9.81) - 1) < 2e-3
assert speed < 5e-3 and forces.normal[stance].min() > -1.0 and forces.facet_margin[stance].min() > -1.0

height = forces.positions[..., 2]
fig, ax = plt.subplots(figsize=(8, 3))
ax.plot(result.times, height - height[0], label=forces.feet)
ax.set(xlabel="t [s]", ylabel="height above start [m]", title="foot heights")
ax.legend(fontsize=7)
fig.tight_layout()

# %%
# Contact forces and friction-cone margins
# ----------------------------------------
# :func:`geoddp.viz.plot_legged` writes ``contact_forces.png`` (the total vertical force against
# m (a_com,z - g_z) and the weight; per foot its normal and tangential force, the impulse nodes
# dotted with the landing impulses written beside them) and ``friction_margin.png`` (per foot
# ``mu f_z - |f_t|`` and the four-facet margin, negative outside the cone);
# :func:`geoddp.viz.legged_figures` writes them with the joint, control and solver figures.
with tempfile.TemporaryDirectory() as tmp:
    figs = plot_legged(result, problem, tmp, forces=forces)
    images = {name: plt.imread(path) for name, path in figs.items()}
    if os.environ.get("GEODDP_WRITE_FIGURES"):  # the guide's copies
        for name, path in figs.items():
            shutil.copy(path, Path(__file__).resolve().parents[1] / "docs" / "figures" / f"legged_walk_{name}.png")
drawn = figs.data["contact_forces"].arrays
on = stance[:, 0]
assert np.array_equal(drawn["LF_FOOT/normal"][on], forces.forces[on, 0, 2])
for name, image in images.items():
    fig, ax = plt.subplots(figsize=(8, 11))
    ax.imshow(image)
    ax.axis("off")
    fig.tight_layout()

# %%
# Replay
# ------
# :func:`geoddp.viz.export_legged_html` writes the self-contained replay with the ground, a yellow
# sphere at each foot on the ground and the force arrows (blue, 1 mm per N; the landing impulses
# orange, 1 m per N s); :func:`geoddp.viz.replay_legged` shows the same in a live meshcat viewer.
# ANYmal's visual meshes make a 16 MB page (``max_mesh_mb=None``); its collision primitives, about 2 MB.
with tempfile.TemporaryDirectory() as tmp:
    page = export_legged_html(result, problem, Path(tmp) / "anymal_walk.html", geometry="collision")
    print(f"replay: {page.stat().st_size / 1e6:.1f} MB")
