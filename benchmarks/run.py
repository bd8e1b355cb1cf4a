"""Speed against error on the paper's satellite: geoddp vs Crocoddyl vs CasADi + IPOPT.

All solvers get the same discrete problem (see ``peers.py``): semi-implicit Euler, geodesic
terminal attitude cost, terminal rate cost, running control cost (Crocoddyl's running weight is
S_u / dt because its integrated action models multiply running costs by dt), zero initial
controls. Solvers run interleaved (A B C A B C ...) and times are medians, because shared
machines are noisy: only the ratios measured side by side in one run mean something.

Run (in an environment with the ``bench`` extra: crocoddyl 3.2.1 needs pin 4.0.0):

    python3 -m venv .venv-bench && .venv-bench/bin/pip install -q -e ".[bench]"
    .venv-bench/bin/python benchmarks/run.py [--repeats 7] [--plots docs/figures] [--scaling]

Prints Markdown tables (solvers; horizon scaling) and writes speed_vs_error.png.
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402  (the peers' side, independent of geoddp)

from geoddp.problem import satellite_problem  # noqa: E402
from geoddp.solver import SolverOptions, cost_gradient, solve  # noqa: E402


def geoddp_problem(params: dict):
    return satellite_problem(
        inertia=params["inertia"], actuation=params["actuation"], dt=params["dt"], horizon=params["horizon"],
        R0=params["R0"], Omega0=params["Omega0"], R_d=params["Rd"], Omega_d=params["Omegad"],
        S_u=params["S_u"], S_R=params["W_R"], S_Omega=params["S_Omega"], attitude_kind="geodesic",
        integrator="semi_implicit",
    )


def run_geoddp(problem, expansion: str) -> dict:
    r = solve(problem, SolverOptions(expansion=expansion, verbose=False, tol=1e-8))
    return dict(cost=r.cost, iterations=r.iterations, time_s=r.solve_time_s, controls=r.controls,
                cost_history=r.cost_history, time_history=r.time_history, grad_history=r.grad_norm_history,
                status=r.status)


def solvers(params: dict, problem, include_lbfgs: bool) -> dict:
    table = {
        "geoddp switch": lambda: run_geoddp(problem, "switch"),
        "geoddp second": lambda: run_geoddp(problem, "second"),
        "geoddp first": lambda: run_geoddp(problem, "first"),
        "crocoddyl FDDP": lambda: peers.solve_crocoddyl(params, solver="fddp", record_history=False),
        "crocoddyl FDDP, 1 thread": lambda: peers.solve_crocoddyl(params, solver="fddp", nthreads=1, record_history=False),
        "crocoddyl DDP": lambda: peers.solve_crocoddyl(params, solver="ddp", record_history=False),
        "IPOPT exact Hessian": lambda: peers.solve_ipopt(params, hessian="exact", record_history=False),
    }
    if include_lbfgs:
        table["IPOPT L-BFGS"] = lambda: peers.solve_ipopt(params, hessian="lbfgs", record_history=False)
    return table


def benchmark(horizon: int, repeats: int, include_lbfgs: bool) -> tuple[list[dict], dict]:
    params = peers.satellite_params(horizon=horizon)
    problem = geoddp_problem(params)
    table = solvers(params, problem, include_lbfgs)
    runs: dict[str, list[dict]] = {name: [] for name in table}
    for rep in range(repeats):  # interleaved
        for name, fn in table.items():
            if name == "IPOPT L-BFGS" and rep >= 2:
                continue  # seconds per solve: two samples are enough
            runs[name].append(fn())
    # histories for the speed-against-error figure come from one extra, untimed, recorded run
    recorded = {
        "crocoddyl FDDP, 1 thread": lambda: peers.solve_crocoddyl(params, solver="fddp", nthreads=1),
        "IPOPT exact Hessian": lambda: peers.solve_ipopt(params, hessian="exact"),
    }
    if include_lbfgs:
        recorded["IPOPT L-BFGS"] = lambda: peers.solve_ipopt(params, hessian="lbfgs")
    histories = {name: fn() for name, fn in recorded.items()}
    rows = []
    for name, rs in runs.items():
        r = rs[-1]
        # every solver's controls judged by the same exact cost and gradient (single shooting)
        J, g = cost_gradient(problem, np.asarray(r["controls"]))
        rows.append(dict(name=name, iterations=int(r["iterations"]), cost=J, grad=float(np.linalg.norm(g)),
                         time_s=float(np.median([x["time_s"] for x in rs])), samples=len(rs),
                         last=histories.get(name, r)))
    J_best = min(row["cost"] for row in rows)
    ref = next(row for row in rows if row["name"] == "crocoddyl FDDP")["time_s"]
    ref1 = next(row for row in rows if row["name"] == "crocoddyl FDDP, 1 thread")["time_s"]
    for row in rows:
        row["dJ"] = row["cost"] - J_best
        row["ratio"] = row["time_s"] / ref
        row["ratio1"] = row["time_s"] / ref1
    return rows, dict(J_best=J_best)


def print_table(rows: list[dict], horizon: int) -> None:
    print(f"\n### H = {horizon}\n")
    print("| solver | iterations | J (rollout) | J - J_best | ‖∇J‖ | median time (ms) | time / iteration (ms) | ratio to FDDP | ratio to FDDP 1 thread |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        per_it = r["time_s"] / max(r["iterations"], 1)
        print(f"| {r['name']} | {r['iterations']} | {r['cost']:.10f} | {r['dJ']:.1e} | {r['grad']:.1e} | "
              f"{r['time_s'] * 1e3:.2f} | {per_it * 1e3:.3f} | {r['ratio']:.3f} | {r['ratio1']:.3f} |")


def plot_speed_vs_error(rows: list[dict], J_best: float, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11.5, 4.4))
    for r in rows:
        last = r["last"]
        th, ch = last.get("time_history"), last.get("cost_history")
        if th is None or ch is None or len(ch) < 2 or len(th) != len(ch):
            continue  # timed-only runs record no history
        err = np.asarray(ch, dtype=float) - J_best
        keep = err > 0
        a.loglog(np.maximum(np.asarray(th)[keep], 1e-5) * 1e3, err[keep], "o-", ms=3, label=r["name"])
        if last.get("grad_history") is not None:
            gh = np.asarray(last["grad_history"])
            b.loglog(np.maximum(np.asarray(th)[: gh.size], 1e-5) * 1e3, gh, "o-", ms=3, label=r["name"])
    a.set(xlabel="wall time (ms)", ylabel="J - J*", title="Cost error against time, per iteration")
    b.set(xlabel="wall time (ms)", ylabel="‖∇J‖", title="Gradient norm (ψ recursion) against time, geoddp")
    for ax in (a, b):
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize="small")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "speed_vs_error.png"
    fig.savefig(path, dpi=110)
    return path


def scaling(repeats: int) -> None:
    """geoddp per-iteration time and peak memory against the horizon (tf = 3 s, dt = 3/H)."""
    print("\n### geoddp horizon scaling (switch, semi-implicit, tf = 3 s)\n")
    print("| H | iterations | median time (ms) | time / iteration (ms) | µs / node / iteration | peak memory (MB) |")
    print("|---:|---:|---:|---:|---:|---:|")
    xs, ys = [], []
    for H in (300, 3000, 30000):
        params = peers.satellite_params(horizon=H, dt=3.0 / H)
        p = geoddp_problem(params)
        times, it = [], 0
        for _ in range(repeats if H < 30000 else 3):
            r = solve(p, SolverOptions(verbose=False))
            times.append(r.solve_time_s)
            it = r.iterations
        tracemalloc.start()
        solve(p, SolverOptions(verbose=False))
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        t = float(np.median(times))
        xs.append(H)
        ys.append(t / it)
        print(f"| {H} | {it} | {t * 1e3:.1f} | {t / it * 1e3:.2f} | {t / it / H * 1e6:.2f} | {peak / 1e6:.1f} |")
    slope = np.polyfit(np.log(xs), np.log(ys), 1)[0]
    print(f"\nlog-log slope of time per iteration against H: {slope:.2f} (1 = linear)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--horizon", type=int, default=300)
    ap.add_argument("--no-lbfgs", action="store_true", help="skip IPOPT with L-BFGS (seconds per solve)")
    ap.add_argument("--plots", type=Path, default=Path("docs/figures"))
    ap.add_argument("--scaling", action="store_true", help="also measure H = 300, 3000, 30000")
    args = ap.parse_args()
    import crocoddyl
    import pinocchio

    print(f"{time.strftime('%Y-%m-%d')}, {platform.processor() or platform.machine()}, "
          f"python {platform.python_version()}, pin {pinocchio.__version__}, crocoddyl {crocoddyl.__version__}")
    rows, info = benchmark(args.horizon, args.repeats, not args.no_lbfgs)
    print_table(rows, args.horizon)
    print(f"\nJ_best = {info['J_best']:.12f}")
    print(f"wrote {plot_speed_vs_error(rows, info['J_best'], args.plots)}")
    if args.scaling:
        scaling(args.repeats)


if __name__ == "__main__":
    main()
