"""
A sweep: iterations over the slew angle
=======================================

``geoddp sweep`` (and :func:`geoddp.sweep.run_sweep`) solves many variations of one scene from a
sweep file: a grid over any scene key, seeded random draws, and optionally a closed-loop
simulation per case, serially, on a Dask ``LocalCluster`` (every core, on 127.0.0.1) or on a
running scheduler. Rows stream into Parquet part files, so a sweep interrupted can resume.

The built-in sweep ``satellite_slew`` (``examples/sweeps/satellite_slew.toml``) turns the paper's
satellite about its x axis by 10 to 180 degrees with each expansion: 54 cases. Serially here; on
a cluster nothing changes but ``workers=`` or ``scheduler=``.
"""

# %%
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from geoddp.sweep import load_sweep, read_table, run_sweep

sweep = load_sweep("satellite_slew")
with tempfile.TemporaryDirectory() as tmp:
    run = run_sweep(sweep, Path(tmp) / "slew", serial=True)
    table = read_table(Path(tmp) / "slew")
print(f"{run.solved} cases solved, {run.failed} failed, complete: {run.complete}")

# Every case converged; the three expansions agree on each angle's optimum, and the cost of the
# turn grows with its angle.
angle = "target.euler_intrinsic[0][1]"
assert run.complete and run.failed == 0 and len(table) == 54 and table["converged"].all()
J = table.pivot(index=angle, columns="solver.expansion", values="J")
assert ((J.max(axis=1) - J.min(axis=1)) <= 1e-9 * J.max(axis=1)).all()
assert (J["switch"].diff().dropna() > 0).all()
print(table.pivot(index=angle, columns="solver.expansion", values="iterations").T.to_string())

# %%
# A rest-to-rest turn about a principal axis stays a turn about that axis at every iterate, and
# the second-order terms act only on the other two axes, where nothing moves: the three
# expansions take the same steps here (the hard cases' 179-180 degree turns about x do the same).
#
# One row per case: the varied parameters by key path, the status, J*, the iterations, the solve
# time and the scene's terminal errors.
fig, ax = plt.subplots(1, 2, figsize=(11, 3.6))
for expansion, rows in table.groupby("solver.expansion"):
    rows = rows.sort_values(angle)
    ax[0].plot(rows[angle], rows["iterations"], "o-", label=expansion)
    ax[1].semilogy(rows[angle], rows["J"], "o-", label=expansion)
ax[0].set(xlabel="slew angle about x [deg]", ylabel="iterations", title="iterations to converge")
ax[1].set(xlabel="slew angle about x [deg]", ylabel="J*", title="optimal cost")
ax[0].legend()
fig.tight_layout()
