"""What a sweep case costs on top of its solve: reading the scene and building its problem.

A sweep's worker gets each case as a plain table and validates and builds it before solving
(``geoddp.sweep.case.run_case``: ``parse_scene`` then ``solve_scene``). For a robot, reading the
scene builds its model (to check frame and joint names against it), checks its meshes, and the
builder builds the model again. This script times, per scene, interleaved round by round in one
process (the machine is shared and noisy; ratios side by side are what count):

* ``direct``: ``solve_scene(spec)`` on a spec parsed once (the sweep benchmark's bare loop);
* ``case``: ``parse_scene(table, source)`` then ``solve_scene`` on the result, as a worker does;
* ``case, cold``: the same with the per-process memos of built URDF models
  (``geoddp.models.urdf``), resolved meshes, robots found by name and the example-robot-data
  directory (``geoddp.models.robots``) swapped for ones that keep nothing: every model built (twice a
  case) and every mesh resolved, as before those memos.

The bar is at most 10 % per case over ``direct`` for cases of 20 ms or more.

Usage: python benchmarks/case_overhead.py [--rounds 15] [SCENE ...]   (default: every built-in
multibody scene and the paper's satellite; the robot scenes need example-robot-data)
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
import tomllib
from collections import OrderedDict
from contextlib import contextmanager
from typing import Iterator

from geoddp import data
from geoddp.models import urdf as urdf_checks
from geoddp import solve_scene
from geoddp.models import robots
from geoddp.scene import parse_scene

DEFAULT_SCENES = ("satellite_paper", "quadrotor", "spacecraft_docking", "space_manipulator", "hector_fly",
                  "ur5_reach", "solo12_reorient")


class _Forgetful(OrderedDict):
    """A memo that keeps nothing: every lookup misses (the code before the memos)."""

    def __setitem__(self, key, value) -> None:
        pass


@contextmanager
def without_memos() -> Iterator[None]:
    """Run with memos that keep nothing: every model built, every mesh resolved, every time."""
    saved = urdf_checks._BUILT, robots._RESOLVED, robots._ERD_DIR, robots._FOUND
    urdf_checks._BUILT, robots._RESOLVED, robots._ERD_DIR, robots._FOUND = (_Forgetful() for _ in range(4))
    try:
        yield
    finally:
        urdf_checks._BUILT, robots._RESOLVED, robots._ERD_DIR, robots._FOUND = saved


def measure(scene: str, rounds: int) -> dict[str, float]:
    """Median seconds per call of the three routes on a built-in scene."""
    path = data.scene_path(scene, "scene")
    table, source = tomllib.loads(path.read_text(encoding="utf-8")), str(path)
    spec = parse_scene(table, source)

    def case():
        return solve_scene(parse_scene(table, source), verbose=False)

    def cold():
        with without_memos():
            return case()

    routes = {"direct": lambda: solve_scene(spec, verbose=False), "case": case, "case, cold": cold}
    times: dict[str, list[float]] = {k: [] for k in routes}
    costs: dict[str, float] = {}
    for r in range(rounds + 1):  # round 0 warms up
        for name, fn in routes.items():
            t0 = time.perf_counter()
            res = fn()
            dt = time.perf_counter() - t0
            if r:
                times[name].append(dt)
            costs[name] = res.cost
    if len(set(costs.values())) != 1:
        raise AssertionError(f"{scene}: the routes disagree on J*: {costs}")
    return {k: statistics.median(v) for k, v in times.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("scenes", nargs="*", default=list(DEFAULT_SCENES))
    args = ap.parse_args()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average {os.getloadavg()[0]:.2f}; "
          f"medians of {args.rounds} interleaved rounds; J* equal on every route")
    print("| scene | direct | case | case, cold | case / direct | cold / direct | case / cold |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for scene in args.scenes:
        m = measure(scene, args.rounds)
        d, c, k = m["direct"], m["case"], m["case, cold"]
        print(f"| {scene} | {d * 1e3:.2f} ms | {c * 1e3:.2f} ms | {k * 1e3:.2f} ms | {c / d:.3f} | {k / d:.3f} | "
              f"{c / k:.3f} |", flush=True)


if __name__ == "__main__":
    main()
