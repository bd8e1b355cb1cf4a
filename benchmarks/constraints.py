"""Hard constraints: what they cost in time against the unconstrained solve of the same scene, and
what a Crocoddyl user gets for the same UR5 task with penalty costs.

1. Constrained against unconstrained, geoddp (expansion of the scene, time per solve the median of
   ``--runs``):

   * ``satellite_keep_out`` against its problem without the cone (``satellite_paper``'s);
   * ``ur5_constraints`` against ``ur5_reach``: the same task with the pose by a weight of 1e3, no
     limits, no obstacle (the scene's own costs without its constraints have no target: the arm
     would hold still).

2. The UR5 task (``ur5_constraints``) as Crocoddyl's users write it today: the costs of the scene
   (through ``benchmarks/robots.py``'s term-by-term mapping, whose J equals geoddp's to 1e-9),
   plus penalty terms built from Crocoddyl's C++ residual and activation models:

   * joint limits: ``ResidualModelState`` (x against 0) with ``ActivationModelQuadraticBarrier``
     on the URDF's position limits and the scene's velocity limits (weight w);
   * the obstacle: ``ResidualModelFrameTranslation`` of tool0 about the sphere's centre with
     ``ActivationModel2NormBarrier(3, radius)`` (0.5 (radius - |r|)^2 inside the sphere; weight w);
   * the terminal pose: ``ResidualModelFramePlacement`` with a large weight W (quadratic);

   both barriers at every node k = 1..H as the constraints are (running weights divided by dt,
   as the mapping does for every running term), solved by ``SolverFDDP`` from the same
   hover-torque start as geoddp, for a ladder of weights (w, W). Its controls are rolled out by
   geoddp (the same semi-implicit Euler) and scored like geoddp's own: the objective J (the
   scene's costs, without penalties) and each constraint's max violation (the units of
   ``constraint_tol``: rad, rad/s, m). The obstacle gives the task two local optima, one round
   each side of the sphere: geoddp's default first penalty (1e2) reaches one, a first penalty of
   1e3 the other (the lower, which the penalty formulations find), both rows are shown.

Each solver runs in its own process (``--worker``), one after the other; the parent only builds
the table. Part 2 needs the bench environment (pin 4.0.0 + crocoddyl 3.2.1); without Crocoddyl
it is skipped with a note. Timings are wall times of one machine, meaningful only when idle:

    python benchmarks/constraints.py --runs 5                     # the tables (markdown)
    python benchmarks/constraints.py --runs 5 --log benchmarks/results/constraints.log
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

# (barrier weight w per node, terminal placement weight W): the penalty ladder of part 2
WEIGHTS = ((1e2, 1e4), (1e4, 1e6), (1e6, 1e8))
ALT_PENALTY = 1e3  # geoddp's UR5 solve with this penalty_initial (default 1e2) too: the other local optimum
FDDP_TH_STOP = 1e-12
FDDP_MAX_ITER = 1000


# ------------------------------------------------------------------ geoddp (worker)
def _median_solve(solve_once, runs: int) -> tuple[Any, float]:
    times, r = [], None
    for _ in range(runs):
        r = solve_once()
        times.append(r.solve_time_s)
    return r, float(np.median(times))


def geoddp_worker(scene: str, runs: int) -> dict[str, Any]:
    """Constrained and unconstrained solves of ``scene``: J, iterations, time (median)."""
    from geoddp import load_scene
    from geoddp.constraints import solve_constrained
    from geoddp.scene import build_problem
    from geoddp.scene.build import solver_options
    from geoddp.solver import solve

    spec = load_scene(scene)
    cp = build_problem(spec)
    opt = solver_options(spec)
    U0 = initial_of(spec)
    rc, tc = _median_solve(lambda: solve_constrained(cp, opt, U0), runs)
    rep = rc.extra["constraints"]
    rows = [dict(scene=scene, solve="constrained", J=rc.cost, status=rc.status, outer=rep["outer_iterations"],
                 iterations=rc.iterations, max_violation=rep["max_violation"], time_s=tc)]
    if scene == "satellite_keep_out":
        ru, tu = _median_solve(lambda: solve(cp.problem, opt, U0), runs)
        rows.append(dict(scene=scene, solve="without the cone (satellite_paper)", J=ru.cost, status=ru.status,
                         outer=None, iterations=ru.iterations, max_violation=_violation(cp, ru)["max"], time_s=tu))
    else:  # its costs without the constraints have no target (the arm holds still): ur5_reach is the task
        spec2 = load_scene("ur5_reach")
        p2 = build_problem(spec2)
        r2, t2 = _median_solve(lambda: solve(p2, solver_options(spec2), initial_of(spec2)), runs)
        rows.append(dict(scene=scene, solve="ur5_reach (pose by a weight)", J=r2.cost, status=r2.status, outer=None,
                         iterations=r2.iterations, max_violation=_violation(cp, r2)["max"], time_s=t2))
    out = dict(rows=rows, U=rc.controls.tolist())
    if scene == "ur5_constraints":
        # the obstacle splits the task into two local optima (round either side of the sphere); a
        # first penalty of 1e3 instead of 1e2 leads to the other one, the one the penalties find
        import dataclasses

        from geoddp.constraints import ConstrainedProblem

        cp3 = ConstrainedProblem(cp.problem, cp.constraints, cp.terminal_constraints,
                                 dataclasses.replace(cp.options, penalty_initial=ALT_PENALTY))
        r3, t3 = _median_solve(lambda: solve_constrained(cp3, opt, U0), runs)
        out["alt"] = dict(J=r3.cost, status=r3.status, outer=r3.extra["constraints"]["outer_iterations"],
                          iterations=r3.iterations, time_s=t3, U=r3.controls.tolist())
    return out


def initial_of(spec: Any) -> np.ndarray | None:
    from geoddp.scene import initial_controls

    return initial_controls(spec)


def _violation(cp: Any, result: Any = None, controls: np.ndarray | None = None) -> dict[str, float]:
    """Max violation of each constraint of ``cp`` along a result's trajectory (or along the rollout
    of ``controls`` by geoddp's dynamics): |c| for equalities, max(0, c) for inequalities."""
    from geoddp.problem.contract import Trajectory

    traj = cp.trajectory(np.asarray(controls)) if result is None else Trajectory(result.q, result.v, result.controls)
    out = {}
    for (where, c), vals, p in zip(cp.kinds, cp.values(traj), cp.placed):
        v = np.abs(vals) if p.bound.equality else np.maximum(vals, 0.0)
        out[c.name] = float(np.max(v, initial=0.0))
    out["max"] = max(out.values())
    out["J"] = float(cp.trajectory_cost(traj))
    return out


