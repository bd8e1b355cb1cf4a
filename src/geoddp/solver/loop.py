"""Algorithm 1 of the paper: DDP on Lie groups, as a short loop over named steps.

One iteration: expand dynamics and costs along the nominal trajectory (first or second order,
Section IV; :meth:`_Solve.direction`), run the backward recursion (eqs. Qfunctions, dustar, backv,
vfinal) with Q_uu regularisation (:mod:`.backward`), then a forward pass with line search on gamma
(eq. dustar, step 'steph'; :mod:`.forward`), a stopping test and the regularisation update.

Decisions the paper leaves open, and why:
* Regularisation (Remark rem:theta): when Q_uu + lambda I is not positive definite at some node,
  lambda <- max(1.9 lambda, reg_min) and the backward pass *restarts* from k = H. Continuing from
  the failing node would mix value functions of different lambda; with the second-order expansion
  the first iterations need this to produce descent directions (30-46 rungs in the first one on
  the benchmark cases: the lowest rung that factorises is found by galloping and bisection,
  :mod:`.ladder`, in 9-11 passes, or 6-8 rounds of two side by side, instead of one pass per
  rung). After an accepted step with gamma >= 0.5, lambda <- lambda / 10 (and to 0 below
  reg_min) so that the last iterations run unregularised and keep their superlinear rate.
* Line search: gamma in {1, 1/3, 1/9, ...} until J <= J_bar (the paper's test); if gamma falls
  below min_step, lambda is raised and the iteration is redone; past reg_max the solve stops.
* First order and the switch: a first-order iteration drops the dynamics' second-order terms;
  where the costs offer it (multibody residual terms) it also takes their Gauss-Newton Hessians
  (``Linearisation.gauss_newton``), so the model is FDDP's. "switch" hands over to second order
  after ``switch_after`` iterations, when a first-order step passes the cost test below (second
  order then finishes instead of stopping at a linearly converging point) or, for an exact
  first-order model only, at the paper's J_i / J_0 < sigma. With a Gauss-Newton model,
  switch_after counts full steps only and waits while they converge superlinearly, and the cost
  test first runs the exact check, which may certify the point (:meth:`_Solve.expansion_order`,
  :meth:`_Solve.certified_deep`). A Gauss-Newton step cut below gamma = 0.1 raises lambda.
* Early certification (Gauss-Newton first order, no input on a control limit; the satellite
  keeps the paper's rules): an
  exact lambda = 0 pass whose Newton decrement is at most CERTIFY_EARLY = 0.1 of the final
  check's threshold ends the solve at its iterate, before the step (the final check reuses it),
  and switch linearises exactly one iterate early when Gauss-Newton predicts that its next step
  would change J by less than ANTICIPATE = 0.01 of that threshold (:meth:`_Solve.converged_next`).
  Crocoddyl stops on the direction it computed at the previous iterate; here the certificate at
  the returned iterate costs one exact linearisation, and these rules keep it to one.
* Stopping: |J_i - J_(i-1)| <= tau after an accepted step, or ||dJ/dU|| <= grad threshold
  (gradient by Lemma lemm:psi), or max_iter. tau = max(tol, rtol max(|J_i|, ZERO_COST |J_0|))
  (:meth:`SolverOptions.cost_tolerance`): relative to |J| by default (rtol = 1e-11), so that
  scaling every weight by c scales J, dJ, the decrement and tau alike and the solve is the same;
  the paper's absolute tol = 1e-8 (the satellite scenes) when ``tol`` is set. A final backward
  pass at the returned iterate, with the exact
  second-order expansion and lambda = 0, gives the feedback gains and tells whether the point is
  a strict local minimum: for exact second-order DDP, all Q_uu positive definite is equivalent to
  a positive definite Hessian of J(U). A stationary point that fails this test is reported as a
  saddle, never as converged, unless a step along negative curvature (:mod:`.saddle`) escapes it.

* Control limits (issue 15; a problem whose ``control_bounds()`` is not None): the backward pass
  minimises each node's Q model over the box (projected Newton, compiled for every model;
  :func:`.backward.backward`), the forward pass clamps u_k into the box after the feedback law
  (every iterate feasible; the line search and the tests above are unchanged, so J never
  rises), and the gradient tests use the projected gradient (components pushing into an active
  bound do not count). The final check reports the KKT residual and the active set. Indefinite
  Q_uu: the same lambda rule, applied to the whole Q_uu + lambda I before each box QP.

The solver talks to the problem only through :class:`geoddp.contract.OptimalControlProblem`.
"""
from __future__ import annotations

