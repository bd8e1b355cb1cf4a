"""geoddp against Crocoddyl FDDP on real robots from example-robot-data.

Cases (unmodified URDFs of ``example-robot-data``; semi-implicit Euler in both libraries):

* ``ur5``: UR5 (``ur_description/urdf/ur5_robot.urdf``), fixed base, gravity on, all six joints
  actuated; the tool frame ``tool0`` reaches a pose in 1 s;
* ``panda``: Franka Panda (``panda_description/urdf/panda.urdf``, nine joints with the two
  fingers), fixed base, gravity on; ``panda_hand_tcp`` reaches a pose in 1 s;
* ``solo12``: Solo12 (``solo_description/robots/solo12.urdf``) on a free-flyer root, no contacts,
  no gravity (free flight), the twelve leg joints actuated and the base not: the front-left foot
  reaches a pose while the floating base reacts;
* ``hector``: Hector quadrotor (``hector_description/robots/quadrotor_base.urdf``), free-flyer,
  gravity on, four rotors (a "+" frame, arm 0.1525 m, torque coefficient 0.0152 m as in
  Crocoddyl's own Hector example): hover at (0, 0, 1) m to hover at (2, 1, 2) m yawed 45 deg;
* the three built-in scenes ``spacecraft_docking``, ``space_manipulator``, ``quadrotor``.

Every running cost is a sum of state and control regularisations (diagonal weights), every
terminal cost a FramePlacement (plus a state regularisation). Crocoddyl's problem is built
independently from the same constants: ``StateMultibody`` on the same ``pin.Model``,
``DifferentialActionModelFreeFwdDynamics`` with a C++ actuation model
(``ActuationModelFull``, ``ActuationModelFloatingBase`` or ``ActuationModelFloatingBaseThrusters``
whose thrusters are derived from the columns of geoddp's actuation matrix; the matrix
``dtau/du`` of Crocoddyl's model is checked equal to geoddp's), ``IntegratedActionModelEuler``
(semi-implicit), running weights / dt (geoddp's running cost is not multiplied by dt). Then
J(U0) of the initial controls must agree to 1e-9 relative (else the case stops).

Solvers, from the same initial controls, each in a process of its own (in one process
Crocoddyl's OpenMP threads and geoddp's pool disturb each other: a UR5 ratio swung 0.7x-1.8x),
alternating: one round = one process per solver (FDDP default threads, FDDP one thread, geoddp
first, second, switch), each building the case, solving once to warm up and timing
``--solves`` solves (their median); the reported time is the median over ``--runs`` rounds.
``--one-process`` times them interleaved in this process instead (10 ms of sleep before each
solve, one warm-up round; quicker, and biased as said):

* Crocoddyl ``SolverFDDP``, ``th_stop`` 1e-9, ``ShootingProblem.nthreads`` left at its default
  and set to 1; time = wall time of ``solve``;
* geoddp ``solve`` (default options: stopping relative to |J|, rtol 1e-11; tol 1e-8 on |dJ| before
  that default), ``expansion`` first / second / switch;
  time = ``Result.solve_time_s`` (includes the final gradient check).

Reported per solver: iterations, J* (geoddp's cost of the returned controls, for both
libraries), ||dJ/dU|| at the returned controls (``geoddp.solver.cost_gradient``, the same
function for both), time per solve, time per iteration (solve / iterations), and the ratios
geoddp / FDDP (default threads) per solve and per iteration.

``--scaling`` also times one iteration against nv on free-flyer robots from nv 6 to the largest
that can be simulated (free flight, no gravity, posture regularisation + a frame task, H = 20,
4 iterations each, from zero controls) and saves docs/figures/time_per_iteration_vs_nv.png.

Needs crocoddyl 3.2.1 with pin 4.0.0 and example-robot-data (the bench environment):
``python benchmarks/robots.py [--runs 5] [--solves 5] [--one-process] [--cases ...] [--scaling]``.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))

from geoddp.models.actuation import quadrotor_actuation  # noqa: E402
from geoddp.models.multibody import Multibody  # noqa: E402
from geoddp.costs.multibody import (ControlRegularisation, FramePlacement, MultibodyCostSum,  # noqa: E402
                                    StateRegularisation)
from geoddp.problem import Problem  # noqa: E402
from geoddp.solver import SolverOptions, cost_gradient, solve  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FIGURE = ROOT / "docs" / "figures" / "time_per_iteration_vs_nv.png"
BUILTIN = ("spacecraft_docking", "space_manipulator", "quadrotor")
ROBOTS = ("ur5", "panda", "solo12", "hector")


def robots_dir() -> Path:
    """The ``robots`` directory of the installed example-robot-data."""
    import example_robot_data

    return Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf"))


def urdf(rel: str) -> Path:
    return robots_dir() / rel


# ------------------------------------------------------------------ geoddp problems
@dataclass
class Case:
    name: str
    problem: Problem
    U0: np.ndarray
    note: str


def _se3_at(pm: pin.Model, q: np.ndarray, frame: str) -> pin.SE3:
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q)
    return data.oMf[pm.getFrameId(frame)].copy()


def _gravity_torque(pm: pin.Model, q: np.ndarray) -> np.ndarray:
    return pin.computeGeneralizedGravity(pm, pm.createData(), q).copy()


def arm_case(name: str, rel: str, frame: str, q0: np.ndarray, dq_target: np.ndarray,
             dt: float = 0.01, H: int = 100) -> Case:
    """Fixed-base arm, gravity on, every joint actuated: ``frame`` reaches the pose it has at
    integrate(q0, dq_target) (q0 + dq_target for revolute and prismatic joints) in H dt seconds;
    running: posture (q0) and velocity regularisation, torques regularised about the gravity
    torque at q0; terminal: FramePlacement + at rest."""
    mb = Multibody(urdf(rel), root="fixed", dt=dt, integrator="semi_implicit")
    pm = mb.pin_model
    nv = pm.nv
    q0 = np.asarray(q0, float)
    M_ref = _se3_at(pm, pin.integrate(pm, q0, np.asarray(dq_target, float)), frame)
    running = MultibodyCostSum([
        StateRegularisation(pm, q0, W=np.r_[np.full(nv, 1e-3), np.full(nv, 1e-2)]),
        ControlRegularisation(_gravity_torque(pm, q0), W=np.full(nv, 1e-4)),
    ], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, frame, M_ref, W=np.full(6, 1e3)),
        StateRegularisation(pm, q0, W=np.r_[np.zeros(nv), np.full(nv, 1e1)]),
    ], model=pm, terminal=True)
    p = Problem(mb, q0, np.zeros(nv), H, running, terminal)
    U0 = np.tile(_gravity_torque(pm, q0), (H, 1))  # gravity compensation at q0
    return Case(name, p, U0, f"fixed base, nv {nv}, m {nv}, H {H}, dt {dt}, U0 = gravity torque at q0")


def ur5() -> Case:
    return arm_case("ur5", "ur_description/urdf/ur5_robot.urdf", "tool0",
                    np.array([0.0, -1.2, 1.4, -1.6, -1.57, 0.0]),
                    np.array([0.6, -0.4, 0.5, 0.4, 0.5, -0.6]))


def panda() -> Case:
    return arm_case("panda", "panda_description/urdf/panda.urdf", "panda_hand_tcp",
                    np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02, 0.02]),
                    np.array([0.5, 0.3, -0.4, 0.5, 0.4, -0.3, 0.5, 0.0, 0.0]))


def floating_case(name: str, rel: str, frame: str, q0_joints: np.ndarray, dq_target: np.ndarray,
                  dt: float, H: int, fixed_joint_target: bool = True) -> Case:
    """Free-flyer root, no gravity, no contacts, joints actuated (base not): ``frame`` reaches
    the world pose it has at q0 + dq_target (joints only, base at the origin); running: posture
    and velocity regularisation, torques regularised about 0; terminal: FramePlacement + at rest."""
    pm0 = pin.buildModelFromUrdf(str(urdf(rel)), pin.JointModelFreeFlyer())
    nv, nj = pm0.nv, pm0.nv - 6
    Hm = np.vstack([np.zeros((6, nj)), np.eye(nj)])
    mb = Multibody(urdf(rel), root="free_flyer", actuation=Hm, gravity=False, dt=dt, integrator="semi_implicit")
    pm = mb.pin_model
    q0 = pin.neutral(pm)
    q0[7:] = q0_joints
    qt = q0.copy()
    qt[7:] += dq_target
    M_ref = _se3_at(pm, qt, frame)
    w_q = np.r_[np.zeros(6), np.full(nj, 1e-2)]  # posture of the joints; the base floats free
    running = MultibodyCostSum([
        StateRegularisation(pm, q0, W=np.r_[w_q, np.full(nv, 1e-2)]),
        ControlRegularisation(np.zeros(nj), W=np.full(nj, 1e-3)),
    ], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, frame, M_ref, W=np.full(6, 1e3)),
        StateRegularisation(pm, q0, W=np.r_[np.zeros(nv), np.full(nv, 1e1)]),
    ], model=pm, terminal=True)
    p = Problem(mb, q0, np.zeros(nv), H, running, terminal)
    return Case(name, p, np.zeros((H, nj)), f"free-flyer, no gravity, nv {nv}, m {nj}, H {H}, dt {dt}, U0 = 0")


def solo12() -> Case:
    legs = np.tile([0.0, 0.8, -1.6], 4)
    dq = np.zeros(12)
    dq[0:3] = [0.3, -0.6, 0.7]  # front-left leg
    return floating_case("solo12", "solo_description/robots/solo12.urdf", "FL_FOOT", legs, dq, dt=0.01, H=100)


def hector() -> Case:
    """Hector quadrotor: the built-in quadrotor scene's task on the example-robot-data URDF."""
    dt, H = 0.02, 150
    Hm = quadrotor_actuation(0.1525, 1e-6 / 6.6e-5)  # Crocoddyl's Hector example: cm / cf
    mb = Multibody(urdf("hector_description/robots/quadrotor_base.urdf"), root="free_flyer", actuation=Hm,
                   dt=dt, integrator="semi_implicit")
    pm = mb.pin_model
    q0 = pin.neutral(pm)
    q0[2] = 1.0
    u_hover = np.linalg.lstsq(Hm, _gravity_torque(pm, q0), rcond=None)[0]
    M_ref = pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, np.pi / 4), np.array([2.0, 1.0, 2.0]))
    running = MultibodyCostSum([ControlRegularisation(u_hover, W=np.full(4, 1e-1))], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, "base_link", M_ref, W=np.full(6, 1e3)),
        StateRegularisation(pm, q0, W=np.r_[np.zeros(6), np.full(6, 1e2)]),
    ], model=pm, terminal=True)
    p = Problem(mb, q0, np.zeros(6), H, running, terminal)
    return Case("hector", p, np.tile(u_hover, (H, 1)),
                f"free-flyer, gravity, 4 rotors, nv 6, m 4, H {H}, dt {dt}, U0 = hover thrust")


