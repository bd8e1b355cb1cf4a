"""Control limits: geoddp's box-constrained DDP against Crocoddyl's BoxFDDP.

Two problems, semi-implicit Euler, the same costs, Crocoddyl's running weights divided by dt
(its integrator multiplies running costs by dt), Crocoddyl built from C++ actuation models only:

* the paper's satellite (Table I, geodesic attitude cost as in benchmarks/run.py) with reaction-
  wheel limits |u_i| <= 5 N m (only axis 3 saturates) and |u_i| <= 3 N m (all three);
  Crocoddyl's problem is benchmarks/peers.py's (``ActuationModelFull``);
* the built-in quadrotor with rotor thrusts in [0, 4] N (hover: 3.68 N per rotor);
  Crocoddyl's problem is benchmarks/robots.py's (``ActuationModelFloatingBaseThrusters``).

Both solvers start from the same feasible guess (zeros, resp. the hover thrusts, clipped into
the box). For each: J*, iterations, time per solve (median of ``--runs``), and the ratio
geoddp / BoxFDDP (the faster of its default threads and one thread). Both optima are re-evaluated by geoddp's single-shooting cost of the returned
controls, so the J column compares like with like.

Needs the bench environment (pin 4.0.0 + crocoddyl 3.2.1) with geoddp's compiled core built
there from this branch. Timings are meaningful only on an idle machine:

    python benchmarks/limits_peers.py --runs 5            # the table (markdown)
    python benchmarks/limits_peers.py --runs 1 --quick    # a smoke run
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402
import robots  # noqa: E402

from geoddp.scene import builtin as scenes  # noqa: E402
from geoddp.problem import Problem, satellite_problem  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402

BOXFDDP_TH_STOP = 1e-12  # Crocoddyl's stopping value (its squared-gradient-like measure); tight so that
# both report the same optimum to ~1e-9 and the comparison is not decided by a loose stop
QUAD_THRUST = (0.0, 4.0)


def satellite(limit: float) -> tuple[Problem, Any, np.ndarray]:
    """(geoddp problem, Crocoddyl problem, U0) for Table I with |u_i| <= limit."""
    params = peers.satellite_params()
    p = satellite_problem(
        inertia=params["inertia"], actuation=params["actuation"], dt=params["dt"], horizon=params["horizon"],
        R0=params["R0"], Omega0=params["Omega0"], R_d=params["Rd"], Omega_d=params["Omegad"],
        S_u=params["S_u"], S_R=params["W_R"], S_Omega=params["S_Omega"], attitude_kind="geodesic",
        integrator="semi_implicit", limits=(-limit, limit))
    return p, lambda: set_box(peers.build_crocoddyl_problem(params)[0], *p.control_bounds()), np.zeros((p.horizon, 3))


def quadrotor() -> tuple[Problem, Any, np.ndarray]:
    q = scenes.quadrotor(integrator="semi_implicit")
    p = Problem(q.model, q.q0, q.v0, q.horizon, q.running, q.terminal, limits=QUAD_THRUST)
    U0 = np.clip(scenes.hover_controls(q), *p.control_bounds())
    return p, lambda: set_box(robots.crocoddyl_problem(q)[0], *p.control_bounds()), U0


def set_box(problem: Any, lower: np.ndarray, upper: np.ndarray) -> Any:
    """Crocoddyl's control limits per running node (the box BoxFDDP projects onto)."""
    for k, model in enumerate(problem.runningModels):
        model.u_lb = lower[k].copy()
        model.u_ub = upper[k].copy()
        model.differential.u_lb = lower[k].copy()
        model.differential.u_ub = upper[k].copy()
    return problem


