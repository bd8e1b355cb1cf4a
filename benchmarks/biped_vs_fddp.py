"""geoddp (first, second, switch) against Crocoddyl FDDP on the Talos biped walk (Crocoddyl's
SimpleBipedGaitProblem, its example bipedal_gaits_fwddyn.py's walking phase: step 0.6 m, height
0.1 m, dt 0.03 s, 15 step knots, 4 support knots), each solve in its own process.

Both start from the example's quasi-static controls (Crocoddyl's ``quasiStatic``); FDDP from its
example's states xs = [x0] * (T + 1) (infeasible, as the example) with its default threads
("fddp", ShootingProblem.nthreads as built) and on one thread ("fddp1"), and, "fddp_rollout", from
the rollout of those controls (geoddp's start). Per solver: iterations, J* (geoddp's as Crocoddyl's
problem costs geoddp's trajectory, with the largest transition gap), wall and CPU time of the solve.
Needs the bench environment (crocoddyl 3.2.1 + pin 4.0.0, example-robot-data); geoddp's processes
run numpy's BLAS on one thread (OPENBLAS_NUM_THREADS=1 unless set).

    .venv-bench/bin/python benchmarks/biped_vs_fddp.py            # all, results log
    .venv-bench/bin/python benchmarks/biped_vs_fddp.py one first  # or fddp, fddp1, fddp_rollout, second, switch
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from legged_vs_fddp import crocoddyl_cost  # the same check of a trajectory by Crocoddyl's problem

SOLVERS = ("fddp", "fddp1", "fddp_rollout", "first", "second", "switch")
WALK = (0.6, 0.1, 0.03, 15, 4)  # step length, height, dt, step knots, support knots: geoddp.scene.legged.TALOS_WALK


def crocoddyl_problem(robot):
    from crocoddyl.utils.biped import SimpleBipedGaitProblem

    q0 = robot.model.referenceConfigurations["half_sitting"].copy()
    x0 = np.concatenate([q0, np.zeros(robot.model.nv)])
    builder = SimpleBipedGaitProblem(robot.model, "right_sole_link", "left_sole_link")  # fresh: its half step
    return builder.createWalkingProblem(x0, *WALK), x0


def fddp(rollout: bool, max_iter: int = 200, threads: int | None = None) -> dict:
    """FDDP from the example's states or the rollout, with its default threads (``threads`` None)
    or ``threads`` of them."""
    import crocoddyl
    import example_robot_data

    croc, x0 = crocoddyl_problem(example_robot_data.load("talos_legs"))
    if threads is not None:
        croc.nthreads = threads
    solver = crocoddyl.SolverFDDP(croc)
    us = croc.quasiStatic([x0] * croc.T)
    xs = croc.rollout(us) if rollout else [x0] * (croc.T + 1)
    t, c = time.perf_counter(), time.process_time()
    converged = solver.solve(xs, us, max_iter, rollout)
    elapsed, cpu = time.perf_counter() - t, time.process_time() - c
    name = "fddp_rollout" if rollout else "fddp" if threads is None else f"fddp{threads}"
    return {"solver": name, "threads": int(croc.nthreads),
            "iterations": int(solver.iter), "J": float(solver.cost), "converged": bool(converged),
            "time_s": elapsed, "cpu_s": cpu}


def geoddp(expansion: str, max_iter: int = 200) -> dict:
    import example_robot_data

    from geoddp.scene.legged import talos_walk
    from geoddp.solver import SolverOptions, solve

    robot = example_robot_data.load("talos_legs")
    problem = talos_walk(robot)
    t, c = time.perf_counter(), time.process_time()
    res = solve(problem, SolverOptions(expansion=expansion, max_iter=max_iter))
    elapsed, cpu = time.perf_counter() - t, time.process_time() - c
    out = {"solver": expansion, "iterations": int(res.iterations), "J": float(res.cost),
           "converged": bool(res.converged), "status": res.status, "time_s": elapsed, "cpu_s": cpu}
    try:
        croc, _ = crocoddyl_problem(robot)
        out["J_crocoddyl"], out["max_gap"] = crocoddyl_cost(croc, problem, res.q, res.v, res.controls)
    except ImportError:
        pass
    return out


def one(solver: str) -> dict:
    if solver.startswith("fddp"):
        return fddp(solver == "fddp_rollout", threads=1 if solver == "fddp1" else None)
    return geoddp(solver)


def main(argv: list[str]) -> None:
    if argv and argv[0] == "one":
        print(json.dumps(one(argv[1])))
        return
    rows = []
    for solver in SOLVERS:
        env = dict(os.environ)
        if not solver.startswith("fddp"):
            env.setdefault("OPENBLAS_NUM_THREADS", "1")
        out = subprocess.run([sys.executable, __file__, "one", solver], capture_output=True, text=True,
                             check=True, env=env)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    log = Path(__file__).resolve().parent / "results" / "biped_vs_fddp.log"
    log.write_text("\n".join(json.dumps(r) for r in rows) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