def builtin(name: str) -> Case:
    from geoddp.scene import builtin as scenes

    p = getattr(scenes, name)(integrator="semi_implicit")
    U0 = scenes.hover_controls(p) if name == "quadrotor" else np.zeros((p.horizon, p.nu))
    return Case(name, p, U0, f"built-in scene, nv {p.model.nv}, m {p.nu}, H {p.horizon}, dt {p.model.dt}")


CASES: dict[str, Callable[[], Case]] = {"ur5": ur5, "panda": panda, "solo12": solo12, "hector": hector,
                                        **{n: (lambda n=n: builtin(n)) for n in BUILTIN}}


# ------------------------------------------------------------------ Crocoddyl, built independently
def crocoddyl_actuation(crocoddyl: Any, state: Any, model: Multibody) -> tuple[Any, str]:
    """A C++ Crocoddyl actuation model equal to geoddp's tau = H u (never a Python subclass)."""
    H = np.asarray(model.actuation, float)
    nv, m = H.shape
    if H.shape == (nv, nv) and np.array_equal(H, np.eye(nv)):
        return crocoddyl.ActuationModelFull(state), "ActuationModelFull"
    if model.root == "free_flyer" and np.array_equal(H, np.vstack([np.zeros((6, nv - 6)), np.eye(nv - 6)])):
        return crocoddyl.ActuationModelFloatingBase(state), "ActuationModelFloatingBase"
    if model.root == "free_flyer" and not np.any(H[6:]):
        # column j = [d; p x d + c d] (unit thrust along d at p, drag torque c d): recover the
        # thruster's placement (z axis along d) and its signed torque coefficient
        thrusters = []
        for j in range(m):
            f, tau = H[:3, j], H[3:6, j]
            if abs(np.linalg.norm(f) - 1.0) > 1e-12:
                raise NotImplementedError(f"actuation column {j}: force part not unit ({np.linalg.norm(f)})")
            c = float(tau @ f)
            p = np.cross(f, tau - c * f)
            z = f
            x = np.cross([0.0, 1.0, 0.0], z) if abs(z[1]) < 0.9 else np.cross([1.0, 0.0, 0.0], z)
            x /= np.linalg.norm(x)
            R = np.column_stack([x, np.cross(z, x), z])
            kind = crocoddyl.ThrusterType.CW if c >= 0 else crocoddyl.ThrusterType.CCW
            thrusters.append(crocoddyl.Thruster(pin.SE3(R, p), abs(c), kind))
        act = crocoddyl.ActuationModelFloatingBaseThrusters(state, thrusters)
        return act, "ActuationModelFloatingBaseThrusters"
    raise NotImplementedError("no C++ Crocoddyl actuation model for this actuation matrix")


