"""Solve time of the three real-robot examples (``ur5_reach``,
``solo12_reorient``, ``hector_fly``), as ``geoddp run NAME`` solves them.

One warm-up solve per example, then ``--runs`` rounds interleaved over the examples; reported per
example: J*, iterations, status, and the median / min of ``Result.solve_time_s`` (wall time of
the solve, including the final optimality check), with the machine's load average. These are
the numbers of the robots guide's table (docs/guide/robots.md):
``python benchmarks/robot_examples.py [--runs 5]`` (needs example-robot-data: the ``robots`` extra).
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from geoddp import solve_scene
from geoddp.scene import load_scene

EXAMPLES = ("ur5_reach", "solo12_reorient", "hector_fly")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="recorded rounds (after one warm-up solve each)")
    args = ap.parse_args(argv)
    specs = {n: load_scene(n) for n in EXAMPLES}
    last, times = {}, {n: [] for n in EXAMPLES}
    for i in range(args.runs + 1):
        for n in EXAMPLES:
            r = solve_scene(specs[n], verbose=False)
            last[n] = r
            if i:
                times[n].append(r.solve_time_s)
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {os.cpu_count()} cores, load average "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print("| example | J* | iterations | status | solve time median (min) |")
    print("|---|---:|---:|---|---:|")
    for n in EXAMPLES:
        r = last[n]
        print(f"| {n} | {r.cost:.12g} | {r.iterations} | {r.status.split(':')[0]} | "
              f"{statistics.median(times[n]):.3f} s ({min(times[n]):.3f} s) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
