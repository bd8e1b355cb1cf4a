"""
Talos walks on flat feet: 6D contacts
=====================================

Crocoddyl's biped walk (its example bipedal_gaits_fwddyn.py, ``SimpleBipedGaitProblem``), node for
node, on Talos' legs: from "half_sitting" at rest, both soles on the ground as **6D contacts** (a flat
foot: its whole placement held, the ground pushing with a force and a torque; Baumgarte gains
(0, 30)), 4 support knots, the right foot's 0.3 m half step, 4 support knots, the left foot's 0.6 m
step, each 15 knots of 0.03 s, each landing an impulse node; the left foot's landing ends the walk
(39 nodes, 12 joint torques, the base unactuated). The swing foot tracks its placement (position and
orientation), each stance foot's wrench is kept in the wrench cone of a 0.1 x 0.05 m sole. The robot
comes from example-robot-data (``pip install 'geoddp[robots]'``).
"""

# %%
# Build and solve
# ---------------
# ``talos_walk()`` builds the schedule and Crocoddyl's biped costs (the built-in scene
# ``talos_walk`` is the same problem: ``geoddp run talos_walk``); the solver starts from Crocoddyl's
# quasi-static controls. The first-order expansion is FDDP's model; Crocoddyl's FDDP reaches the same
# J* (tests/test_contact6d_crocoddyl.py checks it to 1e-9 relative).
import os
import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from geoddp.scene.legged import talos_walk
from geoddp.solver import SolverOptions, solve
from geoddp.viz import export_legged_html, legged_forces, plot_legged

problem = talos_walk()
J0 = problem.trajectory_cost(problem.trajectory(problem.quasi_static_controls()))
result = solve(problem, SolverOptions(expansion="first"))
print(result.status)
print(f"J = {J0:.1f} at the start, J* = {result.cost:.9f} after {result.iterations} iterations, "
      f"||dJ/dU|| = {result.grad_norm:.1e}")
assert result.converged and abs(result.cost - 5111.964479134) < 1e-6 * result.cost  # FDDP's J*
assert result.iterations <= 25  # 17 here

# %%
# Feet, forces and centres of pressure
# ------------------------------------
# :func:`geoddp.viz.legged_forces` re-evaluates every node along the solution. A flat foot carries a
# torque about its sole frame's origin besides the force; ``cop`` is where the force acts on the
# ground, (-tau_y, tau_x) / f_z from that origin. The wrench cone asks for it inside the sole (x
# within 0.05 m of the sole frame's origin, y within 0.025 m), but as a cost (Crocoddyl's quadratic
# barrier, weight 10), not a constraint: through most of the walk it sits at the sole's toe or heel
# edge, and while a foot unloads in double support it passes the edge by up to 33 mm (a foot about
# to lift, carrying a few newtons, has an ill-defined one: left out below). The forces sum to m (a_com - g) as
# Newton's law wants. The swing feet rise about 3 cm, not the 0.1 m of their targets: in Crocoddyl's
# costs the placement tracking trades against the posture's (FDDP lands at the same J*). Each foot
# lands where its arc's last target is, 1.3 cm up, and stays there: a contact holds the sole's
# acceleration, and with Kp = 0 nothing pulls it down to the ground (it drifts by 3 mm).
forces = legged_forces(result, problem)
stance = forces.active & ~forces.impulse[:, None]
newton = np.abs(forces.total - forces.momentum_change).max()
loaded = stance & (np.nan_to_num(forces.normal) > 0.05 * forces.mass * 9.81)  # more than 5% of the weight
cop = np.abs(forces.cop[loaded])
speed = np.linalg.norm(forces.velocities[:-1], axis=-1)[stance].max()
print(f"sum of the forces - m (a_com - g): {newton:.1e} N at most; robot {forces.mass:.2f} kg")
print(f"loaded stance feet: |cop x| <= {cop[:, 0].max() * 1e3:.1f} mm, |cop y| <= {cop[:, 1].max() * 1e3:.1f} mm "
      f"(sole: 50 mm, 25 mm); stance feet slide {speed * 1e3:.1f} mm/s at most")
print(f"swing feet rise {forces.positions[..., 2].max() * 1e2:.1f} cm; the left foot lands "
      f"{forces.positions[-1, 1, 0] - forces.positions[0, 1, 0]:.3f} m ahead")
assert newton < 1e-9 * forces.mass * 9.81
assert cop[:, 0].max() < 0.05 + 0.04 and cop[:, 1].max() < 0.025 + 0.015 and speed < 0.05  # 83 mm, 34 mm, 15 mm/s

t = result.times
fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
axes[0].plot(t, forces.positions[..., 2] * 1e2, label=forces.feet)
axes[0].set(ylabel="height [cm]", title="sole heights")
fz = np.where(stance, forces.normal, np.nan)
axes[1].plot(t[:-1], fz, label=forces.feet)
axes[1].axhline(forces.mass * 9.81, color="0.5", linewidth=1.0, label="weight")
axes[1].set(ylabel="f_z [N]", title="normal forces (contact nodes)")
cx = np.where(loaded, forces.cop[..., 0], np.nan)
axes[2].plot(t[:-1], cx * 1e3, label=forces.feet)
axes[2].axhspan(-50, 50, color="tab:green", alpha=0.1, label="sole")
axes[2].set(xlabel="t [s]", ylabel="x [mm]", title="centre of pressure along the sole (loaded feet)")
for ax in axes:
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
fig.tight_layout()

# %%
# Contact forces and friction margins
# -----------------------------------
# :func:`geoddp.viz.plot_legged` draws the same figures as for ANYmal from the soles' forces (their
# torques aside): ``contact_forces.png`` and ``friction_margin.png`` (the friction-cone margins of
# the force; the wrench cone's friction rows take the inner four-facet cone, mu cos(pi/4)).
with tempfile.TemporaryDirectory() as tmp:
    figs = plot_legged(result, problem, tmp, forces=forces)
    images = {name: plt.imread(path) for name, path in figs.items()}
    if os.environ.get("GEODDP_WRITE_FIGURES"):  # the guide's copies
        for name, path in figs.items():
            shutil.copy(path, Path(__file__).resolve().parents[1] / "docs" / "figures" / f"talos_walk_{name}.png")
for name, image in images.items():
    fig, ax = plt.subplots(figsize=(8, 6))
    ax.imshow(image)
    ax.axis("off")
    fig.tight_layout()

# %%
# Replay
# ------
# :func:`geoddp.viz.export_legged_html` writes the self-contained replay: the ground, a sphere at each
# sole on the ground and the force arrows (1 mm per N); example-robot-data's talos_legs is Talos cut
# to its legs, so the replay draws the legs' visual meshes (about 2 MB of page).
with tempfile.TemporaryDirectory() as tmp:
    page = export_legged_html(result, problem, Path(tmp) / "talos_walk.html")
    print(f"replay: {page.stat().st_size / 1e6:.1f} MB")
