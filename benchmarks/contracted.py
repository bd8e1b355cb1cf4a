"""The contracted second order against the formed tensors, interleaved in one process.

Multibody(contract=True) (the default) keeps the compiled expansion's second-order terms factored
and contracts them with V_x' inside the backward pass (cpp/contracted.*); contract=False forms
Theta, Gamma, Xi (H n^3 + ... numbers) and contracts them in the old pass. Both are the same
solver on the same problem: this script times them side by side, alternating per solve, and
checks that the histories agree.

For each case (benchmarks/robots.py's builders: ``ur5``, ``panda``, ``solo12``, the built-in
``quadrotor``; any of robots.CASES) and expansion (first, second, switch), one warm-up round then
``--runs`` rounds of [tensors, contracted]; medians. Reported: iterations, ms per solve and per
iteration (solve_time_s / iterations, the final check included), the ratio contracted / tensors,
and the largest relative difference of the cost histories. A second table times the pieces of one
iteration at U0 (order-2 linearisation, backward pass at lambda = 1e3) the same way.

Needs example-robot-data; no Crocoddyl. ``python benchmarks/contracted.py [--runs 5] [--cases ...]``.
Timings on a shared machine mean little: compare only the ratios of one run.
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

import robots  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402
from geoddp.solver.backward import Workspace, backward  # noqa: E402

DEFAULT_CASES = ("ur5", "panda", "solo12", "quadrotor")
EXPANSIONS = ("first", "second", "switch")


def _solve(p, U0, expansion: str, contract: bool):
    p.model.contract = contract
    return solve(p, SolverOptions(expansion=expansion, verbose=False), initial_controls=U0)


def solves(case: robots.Case, runs: int) -> list[str]:
    p, rows = case.problem, []
    for exp in EXPANSIONS:
        rec: dict[bool, list] = {False: [], True: []}
        for i in range(runs + 1):
            for contract in (False, True):
                r = _solve(p, case.U0, exp, contract)
                if i:
                    rec[contract].append(r)
        a, b = rec[True][-1], rec[False][-1]
        diff = (float(np.max(np.abs(a.cost_history - b.cost_history) / np.abs(b.cost_history)))
                if a.cost_history.shape == b.cost_history.shape else float("nan"))
        t = {c: statistics.median(r.solve_time_s for r in rec[c]) for c in (False, True)}
        rows.append(f"| {case.name} | {exp} | {b.iterations} / {a.iterations} | {1e3 * t[False]:.1f} | {1e3 * t[True]:.1f} | "
                    f"{1e3 * t[False] / max(b.iterations, 1):.2f} | {1e3 * t[True] / max(a.iterations, 1):.2f} | "
                    f"{t[True] / t[False]:.2f}x | {diff:.1e} |")
    p.model.contract = True
    return rows


def pieces(case: robots.Case, runs: int) -> str:
    p = case.problem
    traj = p.trajectory(case.U0)
    ws = Workspace(p.horizon, p.nu, p.nx)
    lins, ts = {}, {k: [] for k in ("lin_t", "lin_c", "bwd_t", "bwd_c", "lin1")}
    for i in range(10 * runs + 1):
        for contract in (False, True):
            p.model.contract = contract
            t0 = time.perf_counter()
            lins[contract] = p.linearise(traj, 2)
            t1 = time.perf_counter()
            backward(lins[contract], ws, 1e3)
            t2 = time.perf_counter()
            if i:
                ts["lin_c" if contract else "lin_t"].append(t1 - t0)
                ts["bwd_c" if contract else "bwd_t"].append(t2 - t1)
        t0 = time.perf_counter()
        p.linearise(traj, 1)
        if i:
            ts["lin1"].append(time.perf_counter() - t0)
    p.model.contract = True
    m = {k: 1e3 * statistics.median(v) for k, v in ts.items()}
    return (f"| {case.name} | {p.model.nv} | {m['lin1']:.2f} | {m['lin_t']:.2f} | {m['lin_c']:.2f} | "
            f"{m['lin_c'] / m['lin_t']:.2f}x | {m['bwd_t']:.2f} | {m['bwd_c']:.2f} | "
            f"{(m['lin_c'] + m['bwd_c']) / (m['lin_t'] + m['bwd_t']):.2f}x |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--cases", nargs="*", default=list(DEFAULT_CASES), choices=list(robots.CASES))
    args = ap.parse_args(argv)
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {robots.machine()}")
    cases = [robots.CASES[n]() for n in args.cases]
    print("\n| case | expansion | iterations (tensors / contracted) | ms / solve tensors | ms / solve contracted | "
          "ms / it tensors | ms / it contracted | contracted / tensors | max rel diff of J history |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|")
    for c in cases:
        for row in solves(c, args.runs):
            print(row, flush=True)
    print("\n| case | nv | order-1 linearise ms | order-2 linearise ms, tensors | contracted | ratio | "
          "backward ms, tensors | contracted | (linearise + backward) ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for c in cases:
        print(pieces(c, args.runs), flush=True)
    print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
