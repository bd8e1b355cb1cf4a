"""
Control limits
==============

Reaction wheels saturate. The paper's manoeuvre with every wheel limited to ``|u_i| <= 5`` N m (the
built-in scene ``satellite_wheel_limits``: Table I plus a ``[limits]`` table), then the same
problem built in Python with tighter limits, ``|u_i| <= 3`` N m.

Each backward pass solves a box-constrained QP per node (projected Newton), the forward pass
clamps after the feedback law, so every iterate stays inside the box, and the result reports
which inputs sit on a bound and the KKT residual (the largest projected gradient).
"""

# %%
# From a scene file
# -----------------
import matplotlib.pyplot as plt
import numpy as np

from geoddp import SolverOptions, solve, solve_scene
from geoddp.problem import paper_problem

result = solve_scene("satellite_wheel_limits")
lower, upper = result.limits                      # each (H, m), N m
opt = result.extra["optimality"]
on_bound = (result.active_set != 0).sum(axis=0)   # nodes on a bound, per input
print(result.status)
print(f"J* = {result.cost:.10f}, {result.iterations} iterations, KKT residual {opt['kkt_residual']:.1e}")
print(f"(node, input) pairs on a bound: {opt['active_inputs']} of {result.controls.size}; per input {on_bound}")

# The unconstrained optimum peaks at about 3.0, 2.8 and 8.9 N m: only the third wheel saturates.
assert result.converged and abs(result.cost - 609.5420669) < 1e-6
assert np.all(result.controls >= lower) and np.all(result.controls <= upper)
assert list(on_bound) == [0, 0, 210] and opt["kkt_residual"] < 1e-8

# %%
# From Python, tighter
# --------------------
# ``paper_problem`` builds Table I in code; ``limits`` takes a scalar, one bound per input (m,)
# or one row per node (H, m), with -inf / inf for an open side. With 3 N m all three wheels
# saturate, the second one too although its unconstrained peak is below 3.
tight = solve(paper_problem(limits=(-3.0, 3.0)), SolverOptions(expansion="switch"))
print(tight.status, f"J* = {tight.cost:.9f}", (tight.active_set != 0).sum(axis=0))
assert tight.converged and abs(tight.cost - 1392.846355) < 1e-5
assert np.abs(tight.controls).max() <= 3.0 and np.all((tight.active_set != 0).sum(axis=0) > 0)

# %%
# The torques against their bounds
# --------------------------------
fig, ax = plt.subplots(1, 2, figsize=(11, 3.6), sharey=True)
for a, r, bound in ((ax[0], result, 5.0), (ax[1], tight, 3.0)):
    a.step(r.times[:-1], r.controls, where="post", label=["u_1", "u_2", "u_3"])
    a.axhline(bound, color="grey", ls="--")
    a.axhline(-bound, color="grey", ls="--")
    a.set(xlabel="t [s]", title=f"|u_i| <= {bound:g} N m: J* = {r.cost:.2f}")
ax[0].set_ylabel("u [N m]")
ax[0].legend(fontsize=8)
fig.tight_layout()