def actuation_matrix(crocoddyl: Any, act: Any, state: Any, nu: int) -> np.ndarray:
    """Crocoddyl's dtau/du at a random state (constant for these models)."""
    data = act.createData()
    x = state.rand()
    u = np.random.default_rng(0).normal(size=nu)
    act.calc(data, x, u)
    act.calcDiff(data, x, u)
    return np.array(data.dtau_du)


def crocoddyl_problem(p: Problem) -> tuple[Any, str, np.ndarray]:
    """(ShootingProblem, actuation class name, its dtau/du) for a semi-implicit geoddp problem."""
    import crocoddyl
    from multibody_peers import _cost_model  # the term-by-term cost mapping (weights x scale)

    model = p.model
    assert model.integrator == "semi_implicit"
    state = crocoddyl.StateMultibody(model.pin_model)
    act, act_name = crocoddyl_actuation(crocoddyl, state, model)
    nu = act.nu
    dt = float(model.dt)
    run = crocoddyl.DifferentialActionModelFreeFwdDynamics(
        state, act, _cost_model(crocoddyl, pin, state, nu, p.running, 1.0 / dt))
    term = crocoddyl.DifferentialActionModelFreeFwdDynamics(
        state, act, _cost_model(crocoddyl, pin, state, nu, p.terminal, 1.0))
    x0 = np.concatenate([p.q0, p.v0])
    problem = crocoddyl.ShootingProblem(x0, [crocoddyl.IntegratedActionModelEuler(run, dt)] * p.horizon,
                                        crocoddyl.IntegratedActionModelEuler(term, 0.0))
    return problem, act_name, actuation_matrix(crocoddyl, act, state, nu)


