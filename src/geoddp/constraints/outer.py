"""The augmented Lagrangian outer loop around the exact second-order DDP.

Each outer iteration solves the inner problem min_U J(U) + sum_j phi_j(U; lambda_j, mu_j) (the PHR
terms of :mod:`.augmented`) with the unconstrained solver (Algorithm 1: first, second or switch,
the controls' box limits by projected Newton), warm-started from the previous controls, then

* updates every multiplier to its first-order estimate, lambda_j <- lhat_j (safeguarded: the
  estimates stay finite since mu does), as in ALGENCAN (Birgin & Martinez, Practical Augmented
  Lagrangian Methods for Constrained Optimization, SIAM 2014, Algorithm 4.1), where a multiplier
  update after every inner solve is what makes the iteration converge without mu -> infinity;
* raises mu_j by ``penalty_increase`` for each constraint whose violation
  V_j = max |lhat_j - lambda_j| / mu_j (= |c| for equalities, |max(c, -lambda / mu)| for
  inequalities: feasibility and complementarity in the constraint's units) fell by less than
  ``violation_decrease`` (Nocedal & Wright, Numerical Optimization, 2nd ed., Algorithm 17.4 and
  the same test in Conn, Gould & Toint's LANCELOT, 1992);
* tightens the inner (absolute) cost tolerance with the violation: omega = inner_tol_initial V /
  V_0, and once omega reaches the solver's own threshold (its ``tol``, or its relative default
  rtol |J|) the final inner solve runs with the solver's own options (so its certificate is the
  usual one).

Only that final inner solve is certified: the ones before it only warm-start the next, and stop
at their stopping test without the final check's exact pass (``solve(..., certify=False)``); a
loop that ends after one of them (infeasible, max_outer_iter, non-finite) runs the final check
alone at its iterate (:func:`geoddp.solver.loop.check`), so the result's gains, gradient and
certificate are always those of the returned controls.

It stops at a KKT point: every V_j <= constraint_tol after an inner solve at the full tolerance
that converged (its certificate: Newton decrement below its threshold with a positive definite
reduced Hessian, at multipliers lambda whose estimates lhat it then returns: the gradient of the
augmented Lagrangian at lambda is the Lagrangian's at lhat, so that certificate is stationarity of
the Lagrangian). "converged" means exactly that. A constraint still violated at mu = penalty_max,
or whose violation no longer falls as its penalty grows (by less than 1 % over three increases),
ends the solve as infeasible, reporting the smallest violation reached.

The Result is the solver's, with the constraints' report in ``extra["constraints"]`` and the KKT
numbers added to ``extra["optimality"]`` (JSON-ready; no NaN).
"""
from __future__ import annotations

import dataclasses
import sys
import time
from typing import Any

import numpy as np

from ..problem.contract import Trajectory
from ..solver.result import Result
from ..solver import SolverOptions, solve
from ..solver.loop import check
from ..solver.status import STATUS_LINALG, STATUS_MAX_ITER, STATUS_NON_FINITE
from ..validate import InputError
from .augmented import multiplier_estimate

__all__ = ["solve_constrained", "STATUS_KKT", "STATUS_INFEASIBLE", "STATUS_OUTER_MAX_ITER", "STATUS_INNER_FAILED",
           "CONSTRAINED_STATUSES"]

STATUS_KKT = "converged: KKT point (constraints within constraint_tol, Lagrangian stationary)"
STATUS_INFEASIBLE = "stopped: infeasible (a constraint stayed violated as its penalty grew)"
STATUS_OUTER_MAX_ITER = "stopped: max_outer_iter reached"
STATUS_INNER_FAILED = "stopped: the constraints hold but the last inner solve did not converge"
CONSTRAINED_STATUSES = (STATUS_KKT, STATUS_INFEASIBLE, STATUS_OUTER_MAX_ITER, STATUS_INNER_FAILED)

# Infeasibility before penalty_max: a constraint's violation fell by less than 1 % over this many
# increases of its penalty (x penalty_increase each).
STALL_INCREASES = 3
# A multiplier estimate beyond this is clipped (ALGENCAN's safeguard): it keeps the inner problem
# finite when a constraint cannot be met (mu grows, lambda + mu c with it).
_MULTIPLIER_MAX = 1e20


def _violation(c: np.ndarray, lam: np.ndarray, lhat: np.ndarray, mu: float, equality: bool) -> np.ndarray:
    """Per row: |c| (equality) or |max(c, -lambda / mu)| = |lhat - lambda| / mu (inequality)."""
    return np.abs(c) if equality else np.abs(lhat - lam) / mu


def _feasibility(c: np.ndarray, equality: bool) -> np.ndarray:
    """Per row: |c| (equality) or max(0, c) (inequality)."""
    return np.abs(c) if equality else np.maximum(c, 0.0)