# ------------------------------------------------------------------ Crocoddyl (worker)
def crocoddyl_worker(w: float, W: float, runs: int) -> dict[str, Any]:
    """FDDP on the penalty formulation of ur5_constraints with barrier weight w and pose weight W."""
    import crocoddyl
    import pinocchio as pin
    from multibody_peers import _cost_model

    from geoddp import load_scene
    from geoddp.scene import build_problem

    spec = load_scene("ur5_constraints")
    cp = build_problem(spec)
    p = cp.problem
    model = p.model
    pm = model.pin_model
    dt = float(model.dt)
    (limits,) = [c for c in spec.constraints if c.type == "joint_limits"]
    (sphere,) = [c for c in spec.constraints if c.type == "frame_sphere_keep_out"]
    (pose,) = [c for c in spec.terminal_constraints if c.type == "frame_placement"]
    fid = pm.getFrameId(pose.frame)
    state = crocoddyl.StateMultibody(pm)
    nu = pm.nv
    lb = np.concatenate([pm.lowerPositionLimit, np.full(pm.nv, -1e10)])
    ub = np.concatenate([pm.upperPositionLimit, np.full(pm.nv, 1e10)])
    for joint, (lo, hi) in limits.velocity.items():
        iv = pm.joints[pm.getJointId(joint)].idx_v
        lb[pm.nq + iv], ub[pm.nq + iv] = lo, hi

    def penalties(costs: Any, scale: float) -> None:
        costs.addCost("joint_limits", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelQuadraticBarrier(crocoddyl.ActivationBounds(lb, ub)),
            crocoddyl.ResidualModelState(state, np.zeros(state.nx), nu)), w * scale)
        costs.addCost("obstacle", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModel2NormBarrier(3, float(sphere.radius)),
            crocoddyl.ResidualModelFrameTranslation(state, pm.getFrameId(sphere.frame), sphere.centre.copy(), nu)),
            w * scale)

    def build() -> Any:
        run_costs = _cost_model(crocoddyl, pin, state, nu, p.running, 1.0 / dt)
        term_costs = _cost_model(crocoddyl, pin, state, nu, p.terminal, 1.0)
        penalties(run_costs, 1.0 / dt)
        penalties(term_costs, 1.0)
        term_costs.addCost("tool_pose", crocoddyl.CostModelResidual(
            state, crocoddyl.ResidualModelFramePlacement(state, fid, pin.SE3(pose.placement), nu)), W)
        act = crocoddyl.ActuationModelFull(state)
        run = crocoddyl.IntegratedActionModelEuler(
            crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, run_costs), dt)
        term = crocoddyl.IntegratedActionModelEuler(
            crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, term_costs), 0.0)
        return crocoddyl.ShootingProblem(np.concatenate([p.q0, p.v0]), [run] * p.horizon, term)

    U0 = initial_of(spec)
    times = []
    for _ in range(runs):
        problem = build()  # rebuilt each run, as a user would; not timed
        s = crocoddyl.SolverFDDP(problem)
        s.th_stop = FDDP_TH_STOP
        us = [u.copy() for u in U0]
        xs = problem.rollout(us)
        t0 = time.perf_counter()
        converged = s.solve(xs, us, FDDP_MAX_ITER, True)
        times.append(time.perf_counter() - t0)
    it = int(s.iter) + 1 if converged else int(s.iter)
    return dict(w=w, W=W, U=np.array(s.us).tolist(), iterations=it, converged=bool(converged),
                time_s=float(np.median(times)), nthreads=int(problem.nthreads))


