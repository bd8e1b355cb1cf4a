"""What the public route costs on top of the solve (the guard: at most 10 %).

Three ways to solve the same scene, interleaved round by round (the machine is shared and noisy;
a ratio measured side by side is what counts):

* ``solve``       : ``geoddp.solver.solve(problem, options)`` on a problem built once;
* ``solve_scene`` : ``geoddp.solve_scene(spec)`` on a spec loaded once (validates, builds the
  problem and assembles the Result on every call);
* ``from file``   : ``geoddp.solve_scene(path)`` (also reads and parses the TOML).

Usage: python benchmarks/api_overhead.py [--rounds 15] [SCENE ...]   (default: the paper's
satellite in its semi-implicit, geodesic variant and the quadrotor)
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

from geoddp import load_scene, solve_scene
from geoddp.scene import initial_controls
from geoddp.scene import build_problem, solver_options
from geoddp.solver import solve

DEFAULT_SCENES = ("satellite_semi_implicit", "quadrotor")


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def measure(scene: str, rounds: int) -> dict[str, float]:
    """Median seconds per call of the three routes on ``scene`` (a name or a path)."""
    spec = load_scene(scene)
    problem = build_problem(spec)
    options = solver_options(spec, verbose=False)
    U0 = initial_controls(spec)
    routes = {
        "solve": lambda: solve(problem, options, initial_controls=U0),
        "solve_scene": lambda: solve_scene(spec, verbose=False),
        "from file": lambda: solve_scene(scene, verbose=False),
    }
    for fn in routes.values():  # warm-up: imports, first allocations
        fn()
    times: dict[str, list[float]] = {k: [] for k in routes}
    names = list(routes)
    for r in range(rounds):
        for name in names[r % 3:] + names[: r % 3]:  # rotate the order: no route always runs first
            times[name].append(_timed(routes[name]))
    return {k: statistics.median(v) for k, v in times.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=list(DEFAULT_SCENES))
    ap.add_argument("--rounds", type=int, default=15)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; medians of {args.rounds} interleaved rounds")
    print(f"{'scene':<26} {'solve':>10} {'solve_scene':>12} {'from file':>10} {'overhead':>9} {'with file':>10}")
    for scene in args.scenes:
        m = measure(scene, args.rounds)
        base = m["solve"]
        print(f"{scene:<26} {base*1e3:8.2f}ms {m['solve_scene']*1e3:10.2f}ms {m['from file']*1e3:8.2f}ms "
              f"{m['solve_scene']/base - 1:8.1%} {m['from file']/base - 1:9.1%}")


if __name__ == "__main__":
    main()
