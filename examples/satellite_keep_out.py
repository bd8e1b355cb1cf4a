"""
A keep-out cone
===============

The paper's satellite slew (Table I, explicit Euler, chordal cost) with an instrument that must
never point near the Sun: its body x axis stays at least 20 degrees from the world direction
(0.849, 0.482, 0.215) at every node. The unconstrained optimum passes straight through that
direction; the constrained one goes round the cone. The scene is the built-in
``satellite_keep_out`` (``examples/satellite_keep_out.toml``: ``satellite_paper.toml`` plus a
``[[constraints]]`` table), solved by the augmented Lagrangian outer loop around the exact
second-order DDP.
"""

# %%
# Solve with and without the cone
# -------------------------------
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from geoddp import solve_scene
from geoddp.problem import paper_problem
from geoddp.solver import SolverOptions, solve
from geoddp.viz import plot_keep_out

result = solve_scene("satellite_keep_out", expansion="second")
free = solve(paper_problem(), SolverOptions(expansion="second"))
report = result.extra["constraints"]
(cone,) = report["items"]
print(result.status)
print(f"J* = {result.cost:.10f} (unconstrained {free.cost:.10f})")
print(f"{report['outer_iterations']} outer, {report['inner_iterations']} inner iterations; "
      f"max violation {report['max_violation']:.1e} (tol {report['constraint_tol']:.0e}); "
      f"cone active at {cone['active_nodes']} of {len(cone['nodes'])} nodes")

# %%
# The angle between the boresight R_k a and the direction d at every node k = 1..H: the cone holds
# everywhere to the constraint tolerance (in cosine units: 1e-8 in the cosine is 1.7e-6 degrees at 20
# degrees), and the unconstrained slew enters it. IPOPT, solving the same discrete problem with
# an exact Hessian (``benchmarks/keep_out_ipopt.py``), finds J = 908.7470222464; the difference
# is the tolerance's (the boresight may enter the cone by 1e-8 in cosine).
a = np.array([1.0, 0.0, 0.0])
d = np.array([0.849, 0.482, 0.215])
d /= np.linalg.norm(d)


def angles_deg(r):
    return np.degrees(np.arccos(np.clip(r.rotations @ a @ d, -1.0, 1.0)))


angle, free_angle = angles_deg(result), angles_deg(free)
print(f"smallest angle: {angle[1:].min():.7f} deg constrained, {free_angle[1:].min():.4f} deg unconstrained")
assert result.converged and report["max_violation"] <= 1e-8
assert np.all(np.cos(np.radians(angle[1:])) - np.cos(np.radians(20.0)) <= 1e-8)
assert free.converged and free_angle.min() < 1.0
assert abs(result.cost - 908.7470222464) < 1e-8 * 908.75
assert result.extra["optimality"]["lagrangian_stationarity"] < 1e-6

# %%
# The keep-out figure
# -------------------
# :func:`geoddp.viz.plot_keep_out` draws the boresight on the unit sphere with the cone (left) and
# the angle against time (right), here with the unconstrained path dashed. It writes a PNG; the
# arrays it drew come back in ``FigureData.arrays``.
with tempfile.TemporaryDirectory() as tmp:
    fd = plot_keep_out(result, Path(tmp) / "keep_out.png", unconstrained=free)
    image = plt.imread(fd.path)
assert np.allclose(fd.arrays["angle_deg"], angle, atol=1e-9)
fig, ax = plt.subplots(figsize=(11, 5))
ax.imshow(image)
ax.axis("off")
fig.tight_layout()
