"""geoddp (first, second, switch) against Crocoddyl FDDP on the ANYmal gaits, each solve in its own
process (in one process their threads compete).

Both start from the example's quasi-static controls (Crocoddyl's ``quasiStatic``; FDDP also from
its example's states xs = [x0] * (T + 1)). FDDP runs twice: with its default threads ("fddp",
ShootingProblem.nthreads as built) and on one thread ("fddp1"). Per solver and gait: iterations,
J* (geoddp's as Crocoddyl's problem costs geoddp's trajectory), wall time of the solve and the
process's CPU time over it (cpu_s: less sensitive to other jobs on shared cores). Needs the bench
environment (crocoddyl 3.2.1 + pin 4.0.0, example-robot-data). geoddp's processes run numpy's BLAS
on one thread (OPENBLAS_NUM_THREADS=1 unless set): its node models' products are small (tens of
rows), and on two shared cores BLAS's threads made the trot's second-order solve 1.4x slower;
FDDP keeps its default threads.

    .venv-bench/bin/python benchmarks/legged_vs_fddp.py            # all, results log
    .venv-bench/bin/python benchmarks/legged_vs_fddp.py one fddp trot      # or fddp1, first, second, switch
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SOLVERS = ("fddp", "fddp1", "first", "second", "switch")
GAITS = ("walk", "trot")


def crocoddyl_problem(robot, gait):
    from crocoddyl.utils.quadruped import SimpleQuadrupedalGaitProblem

    from geoddp.scene.legged import FEET
    from geoddp.scene.legged import GAITS as PARAMS

    q0 = robot.model.referenceConfigurations["standing"].copy()
    x0 = np.concatenate([q0, np.zeros(robot.model.nv)])
    builder = SimpleQuadrupedalGaitProblem(robot.model, *FEET)  # fresh: its first half step
    make = {"walk": builder.createWalkingProblem, "trot": builder.createTrottingProblem,
            "jump": builder.createJumpingProblem}[gait]
    return make(x0, *[list(a) if isinstance(a, tuple) else a for a in PARAMS[gait]]), x0  # it edits the jump's length


def crocoddyl_cost(croc, problem, q, v, u) -> tuple[float, float]:
    """(J of Crocoddyl's problem at the trajectory, largest transition gap |f(x_k, u_k) - x_k+1|)."""
    xs = [np.concatenate([a, b]) for a, b in zip(q, v)]
    us = [np.zeros(0) if problem.impulse_rows[k] else u[k] for k in range(problem.horizon)]
    J = croc.calc(xs, us)
    gap = max(float(np.max(np.abs(d.xnext - xs[k + 1]))) for k, d in enumerate(croc.runningDatas))
    return float(J), gap


def fddp(gait: str, max_iter: int = 200, threads: int | None = None) -> dict:
    """FDDP with its default threads (``threads`` None) or ``threads`` of them."""
    import crocoddyl

    from geoddp.scene.legged import load_anymal

    croc, x0 = crocoddyl_problem(load_anymal(), gait)
    if threads is not None:
        croc.nthreads = threads
    solver = crocoddyl.SolverFDDP(croc)
    xs = [x0] * (croc.T + 1)
    us = croc.quasiStatic([x0] * croc.T)
    t, c = time.perf_counter(), time.process_time()
    converged = solver.solve(xs, us, max_iter, False)
    elapsed, cpu = time.perf_counter() - t, time.process_time() - c
    return {"solver": "fddp" if threads is None else f"fddp{threads}", "gait": gait, "threads": int(croc.nthreads),
            "iterations": int(solver.iter), "J": float(solver.cost), "converged": bool(converged),
            "time_s": elapsed, "cpu_s": cpu}


def geoddp(gait: str, expansion: str, max_iter: int = 200) -> dict:
    from geoddp.scene.legged import anymal_gait, load_anymal
    from geoddp.solver import SolverOptions, solve

    robot = load_anymal()
    problem = anymal_gait(gait, robot)
    t, c = time.perf_counter(), time.process_time()
    res = solve(problem, SolverOptions(expansion=expansion, max_iter=max_iter))
    elapsed, cpu = time.perf_counter() - t, time.process_time() - c
    out = {"solver": expansion, "gait": gait, "iterations": int(res.iterations), "J": float(res.cost),
           "converged": bool(res.converged), "status": res.status, "time_s": elapsed, "cpu_s": cpu}
    try:
        croc, _ = crocoddyl_problem(robot, gait)
        out["J_crocoddyl"], out["max_gap"] = crocoddyl_cost(croc, problem, res.q, res.v, res.controls)
    except ImportError:
        pass
    return out


def one(solver: str, gait: str) -> dict:
    if solver == "fddp":
        return fddp(gait)
    return fddp(gait, threads=1) if solver == "fddp1" else geoddp(gait, solver)


def main(argv: list[str]) -> None:
    if argv and argv[0] == "one":
        print(json.dumps(one(argv[1], argv[2])))
        return
    rows = []
    for gait in GAITS:
        for solver in SOLVERS:
            env = dict(os.environ)
            if not solver.startswith("fddp"):
                env.setdefault("OPENBLAS_NUM_THREADS", "1")
            out = subprocess.run([sys.executable, __file__, "one", solver, gait], capture_output=True, text=True,
                                 check=True, env=env)
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            print(json.dumps(rows[-1]), flush=True)
    log = Path(__file__).resolve().parent / "results" / "legged_vs_fddp.log"
    log.write_text("\n".join(json.dumps(r) for r in rows) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