def solve_constrained(problem: Any, options: SolverOptions | None = None,
                      initial_controls: np.ndarray | None = None) -> Result:
    """Solve a :class:`geoddp.constraints.ConstrainedProblem` by the augmented Lagrangian outer loop.

    Args:
        problem: the constrained problem (its ``options`` are the outer loop's:
            :class:`geoddp.constraints.ConstraintOptions`).
        options: the inner solver's :class:`geoddp.solver.SolverOptions` (expansion, tolerances,
            max_iter per inner solve); ``verbose`` prints one line per outer iteration.
        initial_controls: (H, m) initial guess (zeros, clipped into the limits, by default).

    Returns:
        A :class:`geoddp.solver.result.Result` at the last iterate: ``cost`` is the objective J (without
        the augmented terms); ``iterations`` counts the inner iterations in total; the histories
        are the inner solves' one after another (their costs are the augmented Lagrangian, which
        equals J at a KKT point to within the constraint tolerance); ``feedforward`` and
        ``feedback`` are the last inner solve's gains; ``extra["constraints"]`` the report
        (:func:`_report`), ``extra["optimality"]`` the last inner certificate plus
        ``constraint_violation``, ``complementarity`` and ``lagrangian_stationarity``.

    With no constraints it is :func:`geoddp.solver.solve` of the unconstrained problem, bit for bit.
    """
    if not all(hasattr(problem, a) for a in ("placed", "augmented", "options", "problem")):
        raise InputError("problem", f"expected a geoddp.constraints.ConstrainedProblem, got {type(problem).__name__}")
    if options is not None and not isinstance(options, SolverOptions):
        raise InputError("options", f"expected a geoddp.solver.SolverOptions, got {type(options).__name__}")
    opt = options or SolverOptions()
    if not problem.placed:
        return solve(problem.problem, opt, initial_controls)
    al = problem.options
    out = opt.stream if opt.stream is not None else sys.stdout
    t_start = time.perf_counter()
    placed = problem.placed
    U = None if initial_controls is None else problem.check_controls(initial_controls)
    lam = [np.zeros((p.nodes.size, p.bound.rows)) for p in placed]
    mu = [al.penalty_initial] * len(placed)
    V_prev = [np.inf] * len(placed)
    raised: list[list[float]] = [[] for _ in placed]  # each constraint's violation at its penalty increases
    # The inner solves' cost tolerance omega (absolute, units of J) shrinks with the violation; the
    # last one runs at the solver's own stopping rule (``final``: opt's tol, or its default rtol |J|).
    omega = max(opt.cost_tolerance(0.0), al.inner_tol_initial)
    final = False
    V0 = None
    results: list[Result] = []
    outer: list[dict[str, Any]] = []
    best = np.inf
    status, message = STATUS_OUTER_MAX_ITER, f"{al.max_outer_iter} outer iterations without reaching a KKT point"
    converged = False
    if opt.verbose:
        out.write(f"{'outer':>5} {'inner tol':>9} {'max mu':>9} {'J':>16} {'violation':>10} {'feasibility':>11} "
                  f"{'inner':>5}  inner status\n")
    for k in range(al.max_outer_iter):
        inner = dataclasses.replace(opt, verbose=False) if final else \
            dataclasses.replace(opt, tol=omega, rtol=None, verbose=False)
        # only the final inner solve is certified (its exact check at the returned iterate): the
        # others only warm-start the next one, and stop at their stopping test
        aug = problem.augmented(lam, mu)
        r = solve(aug, inner, U, certify=final)
        results.append(r)
        U = r.controls
        traj = Trajectory(r.q, r.v, r.controls)
        cs = problem.values(traj)
        lhat = [np.clip(multiplier_estimate(c, l_, m, p.bound.equality), -_MULTIPLIER_MAX, _MULTIPLIER_MAX)
                for p, c, l_, m in zip(placed, cs, lam, mu)]
        V = [float(np.max(_violation(c, l_, lh, m, p.bound.equality), initial=0.0))
             for p, c, l_, lh, m in zip(placed, cs, lam, lhat, mu)]
        feas = max(float(np.max(_feasibility(c, p.bound.equality), initial=0.0)) for p, c in zip(placed, cs))
        best = min(best, feas)
        Vmax = max(V)
        J = float(problem.trajectory_cost(traj))
        tol_k = opt.cost_tolerance(J) if final else omega  # this inner solve's cost tolerance
        outer.append({"iteration": k, "inner_tol": tol_k, "penalty_max": max(mu), "cost": J,
                      "violation": Vmax, "feasibility": feas, "inner_iterations": int(r.iterations),
                      "inner_status": r.status})
        if opt.verbose:
            out.write(f"{k:5d} {tol_k:9.1e} {max(mu):9.1e} {J:16.9e} {Vmax:10.3e} {feas:11.3e} {r.iterations:5d}  "
                      f"{r.status}\n")
        if r.status in (STATUS_NON_FINITE, STATUS_LINALG) or not np.isfinite(J):
            status, message = r.status, f"inner solve {k}: {r.message}"
            break
        at_full_tol = final
        if Vmax <= al.constraint_tol:
            lam = lhat
            if at_full_tol and r.converged:
                status, converged = STATUS_KKT, True
                message = (f"max violation {Vmax:.2e} <= constraint_tol {al.constraint_tol:.1e} after {k + 1} outer "
                           f"iterations; the last inner solve: {r.message}")
                break
            if at_full_tol:  # feasible, but the inner solve at full tolerance did not certify its point
                status, message = STATUS_INNER_FAILED, f"inner solve {k}: {r.status} ({r.message})"
                break
            final = True  # the final inner solve at the solver's own tolerance
            continue
        if r.status == STATUS_MAX_ITER:
            # the inner solve ran out of iterations short of its tolerance: its point says nothing
            # about the multipliers and penalties yet; it goes on, warm-started, with the same ones
            # (max_outer_iter bounds the repeats)
            continue
        # penalties: raised where the violation did not fall enough. Infeasible: a constraint still
        # violated with its penalty at penalty_max, or whose violation fell by less than 1 % over
        # its last STALL_INCREASES penalty increases (a factor 1000 by default) while its penalty
        # term mu/2 |c+|^2 outweighs J: the inner solve then minimises the violation itself, which
        # is (locally) the smallest the dynamics allow, and a larger mu would only distort J. (The
        # second condition keeps a feasible problem whose constraint needs a large mu before it
        # moves at all, e.g. the keep-out cone at mu <= 1e3, from being called infeasible.)
        stuck = [j for j in range(len(placed)) if V[j] > al.constraint_tol and V[j] > al.violation_decrease * V_prev[j]]
        # Only a converged inner solve (a minimiser of the augmented Lagrangian) tells.
        stalled = [j for j in stuck if r.converged and (mu[j] >= al.penalty_max or (
            len(raised[j]) >= STALL_INCREASES and V[j] > 0.99 * raised[j][-STALL_INCREASES]
            and 0.5 * mu[j] * float(np.sum(_feasibility(cs[j], placed[j].bound.equality) ** 2)) > abs(J)))]
        if stalled:
            j = stalled[0]
            status = STATUS_INFEASIBLE
            why = (f"with its penalty at penalty_max = {al.penalty_max:.1e}" if mu[j] >= al.penalty_max else
                   f"after {STALL_INCREASES} penalty increases (mu = {mu[j]:.1e}) that reduced it by less than 1 %")
            message = (f"constraint {_name(problem, j)!r} violated by {V[j]:.3e} {why}; the smallest violation "
                       f"reached: {best:.3e}")
            lam = lhat
            break
        for j in stuck:
            if r.converged:
                raised[j].append(V[j])
            mu[j] = min(mu[j] * al.penalty_increase, al.penalty_max)
        V_prev = V
        lam = lhat
        V0 = Vmax if V0 is None else V0
        omega = min(omega, al.inner_tol_initial * Vmax / V0) if V0 > 0 else 0.0
        final = omega <= opt.cost_tolerance(J)
    # the loop ended after an uncertified inner solve (infeasible, max_outer_iter, non-finite): its
    # iterate's gains, gradient and certificate by the final check alone
    last_check = None
    if not final:
        try:
            last_check = check(aug, dataclasses.replace(opt, verbose=False), U)
        except InputError:  # a non-finite cost there: the last inner solve's gains stay
            pass
    result = _assemble(problem, opt, results, lam, mu, outer, status, message, converged, best,
                       time.perf_counter() - t_start, last_check)
    if opt.verbose:
        out.write(f"{status} ({message}); J = {result.cost:.12e}, {len(results)} outer and {result.iterations} inner "
                  f"iterations, {result.solve_time_s * 1e3:.1f} ms\n")
    return result