import sys
import time
from typing import TextIO

import numpy as np

from ..contract import Linearisation, OptimalControlProblem, Trajectory
from ..result import Result
from ..validate import InputError
from ..limits import active_set, projected_gradient
from .backward import Workspace, backward, factorisable_gains, gradient, regularised_backward
from .forward import line_search
from .history import History
from .options import SolverOptions
from .saddle import MAX_ESCAPES, escape_saddle
from .status import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_MAX_ITER,
    STATUS_LINALG,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_NON_FINITE,
    STATUS_SADDLE,
    STATUS_STALLED,
)

_EPS = np.finfo(float).eps

# Early certification (solves with a Gauss-Newton first order: multibody costs). A point whose
# exact lambda = 0 pass factorises with a Newton decrement (1/2) g^T H^-1 g at most CERTIFY_EARLY
# times the final check's threshold is returned as it stands: its J is within a tenth of that of
# the quadratic model's minimum, and one more Newton step would cost an exact linearisation at
# the new point only to certify it (on the real robots the final check was 21-35 % of a solve).
CERTIFY_EARLY = 0.1
# Switch linearises exactly one iterate early when Gauss-Newton converges superlinearly and the
# next decrease it predicts, dJ_i^2 / dJ_(i-1), is below ANTICIPATE times the threshold: that
# exact pass is then the certificate, and the Gauss-Newton iteration it replaces is saved. The
# prediction ran 1.7x (UR5) and 7x (Solo12) below the decrement found, hence ANTICIPATE =
# CERTIFY_EARLY / 10; when the pass does not certify, it is the first second-order iteration.
ANTICIPATE = 0.01
# With inputs on a control limit the certificate users read is the KKT residual; there a
# first-order cost test's exact check stops the solve only at 1e-3 of the threshold (as before
# early certification: at 0.1 the thrust-limited quadrotor stopped with a KKT residual of 5e-4).
CERTIFY_WITH_LIMITS = 1e-3


def cost_gradient(problem: OptimalControlProblem, controls: np.ndarray) -> tuple[float, np.ndarray]:
    """J(U) and dJ/dU (H, m) by the psi recursion of Lemma lemm:psi (exact, not a DDP step)."""
    U = problem.check_controls(controls, "controls")
    traj = problem.trajectory(U)
    ws = Workspace(problem.horizon, problem.nu, problem.nx)
    return problem.trajectory_cost(traj), gradient(problem.linearise(traj, 1), ws).copy()


def _print_header(out: TextIO) -> None:
    # One row per iteration: the nominal iterate's J and gradient, then the step taken from it;
    # 'rungs': how many rungs of its ladder lambda climbed there (the paper's restarts; the passes
    # that found them are fewer, :mod:`.ladder`)
    out.write(f"{'iter':>4} {'cost':>20} {'|grad|':>10} {'dJ':>11} {'lambda':>9} {'gamma':>7} {'exp':>6} {'rungs':>8}\n")


def _print_row(out: TextIO, it, J, g, dJ, lam, gamma, exp_name, rungs) -> None:
    out.write(f"{it:4d} {J:20.14e} {g:10.3e} {dJ:11.3e} {lam:9.2e} {gamma:7.4f} {exp_name:>6} {rungs:8d}\n")
    out.flush()