def boxfddp(build: Any, U0: np.ndarray, max_iter: int = 1000, nthreads: int | None = None) -> dict[str, Any]:
    """Crocoddyl BoxFDDP from U0 (``nthreads``: its OpenMP threads over the nodes; None keeps its
    default, the number of cores, which a loaded machine slows down)."""
    import crocoddyl

    problem = build()
    if nthreads is not None:
        problem.nthreads = int(nthreads)
    s = crocoddyl.SolverBoxFDDP(problem)
    s.th_stop = BOXFDDP_TH_STOP
    us = [u.copy() for u in U0]
    xs = problem.rollout(us)
    t0 = time.perf_counter()
    converged = s.solve(xs, us, max_iter, True)
    t = time.perf_counter() - t0
    return dict(U=np.array(s.us), iterations=int(s.iter) + 1 if converged else int(s.iter), time_s=t,
                converged=bool(converged), cost_solver=float(s.cost))


def geoddp(p: Problem, U0: np.ndarray, expansion: str) -> dict[str, Any]:
    r = solve(p, SolverOptions(expansion=expansion, verbose=False), initial_controls=U0)
    return dict(U=r.controls, iterations=r.iterations, time_s=r.solve_time_s, converged=r.converged,
                kkt=r.extra["optimality"]["kkt_residual"], active=int((r.active_set != 0).sum()), status=r.status)


CASES = {"satellite |u| <= 5": lambda: satellite(5.0), "satellite |u| <= 3": lambda: satellite(3.0),
         "quadrotor thrust [0, 4] N": quadrotor}


def compare(name: str, runs: int, expansions: tuple[str, ...] = ("first", "second", "switch")) -> list[dict]:
    p, build, U0 = CASES[name]()
    rows = []
    solvers = {f"geoddp {e}": (lambda e=e: geoddp(p, U0, e)) for e in expansions}
    solvers["crocoddyl BoxFDDP"] = lambda: boxfddp(build, U0)
    solvers["crocoddyl BoxFDDP, 1 thread"] = lambda: boxfddp(build, U0, nthreads=1)
    for label, fn in solvers.items():
        outs = [fn() for _ in range(runs)]
        o = outs[0]
        lo, hi = p.control_bounds()
        U = np.clip(o["U"], lo, hi)  # BoxFDDP's us are feasible up to round-off; J of the feasible controls
        rows.append(dict(case=name, solver=label, J=p.total_cost(U), iterations=o["iterations"],
                         time_s=float(np.median([x["time_s"] for x in outs])), converged=o["converged"],
                         kkt=o.get("kkt"), active=int(((U <= lo) | (U >= hi)).sum()),
                         max_violation=float(max((o["U"] - hi).max(), (lo - o["U"]).max(), 0.0))))
    t_croc = min(r["time_s"] for r in rows if r["solver"].startswith("crocoddyl"))  # its faster setting
    J_ref = min(r["J"] for r in rows)
    for r in rows:
        r["ratio"] = r["time_s"] / t_croc
        r["dJ_rel"] = (r["J"] - J_ref) / abs(J_ref)
    return rows


def table(rows: list[dict]) -> str:
    out = ["| problem | solver | J* | (J - J_best)/J_best | iterations | active inputs | KKT residual | time [ms] | "
           "time / best BoxFDDP |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        kkt = "" if r["kkt"] is None else f"{r['kkt']:.1e}"
        out.append(f"| {r['case']} | {r['solver']} | {r['J']:.10g} | {r['dJ_rel']:.1e} | {r['iterations']} | "
                   f"{r['active']} | {kkt} | {r['time_s'] * 1e3:.1f} | {r['ratio']:.2f} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="solves per solver (median time)")
    ap.add_argument("--quick", action="store_true", help="the switch expansion only")
    args = ap.parse_args(argv)
    import crocoddyl
    import pinocchio

    exps = ("switch",) if args.quick else ("first", "second", "switch")
    rows = [r for name in CASES for r in compare(name, args.runs, exps)]
    print(table(rows))
    print(f"\n{platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"pin {pinocchio.__version__}, crocoddyl {crocoddyl.__version__}, runs {args.runs}, "
          f"load {Path('/proc/loadavg').read_text().split()[0] if Path('/proc/loadavg').exists() else '?'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