# ------------------------------------------------------------------ the parent
def _run_worker(args: list[str], runs: int) -> dict[str, Any]:
    env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", *args, "--runs", str(runs)],
                         capture_output=True,
                         text=True, env=env, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"worker {args} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _fmt(x: float | None, f: str) -> str:
    return "" if x is None else format(x, f)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--log", type=Path, default=None, help="also write the tables to this file")
    ap.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        kind, *rest = a.worker
        res = geoddp_worker(rest[0], a.runs) if kind == "geoddp" else \
            crocoddyl_worker(float(rest[0]), float(rest[1]), a.runs)
        print(json.dumps(res))
        return 0

    from geoddp import load_scene
    from geoddp.scene import build_problem

    lines = []
    lines.append("## Constrained against unconstrained (geoddp)\n")
    lines.append("| scene | solve | J* | status | outer / inner iterations | max violation | time [ms] | "
                 "time / unconstrained |")
    lines.append("|---|---|---|---|---|---|---|---|")
    geo = {}
    for scene in ("satellite_keep_out", "ur5_constraints"):
        res = _run_worker(["geoddp", scene], a.runs)
        geo[scene] = res
        rows = res["rows"]
        base = rows[1]["time_s"]
        for r in rows:
            its = f"{r['outer']} / {r['iterations']}" if r["outer"] is not None else f"{r['iterations']}"
            lines.append(f"| {scene} | {r['solve']} | {r['J']:.10g} | {r['status'].split(':')[0]} | {its} | "
                         f"{r['max_violation']:.1e} | {1e3 * r['time_s']:.1f} | {r['time_s'] / base:.1f} |")
    lines.append("\n(time / unconstrained: against the problem without the cone for the satellite, against "
                 "ur5_reach for the UR5)\n")

    cp = build_problem(load_scene("ur5_constraints"))
    names = [c.name for _, c in cp.kinds]
    lines.append("## The UR5 task: geoddp's constraints against Crocoddyl's penalties\n")
    lines.append("| solver | weights (barrier w, pose W) | J (objective) | " + " | ".join(
        f"max violation {n}" for n in names) + " | iterations | converged | time [ms] |")
    lines.append("|---|---|---|" + "---|" * len(names) + "---|---|---|")
    g = geo["ur5_constraints"]["rows"][0]
    vg = _violation(cp, controls=np.array(geo["ur5_constraints"]["U"]))
    lines.append(f"| geoddp (augmented Lagrangian) | constraint_tol 1e-8 | {vg['J']:.8f} | " + " | ".join(
        f"{vg[n]:.1e}" for n in names) + f" | {g['outer']} / {g['iterations']} | {g['status'].startswith('converged')} "
        f"| {1e3 * g['time_s']:.1f} |")
    alt = geo["ur5_constraints"]["alt"]
    va = _violation(cp, controls=np.array(alt["U"]))
    lines.append(f"| geoddp, penalty_initial {ALT_PENALTY:.0e} | constraint_tol 1e-8 | {va['J']:.8f} | " + " | ".join(
        f"{va[n]:.1e}" for n in names) + f" | {alt['outer']} / {alt['iterations']} | "
        f"{alt['status'].startswith('converged')} | {1e3 * alt['time_s']:.1f} |")
    try:
        import crocoddyl  # noqa: F401

        have = True
    except ImportError:
        have = False
    if have:
        for w, W in WEIGHTS:
            c = _run_worker(["crocoddyl", repr(w), repr(W)], a.runs)
            vc = _violation(cp, controls=np.array(c["U"]))
            lines.append(f"| Crocoddyl FDDP (penalties), {c['nthreads']} thread(s) | {w:.0e}, {W:.0e} | {vc['J']:.8f} | "
                         + " | ".join(f"{vc[n]:.1e}" for n in names)
                         + f" | {c['iterations']} | {c['converged']} | {1e3 * c['time_s']:.1f} |")
    else:
        lines.append("\n(Crocoddyl not installed here: run in the bench environment for its rows)")
    import pinocchio as pin

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    versions = f"pin {pin.__version__}"
    if have:
        import crocoddyl

        versions += f", crocoddyl {crocoddyl.__version__}"
    lines.append(f"\n{platform.machine()}, python {platform.python_version()}, {versions}, runs {a.runs}, "
                 f"load {load:.2f}")
    text = "\n".join(lines)
    print(text)
    if a.log is not None:
        a.log.write_text("# python benchmarks/constraints.py " + " ".join(argv or sys.argv[1:]) + "\n\n" + text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