def _name(problem: Any, j: int) -> str:
    return problem.kinds[j][1].name


def _assemble(problem: Any, opt: SolverOptions, results: list[Result], lam: list[np.ndarray], mu: list[float],
              outer: list[dict[str, Any]], status: str, message: str, converged: bool, best: float,
              solve_time: float, last_check: Result | None = None) -> Result:
    """One Result from the inner solves: the last one's trajectory and gains, the histories one
    after another, the constraint report and the KKT numbers. An uncertified inner solve that ended
    at an iterate reached by a step has no gradient there (NaN): the next solve's at the same
    controls (its merit's, at the updated multipliers) stands in; ``last_check``: the final check
    at the last iterate when the last inner solve was uncertified (its gains, gradient, certificate)."""
    last = results[-1]
    grads = [r.grad_norm_history.copy() for r in results]
    for g, nxt in zip(grads, grads[1:]):
        if g.size and np.isnan(g[-1]):
            g[-1] = nxt[0]
    if last_check is not None:
        if grads[-1].size and np.isnan(grads[-1][-1]):
            grads[-1][-1] = last_check.grad_norm
        gains = last_check
    else:
        gains = last
    traj = Trajectory(last.q, last.v, last.controls)
    cs = problem.values(traj)
    t0 = 0.0
    times = []
    for r in results:
        times.append(r.time_history + t0)
        t0 += r.solve_time_s
    timings: dict[str, float] = {}
    for r in results:
        for key, val in r.timings.items():
            timings[key] = timings.get(key, 0.0) + float(val)
    report = _report(problem, cs, lam, mu, outer, best)
    optimality = dict(gains.extra.get("optimality") or {})
    optimality.update(constraint_violation=report["max_violation"], complementarity=report["complementarity"],
                      lagrangian_stationarity=float(grads[-1][-1]) if np.isfinite(grads[-1][-1]) else None)
    records = [r.control_history for r in results]
    extra = {k: v for k, v in last.extra.items() if k != "optimality"}
    extra.update(optimality=optimality, constraints=report)
    return type(last)(  # the kind of the inner results (satellite or multibody)
        times=last.times, q=last.q, v=last.v, model=last.model, controls=last.controls,
        feedforward=gains.feedforward, feedback=gains.feedback, cost=float(problem.trajectory_cost(traj)),
        iterations=int(sum(r.iterations for r in results)), converged=bool(converged), status=status, message=message,
        cost_history=np.concatenate([results[0].cost_history[:1]] + [r.cost_history[1:] for r in results]),
        grad_norm_history=np.concatenate([grads[0][:1]] + [g[1:] for g in grads]),
        reg_history=np.concatenate([r.reg_history for r in results]),
        step_history=np.concatenate([r.step_history for r in results]),
        expansion_history=[e for r in results for e in r.expansion_history],
        control_history=None if any(c is None for c in records) else np.concatenate(
            [records[0][:1]] + [c[1:] for c in records]),
        time_history=np.concatenate([times[0][:1]] + [t[1:] for t in times]),
        solve_time_s=solve_time, timings=timings, expansion=opt.expansion, dt=last.dt, limits=last.limits,
        active_set=last.active_set, extra=extra,
    )


