"""What control limits cost per solve (with limits inactive, at most 10 % more).

Solves each problem without limits, with limits that never bind (+-100 N m on the satellite: no
iterate and no full Newton step reaches them, so the solve is the unconstrained one bit for bit,
plus the clamp in the forward pass, the feasibility test of each backward pass and the projected
gradient), and with active limits; reports the median solve_time_s over ``--runs`` solves and the
ratio to the unconstrained solve. Timings are meaningful only on an idle machine:

    python benchmarks/limits_overhead.py --runs 50
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from geoddp.scene import builtin as scenes
from geoddp.problem import Problem, paper_problem
from geoddp.solver import SolverOptions, solve


def quad(limits):
    q = scenes.quadrotor(integrator="semi_implicit")
    return Problem(q.model, q.q0, q.v0, q.horizon, q.running, q.terminal, limits=limits)


CASES = [
    ("satellite (Table I)", "none", lambda: paper_problem()),
    ("satellite (Table I)", "inactive +-100 N m", lambda: paper_problem(limits=(-100.0, 100.0))),
    ("satellite (Table I)", "active +-5 N m", lambda: paper_problem(limits=(-5.0, 5.0))),
    ("satellite (Table I)", "active +-3 N m", lambda: paper_problem(limits=(-3.0, 3.0))),
    ("quadrotor", "none", lambda: quad(None)),
    ("quadrotor", "inactive [-100, 100] N", lambda: quad((-100.0, 100.0))),
    ("quadrotor", "active [0, 4] N", lambda: quad((0.0, 4.0))),
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30)
    args = ap.parse_args(argv)
    base: dict[str, float] = {}
    print("| problem | limits | iterations | J* | median solve [ms] | vs no limits |")
    print("|---|---|---|---|---|---|")
    for name, label, build in CASES:
        p = build()
        opt = SolverOptions(verbose=False)
        U0 = None
        if name == "quadrotor":
            U0 = scenes.hover_controls(p)
            if p.control_bounds() is not None:
                U0 = np.clip(U0, *p.control_bounds())
        rs = [solve(p, opt, initial_controls=U0) for _ in range(args.runs)]
        t = float(np.median([r.solve_time_s for r in rs]))
        base.setdefault(name, t)
        print(f"| {name} | {label} | {rs[0].iterations} | {rs[0].cost:.10g} | {t * 1e3:.2f} | {t / base[name]:.2f} |")
    load = Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"
    print(f"\nruns {args.runs}, load {load}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
