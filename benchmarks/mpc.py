"""Closed loop and MPC speed: per-step re-solve times, real-time factors, and the
90-sample Monte Carlo's wall time.

Cases:

* ``satellite``: the paper's scene (Table I, dt = 0.01 s), MPC with H_mpc = 100 re-solved every
  step for 300 steps (3 s) from the plan's start, at most ``--max-iter`` (3) iterations per
  re-solve, the plant = the model. Targets: median <= 1 ms and p95 <= 2 ms per re-solve (one
  core), i.e. >= 10x faster than real time.
* ``quadrotor``: the built-in quadrotor scene at 100 Hz (dt = 0.01 s, plan H = 300), MPC with
  H_mpc = 100 every step for 300 steps, the same iteration cap; beside it the same loop in
  Crocoddyl: ``SolverFDDP`` on a ``ShootingProblem`` of H_mpc semi-implicit Euler nodes built
  once from geoddp's problem by benchmarks/robots.py (C++ actuation models only), updated per
  step with ``problem.x0 = x`` and ``circularAppend`` (the window slides by one node), warm
  started from the previous solution shifted by one step with the last control repeated (the
  rule geoddp's MPC uses), the same iteration cap. Both fly the same plant (geoddp's
  :class:`~geoddp.simulate.Plant`), so both see the states their own controls produce. Target:
  geoddp's median <= 10 ms; the ratio geoddp / Crocoddyl is reported.
* ``montecarlo``: ``simulate_scene("satellite_authors_code", samples=90, noise=0.001)`` (open
  loop and feedback on the same noise), wall time with one process and with two (``workers=2``,
  forked); target < 2 s on 2 cores.

Timings taken on a shared machine are not valid: the lead times this on an idle machine.
Bench environment (crocoddyl 3.2.1, pin 4.0.0, example-robot-data):
``python benchmarks/mpc.py [--cases satellite quadrotor montecarlo] [--steps 300] [--max-iter 3]``;
without crocoddyl the Crocoddyl column is skipped with a note.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from geoddp.scene.builtin import scene_spec  # noqa: E402
from geoddp.problem import paper_problem  # noqa: E402
from geoddp.scene import build_problem  # noqa: E402
from geoddp.simulate import MPC, Plant, SimulationSpec, simulate, simulate_scene  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402


def summary(times: list[float], dt: float, every: int = 1) -> dict[str, float]:
    t = np.asarray(times)
    return {"median_ms": 1e3 * float(np.median(t)), "p95_ms": 1e3 * float(np.percentile(t, 95)),
            "max_ms": 1e3 * float(t.max()), "rtf": float(len(t) * every * dt / t.sum()), "solves": int(t.size)}


class CrocoddylMPC:
    """The same receding-horizon loop in Crocoddyl (module docstring), as a geoddp policy."""

    name = "crocoddyl"
    horizon = None

    def __init__(self, problem: Any, plan: Any, H_mpc: int, max_iter: int) -> None:
        import crocoddyl
        from robots import crocoddyl_problem

        p = self._window_problem(problem, H_mpc)
        self.shooting, _, _ = crocoddyl_problem(p)
        self.shooting.nthreads = 1
        self.node = self.shooting.runningModels[0]  # one time-invariant node, appended per step
        self.solver = crocoddyl.SolverFDDP(self.shooting)
        self.solver.th_stop = 1e-9
        self.H, self.max_iter = H_mpc, max_iter
        U = np.asarray(plan.controls)
        self.U0 = [u.copy() for u in np.vstack([U, np.repeat(U[-1:], max(0, H_mpc - len(U)), axis=0)])[:H_mpc]]
        self.nq = problem.model.nq
        self.reset()

    @staticmethod
    def _window_problem(problem: Any, H: int) -> Any:
        import copy

        p = copy.copy(problem)
        p.horizon = H
        return p

    def reset(self) -> None:
        self.times: list[float] = []
        self.iterations: list[int] = []
        self.us: list[np.ndarray] | None = None
        self.xs: list[np.ndarray] | None = None

    def control(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        x = np.concatenate([q, v])
        t0 = time.perf_counter()
        if self.us is None:
            us = [u.copy() for u in self.U0]
            self.shooting.x0 = x
            xs = self.shooting.rollout(us)
        else:
            # slide the window by one node and shift the warm start; the new last control repeats
            self.shooting.circularAppend(self.node, self.node.createData())
            self.shooting.x0 = x
            us = self.us[1:] + [self.us[-1].copy()]
            xs = [x] + self.xs[2:] + [self.xs[-1].copy()]
        self.solver.solve(xs, us, self.max_iter, False)
        self.times.append(time.perf_counter() - t0)
        self.iterations.append(int(self.solver.iter))
        self.us, self.xs = list(self.solver.us), list(self.solver.xs)
        return np.array(self.us[0])

    def stats(self) -> dict[str, Any]:
        return {"solve_times_s": list(self.times), "iterations": list(self.iterations)}


def satellite(steps: int, max_iter: int) -> dict[str, Any]:
    p = paper_problem()
    plan = solve(p, SolverOptions(verbose=False))
    mpc = MPC(p, horizon=100, every=1, max_iter=max_iter, plan=plan)
    simulate(plan, p, mpc, steps=20)  # warm-up (imports, allocations)
    s = simulate(plan, p, mpc, steps=steps)
    st = s.stats
    return {"geoddp": summary(st["solve_times_s"], p.dt), "iterations": st["iterations_mean"],
            "attitude_rad": s.errors["attitude_rad"]}


def quadrotor(steps: int, max_iter: int, H_mpc: int = 100) -> dict[str, Any]:
    spec = scene_spec("quadrotor", dt=0.01, horizon=300)
    p = build_problem(spec)
    plan = solve(p, SolverOptions(verbose=False), initial_controls=spec.initial_control_sequence())
    plant = Plant(p.model)
    mpc = MPC(p, horizon=H_mpc, every=1, max_iter=max_iter, plan=plan)
    simulate(plan, p, mpc, plant=plant, steps=10)  # warm-up
    s = simulate(plan, p, mpc, plant=plant, steps=steps)
    out: dict[str, Any] = {"geoddp": summary(s.stats["solve_times_s"], p.dt), "iterations": s.stats["iterations_mean"],
                           "position_m": s.errors["position_m"]}
    try:
        import crocoddyl  # noqa: F401
    except ImportError:
        out["crocoddyl"] = None
        return out
    croc = CrocoddylMPC(p, plan, H_mpc, max_iter)
    simulate(plan, p, croc, plant=plant, steps=10)
    sc = simulate(plan, p, croc, plant=plant, steps=steps)
    out["crocoddyl"] = summary(sc.stats["solve_times_s"], p.dt)
    out["crocoddyl_iterations"] = float(np.mean(sc.stats["iterations"]))
    out["crocoddyl_position_m"] = sc.errors["position_m"]
    return out


def montecarlo(workers: int) -> dict[str, Any]:
    spec = SimulationSpec(samples=90, seed=0, noise=0.001, workers=workers)
    simulate_scene("satellite_authors_code", SimulationSpec(samples=2, seed=0, noise=0.001))  # warm-up
    t0 = time.perf_counter()
    mc = simulate_scene("satellite_authors_code", spec)
    wall = time.perf_counter() - t0
    st = mc.statistics()
    return {"wall_s": wall, "runs_s": mc.wall_time_s, "open_mean": st["open.attitude_rad.mean"],
            "closed_mean": st["feedback.attitude_rad.mean"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="*", default=["satellite", "quadrotor", "montecarlo"],
                    choices=["satellite", "quadrotor", "montecarlo"])
    ap.add_argument("--steps", type=int, default=300, help="closed-loop steps per MPC case")
    ap.add_argument("--max-iter", type=int, default=3, help="iteration cap per re-solve")
    args = ap.parse_args(argv)
    import pinocchio as pin

    la = os.getloadavg()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; pin {pin.__version__}; {os.cpu_count()} cores, "
          f"load {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}; steps {args.steps}, max_iter {args.max_iter}", flush=True)
    rows = []
    if "satellite" in args.cases:
        r = satellite(args.steps, args.max_iter)
        g = r["geoddp"]
        rows.append(f"| satellite, H_mpc 100, dt 0.01 | geoddp | {g['median_ms']:.3f} | {g['p95_ms']:.3f} | "
                    f"{g['max_ms']:.3f} | {r['iterations']:.2f} | {g['rtf']:.1f} | |")
    if "quadrotor" in args.cases:
        r = quadrotor(args.steps, args.max_iter)
        g, c = r["geoddp"], r["crocoddyl"]
        ratio = f"{g['median_ms'] / c['median_ms']:.2f}" if c else "n/a"
        rows.append(f"| quadrotor, H_mpc 100, 100 Hz | geoddp | {g['median_ms']:.3f} | {g['p95_ms']:.3f} | "
                    f"{g['max_ms']:.3f} | {r['iterations']:.2f} | {g['rtf']:.1f} | {ratio} |")
        if c:
            rows.append(f"| quadrotor, H_mpc 100, 100 Hz | Crocoddyl FDDP, circularAppend, 1 thread | "
                        f"{c['median_ms']:.3f} | {c['p95_ms']:.3f} | {c['max_ms']:.3f} | "
                        f"{r['crocoddyl_iterations']:.2f} | {c['rtf']:.1f} | 1 |")
        else:
            rows.append("| quadrotor | Crocoddyl | (crocoddyl not installed) | | | | | |")
    if rows:
        print("| case | solver | median ms / re-solve | p95 ms | max ms | iterations (mean) | real-time factor | "
              "median ratio geoddp / Crocoddyl |")
        print("|---|---|---:|---:|---:|---:|---:|---:|")
        print("\n".join(rows))
    if "montecarlo" in args.cases:
        for workers in (1, 2):
            r = montecarlo(workers)
            print(f"\nMonte Carlo, satellite_authors_code, 90 samples x (open, feedback), noise 0.001 rad/s, "
                  f"{workers} process(es): {r['wall_s']:.2f} s (runs {r['runs_s']:.2f} s); mean terminal attitude "
                  f"error open {r['open_mean']:.3e} rad, closed {r['closed_mean']:.3e} rad")
    la = os.getloadavg()
    print(f"# load after {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