class _Solve:
    """The state of one solve: the iterate, lambda, the counters, the recorder and the buffers."""

    def __init__(self, problem: OptimalControlProblem, opt: SolverOptions, U: np.ndarray) -> None:
        self.problem, self.opt = problem, opt
        self.out = opt.stream or sys.stdout
        self.t_start = time.perf_counter()
        self.timings = {"derivatives": 0.0, "backward": 0.0, "forward": 0.0, "final_check": 0.0}
        self.traj: Trajectory = problem.trajectory(U)
        # control limits (issue 15): an optional member of the contract
        self.bounds = problem.control_bounds() if hasattr(problem, "control_bounds") else None
        self.ws = Workspace(problem.horizon, problem.nu, problem.nx, self.bounds)
        self.J = problem.trajectory_cost(self.traj)
        if not np.isfinite(self.J):
            # bad input, not a solver failure: nothing finite to return (huge controls, a spin
            # that overflows the integrator, a degenerate model)
            raise InputError("initial_controls", f"the initial guess gives a non-finite cost J = {self.J}: the "
                             "rollout or the cost overflowed; start from smaller controls or check the model")
        self.J0 = self.J
        self.hist = History(self.J, U, self.t_start, opt.record_controls)
        self.use_second = opt.expansion == "second"
        self.first_order_gauss_newton = False  # what the last order-1 linearisation said
        self.first_steps: list[tuple[float, float]] = []  # (|dJ|, gamma) of the accepted first-order steps
        self.pending: Linearisation | None = None  # exact linearisation at the iterate, for its next direction
        self.lam = opt.reg_init
        self.it = 0
        self.status, self.message, self.converged = STATUS_MAX_ITER, f"reached max_iter = {opt.max_iter}", False
        self.escapes: list[dict] = []
        self.checked: Linearisation | None = None  # exact (order 2) linearisation at the iterate, if checked there
        self.checked_node = -1  # its lambda = 0 backward pass outcome (gains stay in ws.k, ws.K)
        self.checked_d = (np.nan, np.nan)  # and that pass's (d1, d2)
        self.optimality: dict = {}
        if opt.verbose:
            _print_header(self.out)

    # ------------------------------------------------------------------ steps
    def expansion_order(self) -> int:
        """The switch rule: second order after switch_after iterations, or once J_i / J_0 <
        switch_ratio (the paper's test) unless the first-order model is a Gauss-Newton one, or
        when first order passes its cost test (:meth:`iterate`)."""
        opt = self.opt
        # The paper's test hands over early because its first-order model carries exact, possibly
        # indefinite cost Hessians. A Gauss-Newton model (lin.gauss_newton) has positive
        # semidefinite ones and keeps converging like FDDP; handing over at J / J_0 < sigma
        # replaced those iterations by second-order ones 2-4x dearer doing the same work (with
        # the rules below, switch solves on the real robots take 0.26-0.59x the time they took:
        # benchmarks/speed_vs_main_2026-11-25b.log).
        paper_test = not self.first_order_gauss_newton and self.J0 > 0 and self.J / self.J0 < opt.switch_ratio
        # ... and while Gauss-Newton converges superlinearly (a full step that cut the decrease
        # 100x: small residuals), switch_after waits: the cost test comes within an iteration or
        # two, and a second-order iteration there costs 2-4x a first-order one (UR5, Solo12). A
        # fast linear rate (the space manipulator's 0.02-0.03 per step) still hands over.
        superlinear = self.superlinear()
        # ... and counts only full Gauss-Newton steps: a step the line search damped says the
        # iterate is still far (the line search, not the model, sets the step; with control
        # limits, the box), where a second-order iteration's extra cost buys nothing (Solo12
        # reorienting: 34 -> 17 iterations, 3x faster; thrust-limited quadrotor 28 -> 27); at
        # most 4 switch_after iterations in all, so that damped steps cannot hold it for ever
        if self.first_order_gauss_newton:
            full = sum(1 for _, g in self.first_steps if g == 1.0)
            due = full >= opt.switch_after or self.it >= 4 * opt.switch_after
        else:
            due = self.it >= opt.switch_after
        if opt.expansion == "switch" and not self.use_second and (paper_test or (due and not superlinear)
                                                                 or self.converged_next()):
            self.use_second = True
        return 2 if self.use_second else 1

    def superlinear(self) -> bool:
        """The last first-order step was a full Gauss-Newton step that cut the decrease of the one
        before at least 100x."""
        return self.first_order_gauss_newton and len(self.first_steps) >= 2 and \
            self.first_steps[-1][1] == 1.0 and self.first_steps[-1][0] <= 0.01 * self.first_steps[-2][0]

    def converged_next(self) -> bool:
        """Gauss-Newton predicts that its next step changes J by less than ANTICIPATE of the final
        check's threshold: the last two first-order steps were full and the last cut the decrease
        at least 100x (superlinear), so the next decrease is about dJ_i^2 / dJ_(i-1)."""
        if not self.certifies_early() or not self.superlinear():
            return False
        (d_prev, g_prev), (d_last, _) = self.first_steps[-2:]
        return g_prev == 1.0 and 0.0 < d_prev and d_last * d_last / d_prev <= ANTICIPATE * self.newton_threshold()

    def grad_norm(self, lin: Linearisation) -> float:
        """||dJ/dU||, or with control limits the norm of the projected gradient (the components
        that push into an active bound do not count: the KKT residual of the box problem)."""
        g = gradient(lin, self.ws)
        if self.bounds is not None:
            g = projected_gradient(self.traj.u, g, *self.bounds)
        return float(np.linalg.norm(g))

    def direction(self, order: int) -> tuple[Linearisation, float]:
        """Linearise at the iterate; returns it and ||dJ/dU|| (projected with limits; recorded
        once per iterate)."""
        t0 = time.perf_counter()
        if order == 2 and self.pending is not None:  # the check's exact linearisation, at this very iterate
            lin, self.pending = self.pending, None
        else:
            lin = self.problem.linearise(self.traj, order)
        if order == 1:
            self.first_order_gauss_newton = lin.gauss_newton
        gnorm = self.grad_norm(lin)
        self.timings["derivatives"] += time.perf_counter() - t0
        self.hist.gradient(gnorm)
        return lin, gnorm

    def stop(self, status: str, message: str, converged: bool = False) -> None:
        self.status, self.message, self.converged = status, message, converged

    def escaped(self, lin2: Linearisation | None = None, d: tuple[float, float] | None = None) -> bool:
        """A stopping test passed at the iterate: run the final check's exact lambda = 0 pass now
        (unless the caller hands in ``lin2`` and its (d1, d2) ``d``, where that very pass just
        succeeded) and, at a
        saddle, take an escape step as an iteration. True after an escape; False means stop
        (``checked`` then holds the check's linearisation for the final check)."""
        t0 = time.perf_counter()
        if lin2 is None:
            lin2, failed, d1, d2 = self.exact_pass()
        else:
            failed, (d1, d2) = -1, d
        self.checked, self.checked_node, self.checked_d = lin2, failed, (d1, d2)
        step = None
        if failed >= 0 and len(self.escapes) < MAX_ESCAPES:
            step = escape_saddle(self.problem, lin2, failed, self.ws, self.traj, self.J)
        self.timings["final_check"] += time.perf_counter() - t0
        if step is None or self.it >= self.opt.max_iter:
            return False
        if self.hist.needs_gradient():  # the gradient of an iterate reached by a step
            self.hist.gradient(self.grad_norm(lin2))
        traj, J_new, info = step
        info.update(iteration=self.it, cost_before=float(self.J), cost_after=float(J_new))
        self.escapes.append(info)
        if self.opt.verbose:
            _print_row(self.out, self.it, self.J, self.hist.grad[-1], J_new - self.J, self.lam, abs(info["alpha"]), "escape", 0)
        self.accept(traj, J_new, self.lam, abs(info["alpha"]), "second")
        self.checked = None
        return True

    def exact_pass(self) -> tuple[Linearisation, int, float, float]:
        """The final check's work at the iterate: the exact (order 2) linearisation and its
        lambda = 0 backward pass (gains into ws). Returns (lin2, failed node or -1, d1, d2)."""
        lin2 = self.problem.linearise(self.traj, 2)
        return (lin2, *backward(lin2, self.ws, 0.0, self.traj.u))

    def cost_tol(self) -> float:
        """The threshold of the cost test at the iterate: max(tol, rtol max(|J|, ZERO_COST |J_0|))
        (:meth:`SolverOptions.cost_tolerance`; relative to |J| by default, the paper's absolute
        tol when a scene or the caller sets ``tol``)."""
        return self.opt.cost_tolerance(self.J, self.J0)

    def newton_threshold(self) -> float:
        """The largest Newton decrement the final check calls converged: the cost test's
        threshold (:meth:`cost_tol`), or the round-off of J where that is larger."""
        return max(self.cost_tol(), 16.0 * _EPS * abs(self.J))

    def cost_test_message(self, dJ: float) -> str:
        """The converged message of the cost test: "|dJ| = ... <= tol" (absolute tol, the paper's
        words) or "|dJ| = ... <= rtol |J| = ..." (relative)."""
        if self.opt.absolute():
            return f"|dJ| = {abs(dJ):.3e} <= tol"
        return f"|dJ| = {abs(dJ):.3e} <= {self.cost_tol():.1e} ({self.opt.stopping_rule()})"

    def certified_deep(self) -> bool:
        """At a first-order stop of switch: the exact lambda = 0 pass at the iterate (the final
        check's). True if it factorises with a Newton decrement <= CERTIFY_EARLY of the final
        check's threshold: the check's outcome is kept for the final check. Otherwise its
        linearisation becomes the next (second-order) iteration's, so the work is not repeated."""
        t0 = time.perf_counter()
        lin2, failed, d1, d2 = self.exact_pass()
        self.timings["final_check"] += time.perf_counter() - t0
        if failed < 0 and self.certifies(d1 - 0.5 * d2):
            self.checked, self.checked_node, self.checked_d = lin2, failed, (d1, d2)
            return True
        self.pending = lin2
        return False

    def certifies_early(self) -> bool:
        """Whether the early-certification rules apply: a Gauss-Newton first order (multibody
        costs; the satellite keeps the paper's rules) and no control limits (there the certificate
        users read is the KKT residual, which a point short of the last step leaves at 1e-4..1e-3
        on the thrust-limited quadrotor; the box pass's decrement sees only the free inputs), or
        at least none that an input of the iterate touches."""
        return self.first_order_gauss_newton and not self.on_a_bound()

    def on_a_bound(self) -> bool:
        """Some input of the iterate sits on a control limit (limits no iterate touches change
        nothing: the solve stays bit for bit the unconstrained one)."""
        return self.bounds is not None and bool(np.any(active_set(self.traj.u, *self.bounds)))

    def certifies(self, decrease: float) -> bool:
        """An exact lambda = 0 pass that factorised, with this Newton decrement, certifies the
        iterate early (CERTIFY_EARLY; CERTIFY_WITH_LIMITS with control limits)."""
        bar = CERTIFY_WITH_LIMITS if self.on_a_bound() else CERTIFY_EARLY
        return bool(np.isfinite(decrease) and decrease <= bar * self.newton_threshold())

    def accept(self, traj: Trajectory, J: float, lam: float, step: float, expansion: str) -> None:
        if expansion == "first":
            self.first_steps.append((abs(J - self.J), step))
        self.traj, self.J = traj, J
        self.it += 1
        self.hist.accept(J, lam, step, expansion, traj.u)

    def iterate(self) -> bool:
        """One iteration of Algorithm 1. Returns False when the solve stops."""
        opt, ws = self.opt, self.ws
        order = self.expansion_order()
        lin, gnorm = self.direction(order)
        if not np.isfinite(gnorm):
            self.stop(STATUS_NON_FINITE, f"the order-{order} linearisation at iteration {self.it} is not finite "
                      "(||dJ/dU|| = nan or inf); the last finite iterate is returned")
            return False
        gtol = opt.grad_tolerance(self.J, self.J0)  # max(grad_tol, grad_rtol |J|), relative by default
        if gnorm <= gtol:
            if self.escaped():
                return True
            self.stop(STATUS_CONVERGED_GRAD, f"||dJ/dU|| = {gnorm:.3e} <= " + (
                "grad_tol" if opt.absolute() and opt.grad_rtol is None else f"{gtol:.1e}"), True)
            return False

        t0 = time.perf_counter()
        self.lam, d1, d2, rungs = regularised_backward(lin, ws, self.lam, opt, self.traj.u)
        self.timings["backward"] += time.perf_counter() - t0
        lam_used, quu_min = self.lam, float(ws.quu_eig.min())
        if not (np.isfinite(d1) and np.isfinite(d2)):
            self.stop(STATUS_NON_FINITE, f"the backward pass at iteration {self.it} produced non-finite gains; "
                      "the last finite iterate is returned")
            return False
        if self.lam > opt.reg_max:
            self.stop(STATUS_MAX_REG, f"Q_uu not positive definite with lambda up to {opt.reg_max:.1e}")
            return False

        # At machine-precision stationarity the model's full-step decrease is below the round-off
        # of J: no trial step can show a decrease, so stop here (after the exact check) instead of
        # shrinking gamma through a dozen rollouts.
        full_step_decrease = d1 - 0.5 * d2
        if abs(full_step_decrease) <= 4.0 * _EPS * abs(self.J) and lam_used <= 1e-3 * quu_min:
            exact = lin.order == 2 and lam_used == 0.0
            if self.escaped(lin if exact else None, (d1, d2) if exact else None):
                return True
            self.stop(STATUS_CONVERGED_COST, f"predicted decrease {abs(full_step_decrease):.1e} below the round-off of J", True)
            return False
        # With a Gauss-Newton first order, an exact unregularised pass (a second-order iteration,
        # or switch's anticipated one) that already certifies this iterate ends the solve here:
        # the final check reuses it instead of linearising again after one more Newton step.
        if lin.order == 2 and lam_used == 0.0 and self.certifies_early() and self.certifies(full_step_decrease):
            if self.escaped(lin, (d1, d2)):
                return True
            self.stop(STATUS_CONVERGED_COST, f"predicted decrease of a full Newton step {full_step_decrease:.1e} <= "
                      f"{CERTIFY_EARLY:g} x {self.newton_threshold():.1e}", True)
            return False

        t0 = time.perf_counter()
        found = line_search(self.problem, self.traj, self.J, ws.k, ws.K, opt)
        self.timings["forward"] += time.perf_counter() - t0
        if found is None:
            # No descent along this direction: be more conservative and redo the iteration.
            self.lam = max(self.lam * 10.0, opt.reg_min)
            if self.lam > opt.reg_max:
                self.stop(STATUS_NO_DESCENT, "no gamma >= min_step decreased J, even with maximal regularisation")
                return False
            return True

        traj, J_new, gamma = found
        dJ = J_new - self.J
        exp_name = "second" if self.use_second else "first"
        if opt.verbose:
            _print_row(self.out, self.it, self.J, gnorm, dJ, self.lam, gamma, exp_name, rungs)
        self.accept(traj, J_new, self.lam, gamma, exp_name)
        if gamma >= 0.5:
            self.lam = self.lam / 10.0 if self.lam / 10.0 >= opt.reg_min else 0.0
        elif gamma < 0.1 and lin.gauss_newton:
            # A Gauss-Newton Q_uu is positive definite, so the restart rule never damps it; a step
            # the line search cut below 0.1 says the model overshoots (with control limits: a
            # Newton step far outside the box, then clamped). Raise lambda to the scale of Q_uu's
            # smallest eigenvalue, as Crocoddyl raises its regularisation after a short step.
            # (Quadrotor with thrust limits: first order 73 -> 38 iterations.)
            self.lam = min(max(self.lam * 10.0, quu_min), opt.reg_max)
        # A small |dJ| after a damped step says nothing about optimality. The cost test counts
        # only after an undamped Newton-like step: gamma = 1 (or a model decrease below tol) and
        # lambda negligible against Q_uu (with S_u = 1e-8, lambda = 0.03 would dominate Q_uu and
        # shrink every step to a gradient step with a tiny dJ, far from the optimum) ...
        tol = self.cost_tol()  # at the accepted iterate: max(tol, rtol |J_i|)
        undamped = (gamma == 1.0 or abs(full_step_decrease) <= tol) and lam_used <= 1e-3 * quu_min
        # ... unless J no longer changes beyond round-off: no step can make progress then.
        at_roundoff = abs(dJ) <= 4.0 * _EPS * abs(self.J)
        if abs(dJ) <= tol and (undamped or at_roundoff):
            if opt.expansion == "switch" and not self.use_second:
                # first order has done what it can: second order finishes (quadratically) and
                # the exact check decides, instead of stopping at a linearly converging point ...
                if not self.first_order_gauss_newton or not self.certified_deep():
                    self.use_second = True
                    return True
                # ... unless the exact check certifies this point already, to CERTIFY_EARLY of the
                # final check's threshold (then a Newton step would change J by less than that)
                self.stop(STATUS_CONVERGED_COST, self.cost_test_message(dJ), True)
                return False
            if self.escaped():
                return True
            self.stop(STATUS_CONVERGED_COST, self.cost_test_message(dJ), True)
            return False
        return True

    def final_check(self) -> float:
        """Exact second-order expansion, lambda = 0, at the returned iterate: the user's gains and
        the optimality certificate. Returns ||dJ/dU||.

        A stopping test (small |dJ|, small gradient, predicted decrease at round-off) is a reason
        to stop, not a proof. ``converged`` stays True only if, at the returned iterate,

        * the exact lambda = 0 backward pass factorises every Q_uu: the reduced Hessian of J(U) is
          positive definite (for exact second-order DDP the pass is a block elimination of that
          Hessian), so the quadratic model has a strict minimum; otherwise: saddle; and
        * the Newton decrement is small: the model decrease of the full unregularised step,
          delta = d1 - d2 / 2 = (1/2) g^T H^-1 g (g = dJ/dU, H the Hessian of J(U); d1 = sum_k
          Q_u^T k_k, d2 = sum_k k_k^T Q_uu k_k), is <= max(tau, 16 eps |J|) (tau: the cost
          test's threshold, :meth:`cost_tol`). delta is a squared gradient norm in the metric of
          H^-1: invariant under any rescaling of the controls, in units of J like tau (relative
          tau: invariant under scaling the whole cost too), and it bounds the distance to the local
          optimum in cost for a quadratic J (Boyd & Vandenberghe, Convex Optimization, 9.5.1).
          Otherwise: stalled (a small cost change at a linearly convergent step, far from the
          optimum).
        """
        t0 = time.perf_counter()
        # the exact linearisation at the iterate, made once: by the check of a stopping test, or by
        # a first-order cost test whose hand-over max_iter cut short (pending), or here
        lin = self.checked if self.checked is not None else self.pending if self.pending is not None \
            else self.problem.linearise(self.traj, 2)
        gnorm = self.grad_norm(lin)
        self.hist.gradient(gnorm)
        # the check already ran this exact lambda = 0 pass when a stopping test passed here
        if self.checked is not None:
            failed, (d1, d2) = self.checked_node, self.checked_d
        else:
            failed, d1, d2 = backward(lin, self.ws, 0.0, self.traj.u)
        quu_min = float(self.ws.quu_eig.min()) if failed < 0 else None
        decrease = float(d1 - 0.5 * d2) if failed < 0 else None
        threshold = self.newton_threshold()
        if failed >= 0:
            factorisable_gains(lin, self.ws, self.opt, self.traj.u)  # gains for the user need a factorisable Q_uu
        self.timings["final_check"] += time.perf_counter() - t0
        self.optimality = {
            "newton_decrease": decrease, "newton_threshold": threshold,
            "hessian_positive_definite": failed < 0, "min_quu_eigenvalue": quu_min,
            "indefinite_node": None if failed < 0 else int(failed), "grad_norm": gnorm,
        }
        if self.bounds is not None:
            self.optimality.update(self.kkt(lin))
        if self.converged and failed >= 0:
            self.stop(STATUS_SADDLE, f"stationary (||dJ/dU|| = {gnorm:.3e}) but Q_uu is not positive definite at node "
                      f"{failed} with the exact second-order expansion: the reduced Hessian is indefinite")
        elif self.converged and not (np.isfinite(decrease) and decrease <= threshold):
            self.stop(STATUS_STALLED, f"{self.message}, but the Newton decrement (model decrease of a full "
                      f"unregularised step, (1/2) g^T H^-1 g) is {decrease:.3e} > {threshold:.1e}: J can still "
                      f"decrease; ||dJ/dU|| = {gnorm:.3e}")
        elif self.converged:
            self.message += (f"; verified at the returned iterate: Newton decrement {decrease:.1e} <= {threshold:.1e}, "
                             f"reduced Hessian positive definite (min eig Q_uu = {quu_min:.3e})")
        if self.escapes:
            self.message += f"; escaped {len(self.escapes)} saddle point(s) along negative curvature"
        return gnorm

    def kkt(self, lin: Linearisation) -> dict:
        """KKT certificate of min J(U) over the box at the iterate: ``kkt_residual`` = max |projected
        gradient| (0 at a KKT point); ``active_inputs`` = number of (node, input) pairs on a bound;
        ``min_active_multiplier`` = the smallest |dJ/du| over them (the bound's multiplier: > 0
        means strict complementarity; 0 is the degenerate case of an input at a bound it does not
        need); ``wrong_sign_active`` = inputs on a bound whose gradient points into the box (they
        count in the residual)."""
        g = gradient(lin, self.ws)
        U, (lo, hi) = self.traj.u, self.bounds
        pg = projected_gradient(U, g, lo, hi)
        act = active_set(U, lo, hi)
        on = act != 0
        outward = ((act < 0) & (g >= 0.0)) | ((act > 0) & (g <= 0.0)) | (lo == hi)
        return {"kkt_residual": float(np.max(np.abs(pg))) if pg.size else 0.0,
                "active_inputs": int(on.sum()),
                "min_active_multiplier": float(np.min(np.abs(g[on]))) if on.any() else None,
                "wrong_sign_active": int((on & ~outward).sum())}

    def result(self, gnorm: float) -> Result:
        """Assemble the Result from the trajectory, the recorder and the problem's description."""
        solve_time = time.perf_counter() - self.t_start
        if self.opt.verbose:
            self.out.write(f"{self.status} ({self.message}); J = {self.J:.12e}, ||grad|| = {gnorm:.3e}, "
                           f"{self.it} iterations, {solve_time*1e3:.1f} ms\n")
        p = self.problem
        return Result(
            times=np.arange(p.horizon + 1) * p.dt, q=self.traj.q, v=self.traj.v, model=p.describe(),
            controls=self.traj.u, feedforward=self.ws.k.copy(), feedback=self.ws.K.copy(),
            cost=float(self.J), iterations=self.it, converged=self.converged, status=self.status,
            message=self.message, **self.hist.arrays(), solve_time_s=solve_time, timings=self.timings,
            expansion=self.opt.expansion, dt=p.dt, limits=self.bounds,
            active_set=None if self.bounds is None else active_set(self.traj.u, *self.bounds),
            extra={"optimality": self.optimality, **({"saddle_escapes": self.escapes} if self.escapes else {})},
        )


