"""Crocoddyl peer for geoddp's multibody problems.

``crocoddyl_problem(mb_problem)`` builds the Crocoddyl equivalent of a geoddp
:class:`geoddp.problem.Problem` integrated with semi-implicit Euler
(``integrator="semi_implicit"``), and ``solve_crocoddyl`` solves it with FDDP or DDP.

Mapping (checked by ``check_cost_equivalence``: Crocoddyl's total cost of a random control
sequence equals geoddp's ``mb_problem.cost(*mb_problem.rollout(U), U)`` to ~1e-15 relative,
which checks dynamics, integrator, costs and the dt scaling at once):

* state: ``StateMultibody`` on the same ``pin.Model`` (``mb_problem.model.pin_model``), so
  x = (q, v) and Crocoddyl's ``diff``/``integrate`` are Pinocchio's ``difference``/``integrate``;
* dynamics: ``DifferentialActionModelFreeFwdDynamics`` (ABA) with an actuation model
  tau = H u for the (nv, m) matrix ``mb_problem.model.actuation`` (``ActuationModelFull``
  when H = I, a Python constant-matrix actuation model otherwise), integrated by
  ``IntegratedActionModelEuler(dam, dt)``, which is semi-implicit: v+ = v + dt a,
  q+ = integrate(q, dt v+) -- geoddp's "semi_implicit" step;
* costs: ``ControlRegularisation`` -> ``ResidualModelControl(u_ref)``;
  ``FramePlacement`` -> ``ResidualModelFramePlacement`` (log6(M_ref^-1 oMf), Pinocchio's
  [linear; angular] order, the same as geoddp's); ``StateRegularisation`` ->
  ``ResidualModelState`` with x_ref = (q_ref, v_ref) (r = (difference(q_ref, q), v - v_ref)).
  Each with ``ActivationModelWeightedQuad(diag(W))``: 1/2 r^T diag(W) r. Only diagonal
  weights and constant (single-node) references are supported; anything else raises
  ``NotImplementedError`` naming the term;
* dt scaling: ``IntegratedActionModelEuler`` multiplies the running cost by dt, whereas
  geoddp's running cost is applied per step without dt, so the running weights given to
  Crocoddyl are W / dt. The terminal node is ``IntegratedActionModelEuler(dam_T, 0.)``,
  evaluated by ``calc(data, x)`` and not scaled.

Needs crocoddyl 3.2.1 with pin 4.0.0 (``pip install -e ".[bench]"``; the 3.2.1 wheels are
ABI-broken against pin 4.1.0). Run ``python benchmarks/multibody_peers.py`` for its table of the
built-in scenes beside Crocoddyl FDDP and DDP; ``benchmarks/robots.py`` builds its Crocoddyl
problems with this module and gives the current comparison (docs/benchmarks.md).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peers import _make_matrix_actuation  # noqa: E402  (the satellite benchmark's tau = H u model)

__all__ = ["crocoddyl_problem", "solve_crocoddyl", "check_cost_equivalence", "compare"]


def _diagonal(W: np.ndarray, what: str) -> np.ndarray:
    W = np.asarray(W, dtype=float)
    if W.ndim != 2 or W.shape[0] != W.shape[1]:
        raise NotImplementedError(f"{what}: expected a square weight matrix, got shape {W.shape}")
    if np.count_nonzero(W - np.diag(np.diag(W))):
        raise NotImplementedError(f"{what}: only diagonal weights are mapped to Crocoddyl "
                                  "(ActivationModelWeightedQuad); got a non-diagonal W")
    return np.diag(W).copy()


def _single(ref: np.ndarray, what: str) -> np.ndarray:
    """The one reference of a constant term ((1, ...) stack -> (...))."""
    if ref.shape[0] != 1:
        raise NotImplementedError(f"{what}: per-node (tracking) references are not mapped to Crocoddyl")
    return ref[0]


def _cost_model(crocoddyl: Any, pin: Any, state: Any, nu: int, cost_sum: Any, scale: float) -> Any:
    """A crocoddyl.CostModelSum with the terms of a geoddp MultibodyCostSum, weights x scale."""
    from geoddp.costs.multibody import ControlRegularisation, FramePlacement, StateRegularisation

    costs = crocoddyl.CostModelSum(state, nu)
    for i, t in enumerate(cost_sum.terms):
        name = f"{i}_{type(t).__name__}"
        if isinstance(t, ControlRegularisation):
            w = _diagonal(t.W, name)
            residual = crocoddyl.ResidualModelControl(state, _single(t.u_ref, name).copy())
        elif isinstance(t, FramePlacement):
            w = _diagonal(t.W, name)
            M_ref = pin.SE3(_single(t.M_ref, name).copy())
            residual = crocoddyl.ResidualModelFramePlacement(state, int(t.frame_id), M_ref, nu)
        elif isinstance(t, StateRegularisation):
            w = _diagonal(t.W, name)
            x_ref = np.concatenate([_single(t.q_ref, name), _single(t.v_ref, name)])
            residual = crocoddyl.ResidualModelState(state, x_ref, nu)
        else:
            raise NotImplementedError(f"{name}: no Crocoddyl mapping for {type(t).__name__}")
        costs.addCost(name, crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelWeightedQuad(w * scale), residual), 1.0)
    return costs


def crocoddyl_problem(mb_problem: Any) -> Any:
    """The ``crocoddyl.ShootingProblem`` equivalent to a semi-implicit geoddp Problem."""
    import crocoddyl
    import pinocchio as pin

    model = mb_problem.model
    if model.integrator != "semi_implicit":
        raise NotImplementedError(f"Crocoddyl's IntegratedActionModelEuler is semi-implicit Euler; "
                                  f"got a geoddp problem with integrator {model.integrator!r}")
    pm = model.pin_model
    state = crocoddyl.StateMultibody(pm)
    H = np.asarray(model.actuation, dtype=float)
    nu = H.shape[1]
    if H.shape == (pm.nv, pm.nv) and np.array_equal(H, np.eye(pm.nv)):
        actuation = crocoddyl.ActuationModelFull(state)
    else:
        actuation = _make_matrix_actuation(crocoddyl, state, H)
    dt = float(model.dt)
    # geoddp: sum_k l(x_k, u_k) (no dt); Crocoddyl's Euler integrates dt * l -> weights / dt
    run_costs = _cost_model(crocoddyl, pin, state, nu, mb_problem.running, 1.0 / dt)
    term_costs = _cost_model(crocoddyl, pin, state, nu, mb_problem.terminal, 1.0)
    run_dam = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, run_costs)
    term_dam = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, term_costs)
    running = crocoddyl.IntegratedActionModelEuler(run_dam, dt)
    terminal = crocoddyl.IntegratedActionModelEuler(term_dam, 0.0)
    x0 = np.concatenate([mb_problem.q0, mb_problem.v0])
    return crocoddyl.ShootingProblem(x0, [running] * mb_problem.horizon, terminal)


def check_cost_equivalence(mb_problem: Any, controls: np.ndarray) -> dict[str, float]:
    """Crocoddyl's and geoddp's total cost (and rollout) of the same controls.

    Returns ``geoddp``, ``crocoddyl`` (the two costs), ``rel`` (|difference| / |geoddp|) and
    ``state_err`` (max |x_croco - x_geoddp| over the rollout, configuration coordinates).
    """
    U = np.asarray(controls, dtype=float)
    Q, V = mb_problem.rollout(U)
    J_geo = mb_problem.cost(Q, V, U)
    problem = crocoddyl_problem(mb_problem)
    us = [u.copy() for u in U]
    xs = problem.rollout(us)
    J_cro = float(problem.calc(xs, us))
    X = np.array(xs)
    nq = mb_problem.model.nq
    return dict(geoddp=J_geo, crocoddyl=J_cro, rel=abs(J_cro - J_geo) / abs(J_geo),
                state_err=float(max(np.abs(X[:, :nq] - Q).max(), np.abs(X[:, nq:] - V).max())))


def solve_crocoddyl(mb_problem: Any, solver: str = "fddp", th_stop: float = 1e-9, max_iter: int = 500,
                    nthreads: int | None = None, initial_controls: np.ndarray | None = None) -> dict[str, Any]:
    """Solve the Crocoddyl equivalent of ``mb_problem`` from ``initial_controls`` (H, m) (zero
    controls by default) and their rollout.

    ``th_stop``: Crocoddyl's stopping threshold; in crocoddyl 3.2.1 ``stop`` is the expected
    cost decrease of the full step (docs/benchmarks.md), so this stops after a step predicted to
    lower J by less than th_stop. ``nthreads``: ``ShootingProblem.nthreads`` (None: Crocoddyl's
    default). Returns ``cost`` (geoddp's cost of a geoddp rollout of the returned controls),
    ``cost_solver`` (Crocoddyl's own), ``iterations`` (backward/forward passes), ``time_s``
    (wall time of ``solve`` only), ``controls`` (H, m), ``xs`` (H+1, nq + nv), ``status``,
    ``stop``.
    """
    import crocoddyl

    problem = crocoddyl_problem(mb_problem)
    if nthreads is not None:
        problem.nthreads = int(nthreads)
    if solver == "fddp":
        s = crocoddyl.SolverFDDP(problem)
    elif solver == "ddp":
        s = crocoddyl.SolverDDP(problem)
    else:
        raise ValueError(f"unknown crocoddyl solver {solver!r} (expected 'fddp' or 'ddp')")
    s.th_stop = float(th_stop)
    U0 = np.zeros((mb_problem.horizon, mb_problem.nu)) if initial_controls is None else np.asarray(initial_controls, float)
    us0 = [u.copy() for u in U0]
    xs0 = problem.rollout(us0)
    t0 = time.perf_counter()
    converged = s.solve(xs0, us0, int(max_iter), True)
    t = time.perf_counter() - t0
    U = np.array(s.us)
    return {
        "solver": f"crocoddyl-{solver}",
        "cost": float(mb_problem.total_cost(U)),
        "cost_solver": float(s.cost),
        # crocoddyl's iter is the 0-based index of the last iteration when converged
        "iterations": int(s.iter) + 1 if converged else int(s.iter),
        "time_s": t,
        "controls": U,
        "xs": np.array(s.xs),
        "status": "converged" if converged else "max_iter",
        "stop": float(s.stop),
    }


def compare(mb_problem: Any, runs: int = 1, seed: int = 0) -> list[dict[str, Any]]:
    """Cost check on random controls, then geoddp (switch) vs Crocoddyl FDDP and DDP.

    Times are the minimum over ``runs``."""
    from geoddp.solver import SolverOptions, solve

    rng = np.random.default_rng(seed)
    chk = check_cost_equivalence(mb_problem, rng.normal(size=(mb_problem.horizon, mb_problem.nu)))
    rows = []
    best = None
    for _ in range(runs):
        r = solve(mb_problem, SolverOptions(expansion="switch", verbose=False))
        if best is None or r.solve_time_s < best.solve_time_s:
            best = r
    rows.append(dict(solver="geoddp (switch)", cost=best.cost, iterations=best.iterations,
                     time_s=best.solve_time_s, status="converged" if best.converged else best.status))
    for name in ("fddp", "ddp"):
        res = min((solve_crocoddyl(mb_problem, name) for _ in range(runs)), key=lambda d: d["time_s"])
        rows.append(dict(solver=res["solver"], cost=res["cost"], iterations=res["iterations"],
                         time_s=res["time_s"], status=res["status"]))
    J_ref = rows[1]["cost"]
    for row in rows:
        row["rel_to_fddp"] = abs(row["cost"] - J_ref) / abs(J_ref)
    rows.insert(0, dict(check=chk))
    return rows


def main(argv: list[str] | None = None) -> int:
    from geoddp.scene import builtin as scenes

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--scenes", nargs="+", default=["spacecraft_docking", "space_manipulator"])
    args = ap.parse_args(argv)
    for name in args.scenes:
        p = getattr(scenes, name)(integrator="semi_implicit")
        rows = compare(p, runs=args.runs)
        chk = rows.pop(0)["check"]
        print(f"\n### {name}: H = {p.horizon}, dt = {p.model.dt}, nq = {p.model.nq}, nv = {p.model.nv}, m = {p.nu}")
        print(f"cost check on random controls: geoddp {chk['geoddp']:.15g}, crocoddyl {chk['crocoddyl']:.15g}, "
              f"rel {chk['rel']:.1e}, max state difference {chk['state_err']:.1e}\n")
        print("| solver | status | iterations | J* | rel. diff. to FDDP | time [s] (min of %d) |" % args.runs)
        print("|---|---|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['solver']} | {r['status']} | {r['iterations']} | {r['cost']:.12f} | "
                  f"{r['rel_to_fddp']:.1e} | {r['time_s']:.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
