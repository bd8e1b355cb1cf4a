"""RNEA's contracted second order by the recursion against Pinocchio's tensors, interleaved in one
process (the stretch goal: the vector-tensor product of Nganga and Wensing).

The contracted backward pass needs RNEA's second derivatives only through mu^T d2tau. With the
recursion (cpp/rigid_body/rnea_hessian.hpp, the default) the expansion stores each node's (q, v, a) and the
pass computes the four contractions directly; with ``_core.testing.set_rnea_hessian_recursion(False)`` the
expansion stores Pinocchio's four nv^3 tensors (ComputeRNEASecondOrderDerivatives per node) and
the pass contracts them, as before 2026-12-01. Same solver, same problem: this script times the two
side by side, alternating per solve, and checks that the histories agree.

Per case (benchmarks/robots.py's builders; default the articulated ones, where it applies: the
one-body scenes keep their shortcut, cpp/rigid_body/one_body.hpp) and expansion (first, second, switch): one
warm-up round then ``--runs`` rounds of [tensors, recursion]; medians. Reported: iterations, ms per
solve and per iteration (solve_time_s / iterations, the closing check included), the ratio
recursion / tensors, second order's time per iteration over first order's, and the largest relative
difference of the cost histories. A second table times one exact linearisation plus a backward pass
at lambda = 1e3 the same way, and ``--ladder`` adds the scaling ladder's robots (free flight,
H = 20: robots.LADDER, up to Talos at nv 50).

Needs example-robot-data; no Crocoddyl. ``python benchmarks/rnea_hessian.py [--runs 5] [--ladder]``.
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
from geoddp.models import compiled  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402
from geoddp.solver.backward import Workspace, backward  # noqa: E402

core = compiled._core
DEFAULT_CASES = ("ur5", "panda", "solo12", "space_manipulator")
EXPANSIONS = ("first", "second", "switch")


def _solve(p, U0, expansion: str, recursion: bool, max_iter: int):
    core.testing.set_rnea_hessian_recursion(recursion)
    time.sleep(0.01)  # let the pool's workers stop polling between solves (as robots.py does)
    return solve(p, SolverOptions(expansion=expansion, verbose=False, max_iter=max_iter), initial_controls=U0)


def solves(case: robots.Case, runs: int, max_iter: int = 200) -> list[str]:
    p, rows, per_it = case.problem, [], {}
    for exp in EXPANSIONS:
        rec: dict[bool, list] = {False: [], True: []}
        for i in range(runs + 1):
            for recursion in (False, True):
                r = _solve(p, case.U0, exp, recursion, max_iter)
                if i:
                    rec[recursion].append(r)
        a, b = rec[True][-1], rec[False][-1]
        same = a.cost_history.shape == b.cost_history.shape
        diff = float(np.max(np.abs(a.cost_history - b.cost_history) / np.abs(b.cost_history))) if same else float("nan")
        t = {c: statistics.median(r.solve_time_s for r in rec[c]) for c in (False, True)}
        it = {c: max(rec[c][-1].iterations, 1) for c in (False, True)}
        per_it[exp] = {c: t[c] / it[c] for c in (False, True)}
        ratio2 = ("" if exp != "second" else
                  f"{per_it['second'][False] / per_it['first'][False]:.2f}x / "
                  f"{per_it['second'][True] / per_it['first'][True]:.2f}x")
        rows.append(f"| {case.name} | {p.model.nv} | {exp} | {b.iterations} / {a.iterations} | {1e3 * t[False]:.2f} | "
                    f"{1e3 * t[True]:.2f} | {1e3 * per_it[exp][False]:.3f} | {1e3 * per_it[exp][True]:.3f} | "
                    f"{t[True] / t[False]:.2f}x | {ratio2} | {diff:.1e} |")
    core.testing.set_rnea_hessian_recursion(True)
    return rows


def pieces(case: robots.Case, runs: int) -> str:
    p = case.problem
    traj = p.trajectory(case.U0)
    ws = Workspace(p.horizon, p.nu, p.nx)
    ts: dict[bool, list] = {False: [], True: []}
    lin1 = []
    for i in range(10 * runs + 1):
        for recursion in (False, True):
            core.testing.set_rnea_hessian_recursion(recursion)
            t0 = time.perf_counter()
            lin = p.linearise(traj, 2)
            backward(lin, ws, 1e3)
            if i:
                ts[recursion].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        backward(p.linearise(traj, 1), ws, 1e3)
        if i:
            lin1.append(time.perf_counter() - t0)
    core.testing.set_rnea_hessian_recursion(True)
    m = {c: 1e3 * statistics.median(v) for c, v in ts.items()}
    m1 = 1e3 * statistics.median(lin1)
    return (f"| {case.name} | {p.model.nv} | {p.horizon} | {m1:.2f} | {m[False]:.2f} | {m[True]:.2f} | "
            f"{m[True] / m[False]:.2f}x | {m[False] / m1:.2f}x | {m[True] / m1:.2f}x |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--cases", nargs="*", default=list(DEFAULT_CASES), choices=list(robots.CASES))
    ap.add_argument("--ladder", action="store_true", help="also the scaling ladder's robots (H = 20, 4 iterations)")
    args = ap.parse_args(argv)
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {robots.machine()}")
    cases = [robots.CASES[n]() for n in args.cases]
    head = ("| case | nv | expansion | iterations (tensors / recursion) | ms / solve tensors | ms / solve recursion | "
            "ms / it tensors | ms / it recursion | recursion / tensors | second / first per it (tensors / recursion) | "
            "max rel diff of J history |\n|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|")
    print("\n" + head)
    for c in cases:
        for row in solves(c, args.runs):
            print(row, flush=True)
    print("\n| case | nv | H | order-1 linearise + pass ms | order-2, tensors | order-2, recursion | recursion / tensors | "
          "tensors / order 1 | recursion / order 1 |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for c in cases:
        print(pieces(c, args.runs), flush=True)
    if args.ladder:
        print("\nThe scaling ladder (free flight, H = 20, 4 iterations from zero controls, the closing check included)")
        print("\n" + head)
        for label, rel, frame in robots.LADDER:
            try:
                case = robots.ladder_case(label, rel, frame)
            except Exception as exc:  # a robot that does not load is reported, not fatal
                print(f"# {label} skipped: {exc}", flush=True)
                continue
            for row in solves(case, max(1, args.runs // 2), max_iter=4):
                print(row, flush=True)
    print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