def fddp(p: Problem, U0: np.ndarray, nthreads: int | None, max_iter: int = 500,
         th_stop: float = 1e-9) -> dict[str, Any]:
    """Crocoddyl FDDP from U0 and its rollout; the problem is rebuilt (as a user would)."""
    import crocoddyl

    problem, _, _ = crocoddyl_problem(p)
    if nthreads is not None:
        problem.nthreads = int(nthreads)
    s = crocoddyl.SolverFDDP(problem)
    s.th_stop = th_stop
    us = [u.copy() for u in U0]
    xs = problem.rollout(us)
    t0 = time.perf_counter()
    converged = s.solve(xs, us, max_iter, True)
    t = time.perf_counter() - t0
    it = int(s.iter) + 1 if converged else int(s.iter)
    return dict(U=np.array(s.us), iterations=it, time_s=t, converged=bool(converged), nthreads=problem.nthreads)


def geoddp(p: Problem, U0: np.ndarray, expansion: str, max_iter: int = 200) -> dict[str, Any]:
    r = solve(p, SolverOptions(expansion=expansion, verbose=False, max_iter=max_iter), initial_controls=U0)
    th = r.time_history
    per_it = (th[-1] - th[0]) / r.iterations if (th is not None and r.iterations) else float("nan")
    return dict(U=r.controls, iterations=r.iterations, time_s=r.solve_time_s, converged=r.converged,
                status=r.status, loop_per_iter_s=per_it)