def _report(problem: Any, cs: list[np.ndarray], lam: list[np.ndarray], mu: list[float],
            outer: list[dict[str, Any]], best: float) -> dict[str, Any]:
    """The constraints' part of the result (JSON-ready plain data):

    * ``constraint_tol``, ``max_violation`` (max over rows of |c| for equalities, max(0, c) for
      inequalities), ``smallest_violation`` (over the outer iterations), ``complementarity``
      (max over inequality rows of |lambda c|), ``outer_iterations``, ``inner_iterations``;
    * ``outer``: one dict per outer iteration (inner tolerance, largest penalty, J, violation,
      feasibility, inner iterations and status);
    * ``items``: per constraint ``name``, ``type``, ``where`` ("path" | "terminal"),
      ``equality``, ``definition`` (its parameters), ``nodes`` (the node indices k), ``labels``
      (its rows), ``values`` (N, nc), ``multipliers`` (N, nc), ``active`` (N, nc) (an
      inequality row with a positive multiplier or c >= -constraint_tol; every equality row),
      ``max_violation``, ``penalty``.
    """
    tol = problem.options.constraint_tol
    items = []
    comp = 0.0
    for p, (where, c_obj), c, l_, m in zip(problem.placed, problem.kinds, cs, lam, mu):
        eq = p.bound.equality
        feas = _feasibility(c, eq)
        if eq:
            active = np.ones(c.shape, dtype=bool)
        else:
            active = (l_ > 0.0) | (c >= -tol)
            comp = max(comp, float(np.max(np.abs(l_ * c), initial=0.0)))
        items.append({"name": c_obj.name, "type": c_obj.type, "where": where, "equality": bool(eq),
                      "definition": c_obj.describe(), "nodes": p.nodes.tolist(), "labels": list(p.bound.labels),
                      "values": c.tolist(), "multipliers": l_.tolist(), "active": active.tolist(),
                      "active_nodes": int(np.any(active, axis=1).sum()),
                      "max_violation": float(np.max(feas, initial=0.0)), "penalty": float(m)})
    return {"constraint_tol": tol, "max_violation": max(it["max_violation"] for it in items),
            "smallest_violation": float(best), "complementarity": comp, "outer_iterations": len(outer),
            "inner_iterations": int(sum(o["inner_iterations"] for o in outer)), "outer": outer, "items": items}
