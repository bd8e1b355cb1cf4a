"""How long the core's idle workers poll before they sleep, interleaved in one process.

The compiled passes run on a persistent pool of workers (cpp/runtime/pool.hpp). A worker blocked on a
condition variable took 50-80 us to wake on the 2-core VM, and a DDP iteration calls the pool
several times, with sequential work (line-search rollouts, the backward pass, Python) between the
calls. After each task a worker therefore polls for up to GEODDP_SPIN_US microseconds before it
sleeps. This script times whole solves with several settings side by side: the setting changes
between solves (geoddp._core.set_spin_microseconds), rotating its order every round; medians.
Every setting must give the same iterations and bitwise the same J*: the script checks that.

``python benchmarks/pool_spin.py [--runs 30] [--spins 0 300 1000 5000] [--cases ur5 panda ...]``
Needs example-robot-data for the robots; no Crocoddyl. Compare only the ratios of one run.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import robots  # noqa: E402
from geoddp import kernels  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402

DEFAULT_CASES = ("ur5", "panda", "solo12", "hector", "spacecraft_docking", "space_manipulator", "quadrotor")
EXPANSIONS = ("first", "switch")


def row(case: robots.Case, expansion: str, spins: list[int], runs: int) -> str:
    """One table row: ms per solve for each setting and its ratio to the first."""
    p, opt, core = case.problem, SolverOptions(expansion=expansion, verbose=False), kernels.core
    times: dict[int, list[float]] = {s: [] for s in spins}
    results = {}
    for i in range(runs + 1):
        shift = i % len(spins)
        for s in spins[shift:] + spins[:shift]:
            core.set_spin_microseconds(s)
            r = solve(p, opt, initial_controls=case.U0)
            if i:
                times[s].append(r.solve_time_s)
                results.setdefault(s, r)
    first = results[spins[0]]
    for s, r in results.items():
        if r.iterations != first.iterations or r.cost != first.cost:
            raise SystemExit(f"{case.name} {expansion}: spin {s} gave {r.iterations} iterations, J* {r.cost!r}; "
                             f"spin {spins[0]} {first.iterations}, {first.cost!r}")
    med = {s: 1e3 * statistics.median(t) for s, t in times.items()}
    cells = " | ".join(f"{med[s]:.2f} ({med[s] / med[spins[0]]:.3f})" for s in spins)
    return f"| {case.name} | {expansion} | {first.iterations} | {cells} |"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--spins", type=int, nargs="+", default=[0, 300, 1000, 5000])
    ap.add_argument("--cases", nargs="*", default=list(DEFAULT_CASES), choices=list(robots.CASES))
    args = ap.parse_args(argv)
    core = kernels.core
    saved = core.spin_microseconds()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {robots.machine()}; "
          f"{core.default_threads()} workers; GEODDP_SPIN_US default {saved} us")
    print("\n| case | expansion | iterations | " + " | ".join(f"spin {s} us: ms / solve (ratio)" for s in args.spins) + " |")
    print("|---|---|---:|" + "---:|" * len(args.spins))
    try:
        for name in args.cases:
            case = robots.CASES[name]()
            for exp in EXPANSIONS:
                print(row(case, exp, list(args.spins), args.runs), flush=True)
    finally:
        core.set_spin_microseconds(saved)
    print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