def _available_memory() -> int | None:
    """Bytes of memory available to this process (MemAvailable on Linux), or None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import os

        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def memory_estimate(horizon: int, nx: int, nu: int) -> int:
    """Bytes of the arrays of one exact second-order linearisation (the final check always builds
    one): Theta (H, nx, nx, nx), Gamma (H, nx, nx, m), Xi (H, nx, m, m), Phi, B, the cost blocks,
    the gains and a few trajectories, in float64."""
    H, n, m = int(horizon), int(nx), int(nu)
    per_node = n * n * n + n * n * m + n * m * m + n * n + n * m + n + m + n * n + m * n + m * m + m * n + m
    return 8 * H * (per_node + 6 * n + 4 * m)


# Classes whose instances passed the contract check: isinstance against a runtime-checkable
# Protocol inspects every member on each call (about 40 us, 0.3 % of a UR5 solve).
_CONFORMING: set[type] = set()
# Below this estimate the available-memory test is skipped: reading /proc/meminfo costs about
# 40 us a solve, and a machine without 64 MiB to spare fails elsewhere first.
_MEMORY_CHECK_FROM = 64 * 2**20


def _check_problem(problem: object, options: object) -> None:
    if type(problem) in _CONFORMING:
        pass
    elif isinstance(problem, OptimalControlProblem):
        _CONFORMING.add(type(problem))
    else:
        missing = [a for a in ("nx", "nu", "horizon", "dt", "check_controls", "trajectory", "trajectory_cost",
                               "linearise", "rollout_policy", "describe") if not hasattr(problem, a)]
        raise InputError("problem", f"expected an optimal control problem (geoddp.contract.OptimalControlProblem: "
                         f"e.g. geoddp.scene.build_problem(spec)), got {type(problem).__name__}"
                         + (f" (missing {', '.join(missing)})" if missing else ""))
    if options is not None and not isinstance(options, SolverOptions):
        raise InputError("options", f"expected a geoddp.solver.SolverOptions, got {type(options).__name__}"
                         + (" (build one with SolverOptions(**your_dict))" if isinstance(options, dict) else ""))
    need = memory_estimate(problem.horizon, problem.nx, problem.nu)
    avail = _available_memory() if need >= _MEMORY_CHECK_FROM else None
    if avail is not None and need > avail:
        raise InputError("horizon", f"H = {problem.horizon} with nx = {problem.nx}, m = {problem.nu} needs about "
                         f"{need / 2**30:.2f} GiB for the second-order expansion; {avail / 2**30:.2f} GiB available")


def solve(problem: OptimalControlProblem, options: SolverOptions | None = None,
          initial_controls: np.ndarray | None = None) -> Result:
    """Solve ``problem`` with geometric DDP (Algorithm 1) and return a :class:`Result`.

    Args:
        problem: anything satisfying :class:`geoddp.contract.OptimalControlProblem`
            (:class:`geoddp.problem.Problem`, satellite or multibody).
        options: :class:`SolverOptions`; the switch expansion (sigma = 0.1) and the stopping tests
            relative to |J| (rtol = 1e-11) by default; ``tol=1e-8`` gives the paper's absolute test.
        initial_controls: (H, m) initial guess (it must lie inside the problem's control limits,
            if any). By default the problem's ``quasi_static_controls()``: the controls that hold
            the initial posture against gravity where the actuation can, clipped into the
            limits; zeros (the paper's guess) without gravity, and for a problem that does not
            offer them (then projected into the limits).
    """
    _check_problem(problem, options)
    opt = options or SolverOptions()
    if initial_controls is not None:
        U = problem.check_controls(initial_controls)
    elif hasattr(problem, "quasi_static_controls"):  # optional member of the contract
        U = problem.check_controls(problem.quasi_static_controls(), "quasi_static_controls()")
    else:
        bounds = problem.control_bounds() if hasattr(problem, "control_bounds") else None
        U = np.zeros((problem.horizon, problem.nu)) if bounds is None else np.clip(0.0, *bounds)
    # Overflow and invalid operations are detected by the explicit finiteness checks of the loop
    # (cost, gradient, backward pass): numpy's warnings would only duplicate them on stderr.
    with np.errstate(all="ignore"):
        s = _Solve(problem, opt, U)
        try:
            while s.it < opt.max_iter and s.iterate():
                pass
        except np.linalg.LinAlgError as exc:
            s.stop(STATUS_LINALG, f"linear algebra failed at iteration {s.it} ({exc}); the last iterate is returned")
        except (FloatingPointError, OverflowError, ZeroDivisionError) as exc:
            s.stop(STATUS_NON_FINITE, f"{type(exc).__name__} at iteration {s.it} ({exc}); the last finite iterate "
                   "is returned")
        try:
            gnorm = s.final_check()
        except (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError) as exc:
            s.converged = False
            s.message += f"; the final check failed ({type(exc).__name__}: {exc})"
            gnorm = float("nan")
        return s.result(gnorm)
