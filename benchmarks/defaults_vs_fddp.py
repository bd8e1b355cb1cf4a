"""geoddp at default options against Crocoddyl FDDP at its default ``th_stop``: J* and iterations.

Every robot case of ``benchmarks/robots.py`` (UR5, Panda, Solo12, Hector, the three built-in
multibody scenes), a Kinova Gen2 arm (example-robot-data's ``kinova``: continuous joints, so
nq = 9 > nv = 6) and the free-flight robots of its scaling ladder (Hector with the base wrench, a
UR5 on a free flyer, Solo12, ANYmal-Kinova, G1, Talos reduced and full), each solved to
convergence by both libraries from the same initial controls (``robots.py``'s U0):

* Crocoddyl ``SolverFDDP``, ``th_stop`` left at its default (1e-9 in Crocoddyl 3.2.1),
  ``max_iter`` 500;
* geoddp ``solve(problem, SolverOptions(verbose=False), initial_controls=U0)``: every option at
  its default (``expansion`` switch and the default stopping rule).

Reported per case: iterations of each, J* of each (geoddp's cost of the returned controls, the
same function for both), (J*_geoddp - J*_FDDP) / |J*_FDDP| (the number that must be <= 0),
geoddp's status, and rough wall times (one solve each, on whatever machine runs it: not a
timing claim; ``robots.py`` times). ``--expansions`` adds geoddp first / second.

Needs the bench environment (pin 4.0.0, crocoddyl 3.2.1, example-robot-data):
``python benchmarks/defaults_vs_fddp.py [--cases ...] [--expansions switch first second]``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))

import robots  # noqa: E402
from geoddp.problem import Problem  # noqa: E402
from geoddp.solver import SolverOptions, solve  # noqa: E402


def kinova() -> robots.Case:
    """Kinova Gen2 arm (``kinova_description/robots/kinova.urdf``: three continuous joints, nq 9,
    nv 6) in robots.arm_case's reach from example-robot-data's q0 (1 s, dt 0.01 s)."""
    import example_robot_data

    q0 = np.asarray(example_robot_data.load("kinova").q0, float)
    return robots.arm_case("kinova", "kinova_description/robots/kinova.urdf", "j2s6s200_end_effector", q0,
                           np.array([0.5, 0.3, -0.4, 0.5, 0.4, -0.3]))


def ladder(label: str) -> Callable[[], robots.Case]:
    rel, frame = next((r, f) for lab, r, f in robots.LADDER if lab == label)
    return lambda: robots.ladder_case(label, rel, frame)


LADDER_NAMES = {"hector_wrench": "hector (base wrench)", "ur5_free_flyer": "ur5 (free-flyer)",
                "solo12_flight": "solo12", "anymal_kinova": "anymal-kinova", "g1": "g1",
                "talos_reduced": "talos_reduced", "talos_full_v2": "talos_full_v2"}
CASES: dict[str, Callable[[], robots.Case]] = {**robots.CASES, "kinova": kinova,
                                                **{k: ladder(v) for k, v in LADDER_NAMES.items()}}


def fddp(p: Problem, U0: np.ndarray, max_iter: int = 500) -> dict[str, Any]:
    """Crocoddyl FDDP at its default th_stop, one thread."""
    import crocoddyl

    problem, _, _ = robots.crocoddyl_problem(p)
    problem.nthreads = 1
    s = crocoddyl.SolverFDDP(problem)
    us = [u.copy() for u in U0]
    xs = problem.rollout(us)
    t0 = time.perf_counter()
    converged = s.solve(xs, us, max_iter, True)
    t = time.perf_counter() - t0
    U = np.array(s.us)
    return dict(J=float(p.total_cost(U)), iterations=int(s.iter) + 1 if converged else int(s.iter), time_s=t,
                status="converged" if converged else "max_iter", th_stop=float(s.th_stop))


def geoddp(p: Problem, U0: np.ndarray, expansion: str | None) -> dict[str, Any]:
    """geoddp at default options (``expansion`` given only when not None)."""
    opt = SolverOptions(verbose=False) if expansion is None else SolverOptions(verbose=False, expansion=expansion)
    r = solve(p, opt, initial_controls=U0)
    return dict(J=float(p.total_cost(r.controls)), iterations=r.iterations, time_s=r.solve_time_s,
                status=r.status.split(":")[0], converged=r.converged)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    ap.add_argument("--expansions", nargs="*", default=["switch"], choices=["switch", "first", "second"])
    args = ap.parse_args(argv)
    import crocoddyl

    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; pin {pin.__version__}, crocoddyl "
          f"{getattr(crocoddyl, '__version__', '3.2.1')}; {robots.machine()}; times: one solve each, rough", flush=True)
    print("| case | FDDP it | FDDP J* | geoddp | it | J* | (J* - J*_FDDP) / J*_FDDP | status | FDDP s | geoddp s |")
    print("|---|---:|---:|---|---:|---:|---:|---|---:|---:|")
    for name in args.cases:
        case = CASES[name]()
        p = case.problem
        ref = fddp(p, case.U0)
        for exp in args.expansions:
            g = geoddp(p, case.U0, None if exp == "switch" else exp)
            rel = (g["J"] - ref["J"]) / abs(ref["J"])
            print(f"| {name} | {ref['iterations']} | {ref['J']:.15g} | {exp} | {g['iterations']} | {g['J']:.15g} | "
                  f"{rel:+.1e} | {g['status']} | {ref['time_s']:.2f} | {g['time_s']:.2f} |", flush=True)
    print(f"# load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
