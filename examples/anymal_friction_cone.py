"""
Contact forces as hard constraints: ANYmal trots on a slippery floor
======================================================================

Crocoddyl's trot keeps its contact forces near the friction cone with a penalty (a quadratic
barrier of weight 10 on a mu = 0.7 cone). On a floor with mu = 0.5 that plan slips: some stance
forces leave the cone by newtons. A ``friction_cone`` constraint makes the cone hard: the
augmented Lagrangian outer loop keeps every stance force inside the mu = 0.5 cone, with at least
5 N on each foot, to 1e-8 N, at a KKT point of the exact problem (the forces' first and second
derivatives come from the contact dynamics' KKT system).
"""

# %%
# The unconstrained trot and the constrained one
# -----------------------------------------------
# ``FrictionCone`` acts on the contact forces of a legged problem (``[[constraints]] type =
# "friction_cone"`` in a legged scene file does the same).
import matplotlib.pyplot as plt
import numpy as np

from geoddp import solve
from geoddp.constraints import STATUS_KKT, ConstrainedProblem, FrictionCone
from geoddp.scene.legged import anymal_trot
from geoddp.solver import SolverOptions
from geoddp.viz import legged_forces

MU, F_MIN = 0.5, 5.0
trot = anymal_trot()
free = solve(trot, SolverOptions(expansion="first"))
slippery = ConstrainedProblem(trot, [FrictionCone(mu=MU, min_normal_force=F_MIN)])
held = solve(slippery, SolverOptions(expansion="first"))
report = held.extra["constraints"]
print(f"unconstrained J* = {free.cost:.6f}; constrained J* = {held.cost:.6f} ({held.status})")
print(f"max violation {report['max_violation']:.1e} N after {report['outer_iterations']} outer and "
      f"{report['inner_iterations']} inner iterations")

# %%
# The margins to the mu = 0.5 cone
# --------------------------------
# The smallest margin of each stance foot to the cone's facets (negative: outside, the foot
# slips), before and after.
f_free, f_held = legged_forces(free, trot, mu=MU), legged_forces(held, trot, mu=MU)
stance = f_held.active & ~f_held.impulse[:, None]
fig, axes = plt.subplots(1, 2, figsize=(10, 3.5), sharey=True)
for ax, f, title in ((axes[0], f_free, "penalty only (Crocoddyl's trot)"), (axes[1], f_held, "friction_cone constraint")):
    for i, foot in enumerate(f.feet):
        m = np.where(stance[:, i], f.facet_margin[:, i], np.nan)
        ax.plot(f.times, m, label=foot)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_title(title)
    ax.set_xlabel("t [s]")
axes[0].set_ylabel(f"margin to the mu = {MU} cone [N]")
axes[1].legend(fontsize=8)
fig.tight_layout()
plt.show()

# %%
# The checks
# ----------
assert held.status == STATUS_KKT and report["max_violation"] <= 1e-8
assert np.nanmin(f_free.facet_margin[stance]) < -1.0  # the penalty's plan slips on this floor
assert np.nanmin(f_held.facet_margin[stance]) >= -1e-8  # the constrained one does not
assert np.nanmin(f_held.forces[..., 2][stance]) >= F_MIN - 1e-8
assert free.cost < held.cost