# ------------------------------------------------------------------ the comparison
SOLVERS = ("fddp", "fddp-1t", "first", "second", "switch")


def check(case: Case) -> dict[str, Any]:
    """J(U0) in both libraries (1e-9 relative) and the actuation matrices (1e-12)."""
    p = case.problem
    problem, act_name, B = crocoddyl_problem(p)
    if not np.allclose(B, p.model.actuation, rtol=0, atol=1e-12):
        raise AssertionError(f"{case.name}: Crocoddyl's dtau/du differs from geoddp's actuation by "
                             f"{np.abs(B - p.model.actuation).max():.2e}")
    us = [u.copy() for u in case.U0]
    xs = problem.rollout(us)
    J_cro = float(problem.calc(xs, us))
    J_geo = float(p.total_cost(case.U0))
    rel = abs(J_cro - J_geo) / abs(J_geo)
    # a second, random control sequence probes the dynamics away from U0
    rng = np.random.default_rng(1)
    U1 = case.U0 + 1e-2 * rng.normal(size=case.U0.shape) * (1.0 + np.abs(case.U0))
    us1 = [u.copy() for u in U1]
    J1c = float(problem.calc(problem.rollout(us1), us1))
    J1g = float(p.total_cost(U1))
    rel1 = abs(J1c - J1g) / abs(J1g)
    if not (rel <= 1e-9 and (rel1 <= 1e-9 or (np.isnan(J1c) and np.isnan(J1g)))):
        raise AssertionError(f"{case.name}: J differs: U0 {J_geo!r} vs {J_cro!r} (rel {rel:.1e}); "
                             f"random {J1g!r} vs {J1c!r} (rel {rel1:.1e})")
    return dict(J0=J_geo, J0_croco=J_cro, rel=rel, rel_random=rel1, actuation=act_name)


def run_case(case: Case, runs: int) -> dict[str, Any]:
    p = case.problem
    chk = check(case)
    rec: dict[str, list] = {s: [] for s in SOLVERS}
    for i in range(runs + 1):  # round 0: warm-up
        for s in SOLVERS:
            # every solve starts with both libraries' idle threads asleep: Crocoddyl's OpenMP
            # threads (libgomp polls for GOMP_SPINCOUNT = 300000 pauses, a few ms) and geoddp's
            # pool (GEODDP_SPIN_US, 1 ms) would otherwise share the cores with the next solver
            time.sleep(0.01)
            r = solve_once(p, case.U0, s)
            if i:
                rec[s].append(r)
    return summarise(case, chk, rec)


def summarise(case: Case, chk: dict[str, Any], rec: dict[str, list]) -> dict[str, Any]:
    p = case.problem
    out = dict(case=case.name, note=case.note, check=chk, rows={})
    for s in SOLVERS:
        last = rec[s][-1]
        J, g = cost_gradient(p, last["U"])
        t = statistics.median(r["time_s"] for r in rec[s])
        out["rows"][s] = dict(iterations=last["iterations"], J=J, grad=float(np.linalg.norm(g)), time_s=t,
                              time_min_s=min(r["time_s"] for r in rec[s]),
                              iter_s=t / max(last["iterations"], 1), converged=last["converged"],
                              nthreads=last.get("nthreads"), status=last.get("status", ""))
    return out


def solve_once(p: Problem, U0: np.ndarray, s: str) -> dict[str, Any]:
    if s == "fddp":
        return fddp(p, U0, None)
    if s == "fddp-1t":
        return fddp(p, U0, 1)
    return geoddp(p, U0, s)


def worker(name: str, s: str, solves: int, out: str) -> None:
    """One solver's process: build the case, solve once (warm-up), time ``solves`` solves; the
    times, the last solve's fields and its controls go to ``out`` (.npz)."""
    case = CASES[name]()
    solve_once(case.problem, case.U0, s)
    rs = []
    for _ in range(solves):
        time.sleep(0.01)
        rs.append(solve_once(case.problem, case.U0, s))
    last = rs[-1]
    np.savez(out, U=last["U"], times=np.array([r["time_s"] for r in rs]), iterations=last["iterations"],
             converged=last["converged"], nthreads=last.get("nthreads") or 0, status=last.get("status", ""))


