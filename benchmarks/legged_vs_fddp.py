"""geoddp (first, second, switch) against Crocoddyl FDDP on the ANYmal gaits and jump, a Solo12
jump and the Talos biped walk, each solve in its own process (in one process their threads compete).

The biped ("talos_walk"): Crocoddyl's ``SimpleBipedGaitProblem`` on example-robot-data's talos_legs
from "half_sitting", its example bipedal_gaits_fwddyn.py's walking phase (step 0.6 m, height 0.1 m,
dt 0.03 s, 15 step knots, 4 support knots; flat feet, 6D contacts); geoddp's built-in
``talos_walk`` is the same problem node for node.

The Solo12 jump ("solo_jump"): example-robot-data's solo12 from "standing", feet FL_FOOT FR_FOOT
HL_FOOT HR_FOOT, jumping in place with a 0.1 m CoM apex, 10 ground and 20 + 20 flying knots, dt
0.01 s, Baumgarte gains (0, 50) (Crocoddyl's ``createJumpingProblem(x0, 0.1, [0, 0, 0], 0.01, 10,
20)``; geoddp's ``QuadrupedGait(model, feet).jump(q0, 0.1, (0, 0, 0), 10, 20)``).

Both start from the example's quasi-static controls (Crocoddyl's ``quasiStatic``; FDDP also from
its example's states xs = [x0] * (T + 1)). FDDP runs twice: with its default threads ("fddp",
ShootingProblem.nthreads as built) and on one thread ("fddp1"). Per solver and gait: iterations,
J* (geoddp's as Crocoddyl's problem costs geoddp's trajectory), wall time of the solve and the
process's CPU time over it (cpu_s: less sensitive to other jobs on shared cores). Needs the bench
environment (crocoddyl 3.2.1 + pin 4.0.0, example-robot-data). geoddp's processes run numpy's BLAS
on one thread (OPENBLAS_NUM_THREADS=1 unless set): its node models' products are small (tens of
rows), and on two shared cores BLAS's threads made the trot's second-order solve 1.4x slower;
FDDP keeps its default threads.

Rounds (``--rounds N``, default 3): every round runs every solver once per gait, so the solvers
alternate and a load spike on the shared cores hits one round's solves, not one solver's; the log
has every solve (its ``round``) and then, per gait and solver, the median wall and CPU times
(``"summary": true``). geoddp's legged problems run their rollouts, node costs and first-order
expansions in the compiled core (``ContactProblem.backend`` "compiled", node-parallel on the
core's default threads), the exact second-order expansion included.

    .venv-bench/bin/python benchmarks/legged_vs_fddp.py            # all, results log
    .venv-bench/bin/python benchmarks/legged_vs_fddp.py --rounds 1 walk trot   # some gaits, one round
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
GAITS = ("walk", "trot", "jump", "solo_jump", "talos_walk")
SOLO_FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
SOLO_JUMP = (0.1, (0.0, 0.0, 0.0), 10, 20)  # CoM apex, jump length, ground knots, flying knots
TALOS_WALK = (0.6, 0.1, 0.03, 15, 4)  # step length, height, dt, step knots, support knots: geoddp.scene.legged.TALOS_WALK


def load(gait):
    """The robot of ``gait``: Solo12 for "solo_jump", Talos' legs for "talos_walk", else ANYmal."""
    from geoddp.scene.legged import load_anymal, load_robot

    if gait == "talos_walk":
        return load_robot("talos_legs")
    return load_robot("solo12") if gait == "solo_jump" else load_anymal()


def crocoddyl_problem(robot, gait):
    from crocoddyl.utils.quadruped import SimpleQuadrupedalGaitProblem

    from geoddp.scene.legged import FEET
    from geoddp.scene.legged import GAITS as PARAMS

    if gait == "talos_walk":
        from crocoddyl.utils.biped import SimpleBipedGaitProblem

        q0 = robot.model.referenceConfigurations["half_sitting"].copy()
        x0 = np.concatenate([q0, np.zeros(robot.model.nv)])
        builder = SimpleBipedGaitProblem(robot.model, "right_sole_link", "left_sole_link")  # fresh: its half step
        return builder.createWalkingProblem(x0, *TALOS_WALK), x0
    q0 = robot.model.referenceConfigurations["standing"].copy()
    x0 = np.concatenate([q0, np.zeros(robot.model.nv)])
    if gait == "solo_jump":
        height, length, ground, flying = SOLO_JUMP
        builder = SimpleQuadrupedalGaitProblem(robot.model, *SOLO_FEET)
        return builder.createJumpingProblem(x0, height, list(length), 0.01, ground, flying), x0
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

    croc, x0 = crocoddyl_problem(load(gait), gait)
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
    from geoddp.problem.legged import QuadrupedGait
    from geoddp.scene.legged import anymal_gait, contact_problem, talos_walk
    from geoddp.solver import SolverOptions, solve

    robot = load(gait)
    if gait == "talos_walk":
        problem = talos_walk(robot)
    elif gait == "solo_jump":
        q0 = robot.model.referenceConfigurations["standing"].copy()
        nodes, terminal = QuadrupedGait(robot.model, SOLO_FEET).jump(q0, *SOLO_JUMP)
        problem = contact_problem(robot, nodes, terminal, q0, 0.01, (0.0, 50.0), feet=SOLO_FEET)
    else:
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


def summary(rows: list[dict]) -> list[dict]:
    """Per gait and solver: the medians of the rounds' wall and CPU times (and the first round's
    iterations, J and status: the solves are deterministic)."""
    out = []
    for gait in dict.fromkeys(r["gait"] for r in rows):
        for solver in dict.fromkeys(r["solver"] for r in rows if r["gait"] == gait):
            runs = [r for r in rows if r["gait"] == gait and r["solver"] == solver]
            row = {k: v for k, v in runs[0].items() if k not in ("time_s", "cpu_s", "round")}
            row.update(summary=True, rounds=len(runs), time_s=float(np.median([r["time_s"] for r in runs])),
                       cpu_s=float(np.median([r["cpu_s"] for r in runs])),
                       iterations_all_rounds=sorted({r["iterations"] for r in runs}))
            out.append(row)
    return out


def main(argv: list[str]) -> None:
    if argv and argv[0] == "one":
        print(json.dumps(one(argv[1], argv[2])))
        return
    rounds = 3
    if argv and argv[0] == "--rounds":
        rounds, argv = int(argv[1]), argv[2:]
    gaits = tuple(argv) or GAITS
    rows = []
    for r in range(rounds):
        for gait in gaits:
            for solver in SOLVERS:
                env = dict(os.environ)
                if not solver.startswith("fddp"):
                    env.setdefault("OPENBLAS_NUM_THREADS", "1")
                out = subprocess.run([sys.executable, __file__, "one", solver, gait], capture_output=True, text=True,
                                     check=True, env=env)
                rows.append({**json.loads(out.stdout.strip().splitlines()[-1]), "round": r})
                print(json.dumps(rows[-1]), flush=True)
    summ = summary(rows)
    for row in summ:
        print(json.dumps(row), flush=True)
    log = Path(__file__).resolve().parent / "results" / "legged_vs_fddp.log"
    log.write_text("\n".join(json.dumps(r) for r in rows + summ) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
