"""The forward pass feeding the next first-order expansion: solves with the overlap on and off.

After a first-order linearisation, a compiled multibody problem's forward pass runs on the core's
first worker while the second expands (order 1) the nodes already written
(``geoddp._core.rollout_closed_loop_expanding``); the linearisation of the kept trial finishes the
rest. Both ways give the same bits (tests/test_core_overlap.py), so this times one binary, one
process, the two ways interleaved solve by solve: ``Problem.linearise`` is wrapped to clear the
problem's hint for the "off" runs. Prints medians and their ratio per case and expansion, and the
median share of nodes the second worker finished during the pass.

    python benchmarks/overlap.py [--runs 10] [--cases ur5 panda ...] [--expansions first switch]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import robots  # noqa: E402  (the cases: example-robot-data robots and the built-in scenes)

from geoddp.problem import Problem  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10, help="recorded rounds (after two warm-up rounds)")
    ap.add_argument("--cases", nargs="*", default=list(robots.CASES), choices=list(robots.CASES))
    ap.add_argument("--expansions", nargs="*", default=["first", "switch"], choices=["first", "second", "switch"])
    args = ap.parse_args(argv)
    original = Problem.linearise
    prefixes: list[float] = []

    def off(self, traj, order):
        lin = original(self, traj, order)
        self._first_order_next = False
        return lin

    def on(self, traj, order):
        if order == 1 and traj.precomputed is not None:
            prefixes.append(traj.precomputed[1] / self.horizon)
        return original(self, traj, order)

    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {robots.machine()}; load "
          f"{os.getloadavg()[0]:.2f}; medians of {args.runs} interleaved rounds", flush=True)
    print("| case | expansion | iterations | overlap on (ms) | off (ms) | on / off | nodes done during the pass |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name in args.cases:
        case = robots.CASES[name]()
        p, U0 = case.problem, case.U0
        for exp in args.expansions:
            opt = SolverOptions(expansion=exp, verbose=False)
            times: dict[str, list[float]] = {"on": [], "off": []}
            costs = {}
            prefixes.clear()
            for i in range(args.runs + 2):
                for mode, lin in (("on", on), ("off", off)):
                    Problem.linearise = lin
                    try:
                        r = solve(p, opt, initial_controls=U0)
                    finally:
                        Problem.linearise = original
                    costs[mode] = (r.cost, r.iterations)
                    if i >= 2:
                        times[mode].append(r.solve_time_s)
            if costs["on"] != costs["off"]:
                raise SystemExit(f"{name} {exp}: the overlap changed the solve: {costs}")
            a, b = statistics.median(times["on"]), statistics.median(times["off"])
            share = f"{100 * np.median(prefixes):.0f} %" if prefixes else "-"
            print(f"| {name} | {exp} | {costs['on'][1]} | {1e3 * a:.2f} | {1e3 * b:.2f} | {a / b:.3f} | {share} |",
                  flush=True)
    print(f"# {robots.machine()}; load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
