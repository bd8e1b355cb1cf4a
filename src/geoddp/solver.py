"""Algorithm 1 of the paper: DDP on Lie groups.

One iteration: expand dynamics and costs along the nominal trajectory (first or second order,
Section IV), run the backward recursion (eqs. Qfunctions, dustar, backv, vfinal) with Q_uu
regularisation, then a forward pass with line search on gamma (eq. dustar, step 'steph').

Decisions the paper leaves open, and why:
* Regularisation (Remark rem:theta): when Q_uu + lambda I is not positive definite at some node,
  lambda <- max(1.9 lambda, reg_min) and the backward pass *restarts* from k = H. Continuing from
  the failing node would mix value functions of different lambda; with the second-order expansion
  the first iterations need this to produce descent directions. After an accepted step with
  gamma >= 0.5, lambda <- lambda / 10 (and to 0 below reg_min) so that the last iterations run
  unregularised and keep their superlinear rate.
* Line search: gamma in {1, 1/3, 1/9, ...} until J <= J_bar (the paper's test); if gamma falls
  below min_step, lambda is raised and the iteration is redone; past reg_max the solve stops.
* Stopping: |J_i - J_(i-1)| <= tol after an accepted step, or ||dJ/dU|| <= grad_tol (gradient by
  Lemma lemm:psi), or max_iter. A final backward pass at the returned iterate, with the exact
  second-order expansion and lambda = 0, gives the feedback gains and tells whether the point is
  a strict local minimum: for exact second-order DDP, all Q_uu positive definite is equivalent to
  a positive definite Hessian of J(U). A stationary point that fails this test is reported as a
  saddle, never as converged.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from . import kernels
from .problem import Problem
from .result import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_MAX_ITER,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_SADDLE,
    Result,
)
from .validate import choice, nonnegative_float, positive_float, positive_int

EXPANSIONS = ("first", "second", "switch")


@dataclass
class SolverOptions:
    """Options of :func:`solve`.

    Attributes:
        expansion: "first" (Phi, B only), "second" (with Theta, Gamma, Xi) or "switch" (first
            until J_i / J_0 < switch_ratio, then second; the paper's proposal), or after
            ``switch_after`` first-order iterations, whichever comes first.
        switch_ratio: sigma of the switch rule, in (0, 1).
        switch_after: also switch after this many first-order iterations. The paper's test alone
            never fires when the optimum keeps most of the initial cost (a tumbling start,
            1:1000 inertia, an underactuated body), where first order then grinds on at a
            linear rate for tens of iterations.
        tol: stop when |J_i - J_(i-1)| <= tol.
        grad_tol: stop when ||dJ/dU||_2 <= grad_tol.
        max_iter: maximum number of accepted iterations.
        reg_init, reg_min, reg_max: Q_uu regularisation lambda (start, floor, ceiling).
        reg_increase: factor on lambda when Q_uu is not positive definite (paper: 1.9).
        step_factor: line-search factor h (paper: 1/3); min_step: smallest gamma tried.
        verbose: print the per-iteration table.
        record_controls: keep the controls of every iterate in the result.
        backend: derivative backend: "compiled" (numba, default), "analytic" (numpy reference)
            or "pinocchio" (per-node Pinocchio calls, the source of truth).
    """

    expansion: str = "switch"
    switch_ratio: float = 0.1
    switch_after: int = 5
    tol: float = 1e-8
    grad_tol: float = 1e-10
    max_iter: int = 200
    reg_init: float = 0.0
    reg_min: float = 1e-8
    reg_max: float = 1e10
    reg_increase: float = 1.9
    step_factor: float = 1.0 / 3.0
    min_step: float = 1e-10
    verbose: bool = True
    record_controls: bool = False
    backend: str = "compiled"
    stream: TextIO | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.expansion = choice(self.expansion, "expansion", EXPANSIONS)
        self.switch_ratio = positive_float(self.switch_ratio, "switch_ratio")
        if not self.switch_ratio < 1.0:
            from .validate import InputError

            raise InputError("switch_ratio", f"expected a number in (0, 1), got {self.switch_ratio}")
        self.switch_after = positive_int(self.switch_after, "switch_after")
        self.tol = nonnegative_float(self.tol, "tol")
        self.grad_tol = nonnegative_float(self.grad_tol, "grad_tol")
        self.max_iter = positive_int(self.max_iter, "max_iter")
        self.reg_init = nonnegative_float(self.reg_init, "reg_init")
        self.reg_min = positive_float(self.reg_min, "reg_min")
        self.reg_max = positive_float(self.reg_max, "reg_max")
        self.reg_increase = positive_float(self.reg_increase, "reg_increase")
        self.step_factor = positive_float(self.step_factor, "step_factor")
        self.min_step = positive_float(self.min_step, "min_step")
        self.backend = choice(self.backend, "backend", ("compiled", "analytic", "pinocchio"))


class _Workspace:
    """Per-solve buffers (Crocoddyl's 'data'): allocated once, reused every iteration."""

    def __init__(self, problem: Problem, X: np.ndarray, Y: np.ndarray) -> None:
        # A trajectory is a pair of state arrays (X, Y) over H+1 nodes, opaque to the solver:
        # (R, Omega) on TSO(3), (q, v) for a multibody; nx is the dimension of its tangent space.
        H, m, nx = problem.horizon, problem.nu, problem.nx
        self.k = np.zeros((H, m))
        self.K = np.zeros((H, m, nx))
        self.grad = np.zeros((H, m))
        self.quu_eig = np.zeros(H)
        self.R = np.empty_like(X)
        self.Om = np.empty_like(Y)
        self.U = np.empty((H, m))
        # placeholders for first-order passes: the kernel never indexes them (memory stays O(H))
        self.empty_theta = np.zeros((0, nx, nx, nx))
        self.empty_gamma = np.zeros((0, nx, nx, m))
        self.empty_xi = np.zeros((0, nx, m, m))


class _Linearisation:
    """Expansion of dynamics and costs at one nominal trajectory."""

    def __init__(self, problem: Problem, R, Om, U, order: int, backend: str) -> None:
        self.exp = problem.expansion(R, Om, U, order, backend)
        self.run, self.term = problem.cost_derivatives(R, Om, U)
        self.order = order


def _backward(lin: _Linearisation, ws: _Workspace, reg: float) -> tuple[int, float, float]:
    e, r, t = lin.exp, lin.run, lin.term
    second = lin.order == 2
    return kernels.backward_pass(
        e.Phi, e.B, r.lx, r.lu, r.lxx, r.lux, r.luu, t.lx[0], t.lxx[0],
        e.Theta if second else ws.empty_theta,
        e.Gamma if second else ws.empty_gamma,
        e.Xi if second else ws.empty_xi,
        second, reg, ws.k, ws.K, ws.quu_eig,
    )


def _gradient(lin: _Linearisation, ws: _Workspace) -> np.ndarray:
    kernels.gradient(lin.exp.Phi, lin.exp.B, lin.run.lx, lin.run.lu, lin.term.lx[0], ws.grad)
    return ws.grad


def cost_gradient(problem: Problem, controls: np.ndarray) -> tuple[float, np.ndarray]:
    """J(U) and dJ/dU (H, m) by the psi recursion of Lemma lemm:psi (exact, not a DDP step)."""
    U = problem.check_controls(controls, "controls")
    R, Om = problem.rollout(U)
    lin = _Linearisation(problem, R, Om, U, 1, "compiled")
    ws = _Workspace(problem, R, Om)
    return problem.cost(R, Om, U), _gradient(lin, ws).copy()


# Saddle escape (see the module docstring). Not options: they only matter on degenerate problems.
_MAX_ESCAPES = 10
_ESCAPE_ALPHAS = 10.0 ** np.arange(2.0, -7.0, -1.0)  # times max(1, max|u|): step lengths tried


def _upper_sym(A: np.ndarray) -> np.ndarray:
    # kernels.backward_pass reads only the upper triangle of its symmetric blocks; mirror that.
    return np.triu(A) + np.triu(A, 1).T


def _node_quu(lin: _Linearisation, node: int) -> np.ndarray:
    """Q_uu (lambda = 0) at ``node``: numpy mirror of kernels.backward_pass from H-1 down to node.

    Only used on the (rare) saddle path, where the compiled pass stops at the failing node without
    returning its Q_uu. Nodes > node factorised there, so the recursion is well defined.
    """
    e, r, t = lin.exp, lin.run, lin.term
    second = lin.order == 2
    Vx, Vxx = t.lx[0].copy(), _upper_sym(t.lxx[0])
    for k in range(e.Phi.shape[0] - 1, node - 1, -1):
        P, Bk = e.Phi[k], e.B[k]
        Qx = r.lx[k] + P.T @ Vx
        Qu = r.lu[k] + Bk.T @ Vx
        Qxx = r.lxx[k] + P.T @ Vxx @ P
        Qux = r.lux[k] + Bk.T @ Vxx @ P
        Quu = r.luu[k] + Bk.T @ Vxx @ Bk
        if second:
            Qxx = Qxx + np.einsum("i,iab->ab", Vx, e.Theta[k])
            Qux = Qux + np.einsum("i,iac->ca", Vx, e.Gamma[k])
            Quu = Quu + np.einsum("i,iab->ab", Vx, e.Xi[k])
        Qxx, Quu = _upper_sym(Qxx), _upper_sym(Quu)
        if k == node:
            return Quu
        kk = np.linalg.solve(Quu, Qu)
        KK = np.linalg.solve(Quu, Qux)
        Vx = Qx - Qux.T @ kk
        Vxx = _upper_sym(Qxx - Qux.T @ KK)
    raise AssertionError("unreachable")


def _escape_saddle(problem: Problem, lin2: _Linearisation, node: int, ws: _Workspace, R, Om, U, J: float):
    """One step along negative curvature from a point whose exact Q_uu fails at ``node``.

    ``ws.K[node+1:]`` must hold the lambda = 0 gains of the exact pass that failed at ``node``.
    Returns (R, Om, U, J, info) with J < the given J, or None if no trial decreased J.
    """
    Quu = _node_quu(lin2, node)
    w, V = np.linalg.eigh(Quu)
    if not w[0] < 0.0:  # singular but not indefinite: no negative curvature to follow
        return None
    v = V[:, 0] * (1.0 if V[np.argmax(np.abs(V[:, 0])), 0] > 0 else -1.0)  # deterministic sign
    H, m = U.shape
    kff = np.zeros((H, m))
    K = ws.K.copy()
    K[: node + 1] = 0.0  # states up to node are unchanged (zeta = 0); stale gains must not matter
    Rn, Omn, Un = np.empty_like(R), np.empty_like(Om), np.empty_like(U)
    scale = max(1.0, float(np.max(np.abs(U))))
    best = None
    for alpha in _ESCAPE_ALPHAS * scale:
        for sgn in (1.0, -1.0):
            kff[node] = -sgn * alpha * v  # the rollout applies u_k = u_bar_k - gamma k_k - K_k zeta_k
            ok = problem.rollout_closed_loop(R, Om, U, kff, K, 1.0, Rn, Omn, Un)
            Jn = problem.cost(Rn, Omn, Un) if ok else np.inf
            if np.isfinite(Jn) and Jn < J and (best is None or Jn < best[3]):
                best = (Rn.copy(), Omn.copy(), Un.copy(), Jn,
                        {"node": int(node), "eigenvalue": float(w[0]), "alpha": float(sgn * alpha)})
    return best


def _print_header(out: TextIO) -> None:
    # One row per iteration: the nominal iterate's J and gradient, then the step taken from it.
    out.write(f"{'iter':>4} {'cost':>20} {'|grad|':>10} {'dJ':>11} {'lambda':>9} {'gamma':>7} {'exp':>6} {'restarts':>8}\n")


def _print_row(out: TextIO, it, J, g, dJ, lam, gamma, exp_name, restarts) -> None:
    out.write(f"{it:4d} {J:20.14e} {g:10.3e} {dJ:11.3e} {lam:9.2e} {gamma:7.4f} {exp_name:>6} {restarts:8d}\n")
    out.flush()


def solve(problem: Problem, options: SolverOptions | None = None, initial_controls: np.ndarray | None = None) -> Result:
    """Solve ``problem`` with geometric DDP (Algorithm 1) and return a :class:`Result`.

    Args:
        problem: the :class:`Problem` (model, costs, horizon, initial state).
        options: :class:`SolverOptions`; defaults follow the paper (switch, sigma = 0.1, tol 1e-8).
        initial_controls: (H, m) initial guess; zeros by default (as in the paper).
    """
    opt = options or SolverOptions()
    out = opt.stream or sys.stdout
    H, m = problem.horizon, problem.nu
    U = np.zeros((H, m)) if initial_controls is None else problem.check_controls(initial_controls)
    model = problem.model
    kernels.warm_up()
    t_start = time.perf_counter()
    timings = {"derivatives": 0.0, "backward": 0.0, "forward": 0.0, "final_check": 0.0}

    R, Om = problem.rollout(U)
    ws = _Workspace(problem, R, Om)
    J = problem.cost(R, Om, U)
    if not np.isfinite(J):
        raise FloatingPointError("the initial guess gives a non-finite cost: check the initial controls")
    J0 = J
    cost_hist, grad_hist, reg_hist, step_hist, exp_hist = [J], [], [], [], []
    time_hist = [time.perf_counter() - t_start]
    ctrl_hist = [U.copy()] if opt.record_controls else None
    use_second = opt.expansion == "second"
    lam = opt.reg_init
    status, message, converged = STATUS_MAX_ITER, f"reached max_iter = {opt.max_iter}", False
    lin = None
    escapes: list[dict] = []  # saddle escapes taken (module docstring, "Saddle escape")
    checked = None  # exact (order 2) linearisation at the current iterate, if the check ran there
    check_failed = {"node": -1}  # its lambda = 0 backward pass outcome (gains stay in ws.k, ws.K)
    if opt.verbose:
        _print_header(out)

    def check_and_escape(R, Om, U, J, lin2=None):
        # A stopping test passed at (R, Om, U): run the final check's exact lambda = 0 pass now and,
        # if Q_uu is indefinite somewhere, look for a negative-curvature step. Returns
        # (lin2, step or None); lin2 is reused by the final check when the solve stops here.
        # A caller that has just run that very pass (order 2, lambda = 0, success) hands in lin2.
        t0 = time.perf_counter()
        if lin2 is None:
            lin2 = _Linearisation(problem, R, Om, U, 2, opt.backend)
            failed, _, _ = _backward(lin2, ws, 0.0)
        else:
            failed = -1
        check_failed["node"] = failed
        step = None
        if failed >= 0 and len(escapes) < _MAX_ESCAPES:
            step = _escape_saddle(problem, lin2, failed, ws, R, Om, U, J)
        timings["final_check"] += time.perf_counter() - t0
        return lin2, step

    def take_escape(step, J, gnorm, lam):
        # Record an escape step as an accepted iteration (step_history holds |alpha|).
        R, Om, U, J_new, info = step
        info.update(iteration=it, cost_before=float(J), cost_after=float(J_new))
        escapes.append(info)
        if opt.verbose:
            _print_row(out, it, J, gnorm, J_new - J, lam, abs(info["alpha"]), "escape", 0)
        cost_hist.append(J_new)
        time_hist.append(time.perf_counter() - t_start)
        reg_hist.append(lam)
        step_hist.append(abs(info["alpha"]))
        exp_hist.append("second")
        if ctrl_hist is not None:
            ctrl_hist.append(U.copy())
        return R, Om, U, J_new

    def escaped(R, Om, U, J, lin2=None):
        # A stopping test passed at (R, Om, U): run the exact check and, at a saddle, take an escape
        # step as an iteration. Returns (R, Om, U, J, True) after an escape, else the same iterate
        # and False (the caller stops; ``checked`` then holds the check's linearisation).
        nonlocal checked, it
        checked, step = check_and_escape(R, Om, U, J, lin2)
        if step is None or it >= opt.max_iter:
            return R, Om, U, J, False
        if len(grad_hist) < len(cost_hist):  # the gradient of an iterate reached by a step
            grad_hist.append(float(np.linalg.norm(_gradient(checked, ws))))
        R, Om, U, J = take_escape(step, J, grad_hist[-1], lam)
        checked = None
        it += 1
        return R, Om, U, J, True

    it = 0
    while it < opt.max_iter:
        if opt.expansion == "switch" and not use_second and (
            (J0 > 0 and J / J0 < opt.switch_ratio) or it >= opt.switch_after
        ):
            use_second = True
        order = 2 if use_second else 1
        t0 = time.perf_counter()
        lin = _Linearisation(problem, R, Om, U, order, opt.backend)
        g = _gradient(lin, ws)
        gnorm = float(np.linalg.norm(g))
        timings["derivatives"] += time.perf_counter() - t0
        if len(grad_hist) == len(cost_hist) - 1:
            grad_hist.append(gnorm)
        if gnorm <= opt.grad_tol:
            R, Om, U, J, esc = escaped(R, Om, U, J)
            if esc:
                continue
            status, message, converged = STATUS_CONVERGED_GRAD, f"||dJ/dU|| = {gnorm:.3e} <= grad_tol", True
            break

        # Backward pass, restarted with a larger lambda while Q_uu is not positive definite.
        t0 = time.perf_counter()
        restarts = 0
        while True:
            failed, d1, d2 = _backward(lin, ws, lam)
            if failed < 0:
                break
            restarts += 1
            lam = max(lam * opt.reg_increase, opt.reg_min)
            if lam > opt.reg_max:
                break
        timings["backward"] += time.perf_counter() - t0
        lam_used, quu_min = lam, float(ws.quu_eig.min())
        if lam > opt.reg_max:
            status, message = STATUS_MAX_REG, f"Q_uu not positive definite with lambda up to {opt.reg_max:.1e}"
            break

        # At machine-precision stationarity the model's full-step decrease is below the round-off
        # of J: no trial step can show a decrease, so stop here (after the exact check) instead of
        # shrinking gamma through a dozen rollouts.
        roundoff = 4.0 * np.finfo(float).eps * abs(J)
        if abs(d1 - 0.5 * d2) <= roundoff and lam_used <= 1e-3 * quu_min:
            just_done = lin if (lin.order == 2 and lam_used == 0.0) else None
            R, Om, U, J, esc = escaped(R, Om, U, J, just_done)
            if esc:
                continue
            status, converged = STATUS_CONVERGED_COST, True
            message = f"predicted decrease {abs(d1 - 0.5 * d2):.1e} below the round-off of J"
            break

        # Forward pass with line search (Algorithm 1, inner repeat).
        t0 = time.perf_counter()
        gamma, accepted = 1.0, False
        while gamma >= opt.min_step:
            ok = problem.rollout_closed_loop(R, Om, U, ws.k, ws.K, gamma, ws.R, ws.Om, ws.U)
            J_new = problem.cost(ws.R, ws.Om, ws.U) if ok else np.inf
            if np.isfinite(J_new) and J_new <= J:
                accepted = True
                break
            gamma *= opt.step_factor
        timings["forward"] += time.perf_counter() - t0
        if not accepted:
            # No descent along this direction: be more conservative and redo the iteration.
            lam = max(lam * 10.0, opt.reg_min)
            if lam > opt.reg_max:
                status, message = STATUS_NO_DESCENT, "no gamma >= min_step decreased J, even with maximal regularisation"
                break
            continue

        dJ = J_new - J
        if opt.verbose:
            _print_row(out, it, J, gnorm, dJ, lam, gamma, "second" if use_second else "first", restarts)
        R, Om, U = ws.R.copy(), ws.Om.copy(), ws.U.copy()
        J = J_new
        it += 1
        cost_hist.append(J)
        time_hist.append(time.perf_counter() - t_start)
        reg_hist.append(lam)
        step_hist.append(gamma)
        exp_hist.append("second" if use_second else "first")
        if ctrl_hist is not None:
            ctrl_hist.append(U.copy())
        if gamma >= 0.5:
            lam = lam / 10.0 if lam / 10.0 >= opt.reg_min else 0.0
        # A small |dJ| after a damped step says nothing about optimality. The cost test counts
        # only after an undamped Newton-like step: gamma = 1 (or a model decrease below tol) and
        # lambda negligible against Q_uu (with S_u = 1e-8, lambda = 0.03 would dominate Q_uu and
        # shrink every step to a gradient step with a tiny dJ, far from the optimum).
        full_step_decrease = d1 - 0.5 * d2
        undamped = (gamma == 1.0 or abs(full_step_decrease) <= opt.tol) and lam_used <= 1e-3 * quu_min
        # ... unless J no longer changes beyond round-off: no step can make progress then.
        at_roundoff = abs(dJ) <= 4.0 * np.finfo(float).eps * abs(J)
        if abs(dJ) <= opt.tol and (undamped or at_roundoff):
            R, Om, U, J, esc = escaped(R, Om, U, J)
            if esc:
                continue
            status, message, converged = STATUS_CONVERGED_COST, f"|dJ| = {abs(dJ):.3e} <= tol", True
            break

    # Final check at the returned iterate: exact second-order expansion, lambda = 0.
    t0 = time.perf_counter()
    lin_final = checked if checked is not None else _Linearisation(problem, R, Om, U, 2, opt.backend)
    g = _gradient(lin_final, ws)
    gnorm = float(np.linalg.norm(g))
    if len(grad_hist) < len(cost_hist):
        grad_hist.append(gnorm)
    # the check already ran this exact lambda = 0 pass when a stopping test passed here
    failed = check_failed["node"] if checked is not None else _backward(lin_final, ws, 0.0)[0]
    is_min = failed < 0
    if not is_min:
        # gains for the user still need a factorisable Q_uu
        lam_f = opt.reg_min
        while _backward(lin_final, ws, lam_f)[0] >= 0 and lam_f < opt.reg_max:
            lam_f *= opt.reg_increase
    timings["final_check"] += time.perf_counter() - t0
    if converged and not is_min:
        converged = False
        status = STATUS_SADDLE
        message = (f"stationary (||dJ/dU|| = {gnorm:.3e}) but Q_uu is not positive definite at node {failed} "
                   "with the exact second-order expansion: the reduced Hessian is indefinite")
    if escapes:
        message += f"; escaped {len(escapes)} saddle point(s) along negative curvature"
    if status == STATUS_CONVERGED_COST and converged and gnorm > max(opt.grad_tol, 1e-6 * max(1.0, abs(J))):
        message += f"; note ||dJ/dU|| = {gnorm:.3e} at the final iterate"
    solve_time = time.perf_counter() - t_start
    if opt.verbose:
        out.write(f"{status} ({message}); J = {J:.12e}, ||grad|| = {gnorm:.3e}, {it} iterations, {solve_time*1e3:.1f} ms\n")

    return Result(
        times=np.arange(H + 1) * model.dt,
        controls=U,
        feedforward=ws.k.copy(),
        feedback=ws.K.copy(),
        **problem.trajectory_fields(R, Om),
        cost=float(J),
        iterations=it,
        converged=converged,
        status=status,
        message=message,
        cost_history=np.array(cost_hist),
        grad_norm_history=np.array(grad_hist),
        reg_history=np.array(reg_hist),
        step_history=np.array(step_hist),
        expansion_history=exp_hist,
        solve_time_s=solve_time,
        timings=timings,
        expansion=opt.expansion,
        integrator=model.integrator,
        dt=model.dt,
        control_history=np.array(ctrl_hist) if ctrl_hist is not None else None,
        time_history=np.array(time_hist),
        extra={"saddle_escapes": escapes} if escapes else {},
    )