def run_case_processes(case: Case, runs: int, solves: int) -> dict[str, Any]:
    """As :func:`run_case`, each solver in a process of its own, alternating round by round."""
    import subprocess
    import tempfile

    p = case.problem
    chk = check(case)
    rec: dict[str, list] = {s: [] for s in SOLVERS}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(runs):
            for s in SOLVERS:
                out = str(Path(tmp) / f"{s}.{i}.npz")
                subprocess.run([sys.executable, __file__, "--worker", case.name, s, str(solves), out], check=True)
                z = np.load(out)
                rec[s].append(dict(U=z["U"], time_s=float(np.median(z["times"])), iterations=int(z["iterations"]),
                                   converged=bool(z["converged"]), nthreads=int(z["nthreads"]) or None,
                                   status=str(z["status"])))
    return summarise(case, chk, rec)


LABEL = {"fddp": "Crocoddyl FDDP (default threads)", "fddp-1t": "Crocoddyl FDDP (1 thread)",
         "first": "geoddp first", "second": "geoddp second", "switch": "geoddp switch"}


def table(results: list[dict[str, Any]]) -> str:
    """Markdown table; ratios are geoddp (or FDDP 1 thread) / FDDP, per solve and per iteration,
    against FDDP with default threads and against FDDP with one thread."""
    lines = ["| case | solver | iterations | J* | (J* - J*_FDDP) / J*_FDDP | ‖dJ/dU‖ | ms / solve (median; min) | ms / iteration | "
             "ratio per solve (vs FDDP default / 1 thread) | ratio per iteration (vs FDDP default / 1 thread) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for res in results:
        ref, ref1 = res["rows"]["fddp"], res["rows"]["fddp-1t"]
        for s in SOLVERS:
            r = res["rows"][s]
            if s == "fddp":
                ratio = ratio_it = ""
            elif s == "fddp-1t":
                ratio = f"{r['time_s'] / ref['time_s']:.2f}x / -"
                ratio_it = f"{r['iter_s'] / ref['iter_s']:.2f}x / -"
            else:
                ratio = f"{r['time_s'] / ref['time_s']:.2f}x / {r['time_s'] / ref1['time_s']:.2f}x"
                ratio_it = f"{r['iter_s'] / ref['iter_s']:.2f}x / {r['iter_s'] / ref1['iter_s']:.2f}x"
            name = LABEL[s] + (f" [{r['nthreads']} threads]" if s == "fddp" else "")
            flag = "" if r["converged"] else " (not converged)"
            lines.append(f"| {res['case']} | {name} | {r['iterations']}{flag} | {r['J']:.10g} | "
                         f"{(r['J'] - ref['J']) / abs(ref['J']):+.1e} | {r['grad']:.1e} | {1e3 * r['time_s']:.1f}; {1e3 * r['time_min_s']:.1f} | "
                         f"{1e3 * r['iter_s']:.2f} | {ratio} | {ratio_it} |")
    return "\n".join(lines)


# ------------------------------------------------------------------ scaling with nv
# (label, URDF, frame of the terminal task): free-flyer robots of example-robot-data, nv 6 .. 50
LADDER = (
    ("hector (base wrench)", "hector_description/robots/quadrotor_base.urdf", "base_link"),
    ("ur5 (free-flyer)", "ur_description/urdf/ur5_robot.urdf", "tool0"),
    ("solo12", "solo_description/robots/solo12.urdf", "FL_FOOT"),
    ("anymal-kinova", "anymal_b_simple_description/robots/anymal-kinova.urdf", "j2s6s200_end_effector"),
    ("g1", "g1_description/urdf/g1_29dof_rev_1_0.urdf", "right_rubber_hand"),
    ("talos_reduced", "talos_data/robots/talos_reduced.urdf", "gripper_left_joint"),
    ("talos_full_v2", "talos_data/robots/talos_full_v2.urdf", "gripper_left_joint"),
)
# romeo (nv 61) loads but has 24 massless links: ABA returns NaN at rest, so it cannot be simulated


def ladder_case(label: str, rel: str, frame: str, H: int = 20, dt: float = 0.02) -> Case:
    """Free flight (no gravity, no contacts), posture regularisation + a terminal frame pose
    (the frame's pose at joints + 0.3 rad); joints actuated (hector: the full base wrench)."""
    pm0 = pin.buildModelFromUrdf(str(urdf(rel)), pin.JointModelFreeFlyer())
    nv = pm0.nv
    Hm = None if nv == 6 else np.vstack([np.zeros((6, nv - 6)), np.eye(nv - 6)])
    mb = Multibody(urdf(rel), root="free_flyer", actuation=Hm, gravity=False, dt=dt, integrator="semi_implicit")
    pm = mb.pin_model
    m = mb.nu
    q0 = pin.neutral(pm)
    qt = q0.copy()
    if nv > 6:
        qt = pin.integrate(pm, q0, np.r_[np.zeros(6), np.full(nv - 6, 0.3)])
    else:
        qt = pin.integrate(pm, q0, np.r_[0.3, 0.2, 0.1, 0.2, 0.1, 0.3])
    fid = pm.getFrameId(frame)
    if fid >= len(pm.frames):
        raise KeyError(f"{label}: no frame {frame!r}")
    M_ref = _se3_at(pm, qt, frame)
    w_q = np.r_[np.zeros(6), np.full(nv - 6, 1e-2)]
    running = MultibodyCostSum([
        StateRegularisation(pm, q0, W=np.r_[w_q, np.full(nv, 1e-2)]),
        ControlRegularisation(np.zeros(m), W=np.full(m, 1e-3)),
    ], model=pm)
    terminal = MultibodyCostSum([
        FramePlacement(pm, frame, M_ref, W=np.full(6, 1e2)),
        StateRegularisation(pm, q0, W=np.r_[np.zeros(nv), np.full(nv, 1e1)]),
    ], model=pm, terminal=True)
    return Case(label, Problem(mb, q0, np.zeros(nv), H, running, terminal), np.zeros((H, m)),
                f"nv {nv}, m {m}")


def scaling(iters: int = 4, runs: int = 3) -> list[dict[str, Any]]:
    """Time per iteration (first, second, FDDP default and 1 thread) over a fixed number of
    iterations from zero controls; medians of ``runs`` interleaved rounds after a warm-up."""
    out = []
    for label, rel, frame in LADDER:
        try:
            case = ladder_case(label, rel, frame)
        except Exception as exc:  # a robot that does not load is reported, not fatal
            print(f"# scaling: {label} skipped: {exc}", flush=True)
            continue
        p = case.problem
        chk = check(case)
        rec: dict[str, list] = {s: [] for s in ("fddp", "fddp-1t", "first", "second")}
        loop: dict[str, list] = {"first": [], "second": []}  # geoddp: the iterations alone, per iteration
        its: dict[str, int] = {}
        for i in range(runs + 1):
            for s in rec:
                if s.startswith("fddp"):
                    r = fddp(p, case.U0, None if s == "fddp" else 1, max_iter=iters, th_stop=1e-300)
                else:
                    r = geoddp(p, case.U0, s, max_iter=iters)
                if i:
                    rec[s].append(r["time_s"] / max(r["iterations"], 1))
                    its[s] = r["iterations"]
                    if s in loop:
                        loop[s].append(r["loop_per_iter_s"])
        row = dict(label=label, nv=p.model.nv, m=p.nu, rel=chk["rel"],
                   **{s: statistics.median(v) for s, v in rec.items()}, its=its,
                   lo={s: min(v) for s, v in rec.items()}, hi={s: max(v) for s, v in rec.items()})
        # A solve stopped after `iters` iterations is not at a stationary point: geoddp's closing
        # check (the exact lambda = 0 pass, then the smallest factorisable lambda for the gains it
        # returns) is in the whole solve's time; "iterations alone" leaves it out.
        print(f"# scaling {label}: nv {row['nv']}, " + ", ".join(
            f"{s} {1e3 * row[s]:.2f} ms/it ({its[s]} it"
            + (f"; iterations alone {1e3 * statistics.median(loop[s]):.2f} ms/it)" if s in loop else ")") for s in rec),
            flush=True)
        out.append(row)
    return out


def figure(rows: list[dict[str, Any]], path: Path = FIGURE, load: str = "") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nv = [r["nv"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, lab, st in (("first", "geoddp first order", "o-"), ("second", "geoddp second order (exact)", "s-"),
                         ("fddp", "Crocoddyl FDDP (default threads)", "^--"), ("fddp-1t", "Crocoddyl FDDP (1 thread)", "v:")):
        med = np.array([1e3 * r[key] for r in rows])
        lo = np.array([1e3 * r["lo"][key] for r in rows])
        hi = np.array([1e3 * r["hi"][key] for r in rows])
        ax.errorbar(nv, med, yerr=[med - lo, hi - med], fmt=st, capsize=3, label=lab)
    for r in rows:
        ax.annotate(r["label"], (r["nv"], 1e3 * r["second"]), textcoords="offset points", xytext=(3, 5), fontsize=7)
    ax.set_xlabel("nv (free-flyer robots of example-robot-data)")
    ax.set_ylabel("time per iteration [ms] (H = 20)\nmedian, bars: min..max of the rounds")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Time per iteration vs nv: free flight, posture + frame task" + (f"\n{load}" if load else ""),
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def machine() -> str:
    import platform

    la = os.getloadavg()
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, load average {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="recorded rounds (after one warm-up round)")
    ap.add_argument("--solves", type=int, default=5, help="timed solves per solver process (their median)")
    ap.add_argument("--one-process", action="store_true", help="all solvers interleaved in this process")
    ap.add_argument("--worker", nargs=4, metavar=("CASE", "SOLVER", "SOLVES", "OUT"), help=argparse.SUPPRESS)
    ap.add_argument("--cases", nargs="*", default=list(ROBOTS) + list(BUILTIN), choices=list(CASES))
    ap.add_argument("--scaling", action="store_true", help="also the time-per-iteration-vs-nv figure")
    ap.add_argument("--scaling-only", action="store_true")
    args = ap.parse_args(argv)
    if args.worker:
        name, s, solves, out = args.worker
        worker(name, s, int(solves), out)
        return 0
    import crocoddyl

    t_start = time.perf_counter()
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; pin {pin.__version__}, crocoddyl "
          f"{getattr(crocoddyl, '__version__', '3.2.1')}; {machine()}", flush=True)
    results = []
    if not args.scaling_only:
        for name in args.cases:
            case = CASES[name]()
            res = run_case(case, args.runs) if args.one_process else run_case_processes(case, args.runs, args.solves)
            c = res["check"]
            print(f"# {name}: {case.note}; Crocoddyl {c['actuation']}; J(U0) geoddp {c['J0']:.15g} crocoddyl "
                  f"{c['J0_croco']:.15g} (rel {c['rel']:.1e}; random U rel {c['rel_random']:.1e}); "
                  f"load {os.getloadavg()[0]:.2f}", flush=True)
            results.append(res)
        print()
        print(table(results))
    if args.scaling or args.scaling_only:
        rows = scaling(runs=args.runs)
        la = os.getloadavg()
        figure(rows, load=f"{time.strftime('%Y-%m-%d', time.gmtime())}, 2 cores shared, load {la[0]:.1f}")
        print("\n| robot | nv | m | geoddp first ms/it | geoddp second ms/it | FDDP ms/it | FDDP 1 thread ms/it | "
              "iterations (first, second, FDDP, FDDP 1t) | second / first | first / FDDP | first / FDDP 1 thread |")
        print("|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
        for r in rows:
            it = r["its"]
            print(f"| {r['label']} | {r['nv']} | {r['m']} | {1e3 * r['first']:.2f} | {1e3 * r['second']:.2f} | "
                  f"{1e3 * r['fddp']:.2f} (min {1e3 * r['lo']['fddp']:.2f}) | "
                  f"{1e3 * r['fddp-1t']:.2f} (min {1e3 * r['lo']['fddp-1t']:.2f}) | {it['first']}, {it['second']}, {it['fddp']}, "
                  f"{it['fddp-1t']} | {r['second'] / r['first']:.1f}x | {r['first'] / r['fddp']:.1f}x | "
                  f"{r['first'] / r['fddp-1t']:.1f}x |")
        print(f"\nfigure: {FIGURE}")
    print(f"# total {time.perf_counter() - t_start:.0f} s; {machine()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
