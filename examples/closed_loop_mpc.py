"""
Closed loop and MPC
===================

DDP returns a feedback policy, not only a trajectory: u = u_k - K_k zeta, with zeta the state's
tangent difference from the plan (on the satellite zeta = (log(R_k^T R), Omega - Omega_k)). Here
the plan of the authors' noise test (``satellite_authors_code``: Table I with their code's control
weight) is flown

1. on a plant whose inertia is 20 % larger than the plan's model: open loop, with the DDP gains,
   and with MPC (a re-solve from the measured state at every step, at most 3 iterations);
2. under noise on the angular velocity at every step, 90 seeded samples (the authors' test).
"""

# %%
# Model error
# -----------
import matplotlib.pyplot as plt

from geoddp import load_scene, solve_scene
from geoddp.scene import build_problem
from geoddp.simulate import SimulationSpec, simulate, simulate_scene

spec = load_scene("satellite_authors_code")
plan = solve_scene(spec)
problem = build_problem(spec)
plant = {"inertia_scale": 1.2}
runs = {
    "open": simulate(plan, problem, "open", plant=plant),
    "feedback": simulate(plan, problem, "feedback", plant=plant),
    "mpc": simulate(plan, problem, "mpc", plant=plant, horizon=100, max_iter=3, shrink=True),
}
for name, run in runs.items():
    print(f"{name:8s} terminal attitude error {run.errors['attitude_rad']:.2e} rad")
mpc = runs["mpc"].stats
print(f"MPC: {mpc['solves']} re-solves, {mpc['iterations_mean']:.2f} iterations on average, "
      f"median {1e3 * mpc['solve_median_s']:.2f} ms each")

# The gains and MPC end within 0.01 rad of the target; open loop misses by more than 0.15 rad.
assert runs["open"].errors["attitude_rad"] > 0.15
assert runs["feedback"].errors["attitude_rad"] < 0.01 and runs["mpc"].errors["attitude_rad"] < 0.01

fig, ax = plt.subplots(figsize=(6.5, 3.6))
for name, run in runs.items():
    ax.semilogy(run.times, run.target_error, label=name)
ax.set(xlabel="t [s]", ylabel="attitude error [rad]", title="inertia 20 % above the plan's model")
ax.legend()
fig.tight_layout()

# %%
# Noise: the authors' Monte Carlo test
# ------------------------------------
# N(0, 0.001^2) rad/s added to the body angular velocity after every step, 90 samples drawn from
# ``SeedSequence(0)``: the same table on every machine. The gains cut the mean terminal error
# about 84 times; the authors' own code reports about 4.45e-2 and 6.0e-4 rad.
mc = simulate_scene("satellite_authors_code", SimulationSpec(samples=90, seed=0, noise=0.001))
stats = mc.statistics()
open_mean, fb_mean = stats["open.attitude_rad.mean"], stats["feedback.attitude_rad.mean"]
print(f"mean terminal error: open loop {open_mean:.3e} rad, closed loop {fb_mean:.3e} rad")
assert open_mean > 20 * fb_mean and abs(fb_mean - 6.0e-4) < 6.0e-4

fig, ax = plt.subplots(1, 2, figsize=(11, 3.6), sharey=True)
for a, policy in zip(ax, ("open", "feedback")):
    for run in mc.runs[policy]:
        a.plot(run.times, run.target_error, color="C0" if policy == "open" else "C1", alpha=0.25, lw=0.8)
    a.plot(mc.plan_times, mc.plan_target_error, "k", lw=1.5, label="plan")
    a.set(xlabel="t [s]", title=f"{policy}: 90 noisy runs", yscale="log")
    a.legend()
ax[0].set_ylabel("attitude error [rad]")
fig.tight_layout()
