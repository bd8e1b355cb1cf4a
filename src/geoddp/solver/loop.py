"""Algorithm 1 of the paper: DDP on Lie groups, as a short loop over named steps.

Equation numbers are the paper's printed ones (LaTeX labels: (3) linzeta, (14) Qfunctions,
(17) dustar, (18) backv, (19) vfinal, (32) psi; Lemma V.1 lemm:psi, Remark V.1 rem:theta). One
iteration (:meth:`_Solve.iterate`):

1. direction: expand dynamics and costs along the nominal trajectory, first or second order
   (eq. (3), Section IV; the order is the :mod:`.policy`'s), and the gradient ||dJ/dU|| (eq. (32));
2. stopping test on the gradient;
3. backward pass: eqs. (19), (14), (17), (18) with Q_uu regularisation (:mod:`.backward`);
4. stopping tests on the model's predicted decrease (round-off, early certificate);
5. try the step: a forward pass with line search on gamma (eq. (17), step 'steph'; :mod:`.forward`);
   none decreased J: more regularisation, and the iteration is redone;
6. accept it, update the regularisation, and the stopping test on |dJ|.

What the solve reports as it runs (the verbose table, the histories) goes through
:mod:`.callbacks`; which expansion each iteration uses, and when an exact pass certifies the
iterate early, is the :mod:`.policy`'s.

Decisions the paper leaves open, and why:
* Regularisation (Remark V.1): when Q_uu + lambda I is not positive definite at some node,
  lambda <- max(1.9 lambda, reg_min) and the backward pass *restarts* from k = H. Continuing from
  the failing node would mix value functions of different lambda; with the second-order expansion
  the first iterations need this to produce descent directions (30-46 rungs in the first one on
  the benchmark cases: the lowest rung that factorises is found by galloping and bisection,
  :mod:`.ladder`, in 9-11 passes, or 6-8 rounds of two side by side, instead of one pass per
  rung). After an accepted step with gamma >= 0.5, lambda <- lambda / 10 (and to 0 below
  reg_min) so that the last iterations run unregularised and keep their superlinear rate.
* Line search: gamma in {1, 1/3, 1/9, ...} until J <= J_bar (the paper's test); if gamma falls
  below min_step, lambda is raised and the iteration is redone; past reg_max the solve stops.
  A second-order backward pass that no lambda up to reg_max factorises does not stop the solve:
  the iteration hands back to first order (:meth:`.policy.ExpansionPolicy.hand_back`), far from
  the optimum the exact model can be indefinite beyond any useful lambda (a Solo12 jump from the
  quasi-static start: at its first iterate, and at switch's hand-over with J still 1e7).
* Stopping: |J_i - J_(i-1)| <= tau after an accepted step, or ||dJ/dU|| <= the gradient threshold
  (gradient by Lemma V.1, eq. (32)), or max_iter. tau = max(tol, rtol max(|J_i|, ZERO_COST |J_0|))
  (:meth:`SolverOptions.cost_tolerance`): relative to |J| by default (rtol = 1e-11), so that
  scaling every weight by c scales J, dJ, the decrement and tau alike and the solve is the same;
  the paper's absolute tol = 1e-8 (the satellite scenes) when ``tol`` is set. A final backward
  pass at the returned iterate, with the exact
  second-order expansion and lambda = 0, gives the feedback gains and tells whether the point is
  a strict local minimum: for exact second-order DDP, all Q_uu positive definite is equivalent to
  a positive definite Hessian of J(U). A stationary point that fails this test is reported as a
  saddle, never as converged, unless a step along negative curvature (:mod:`.saddle`) escapes it.
* Control limits (a problem whose ``control_bounds()`` is not None): the backward pass
  minimises each node's Q model over the box (projected Newton, compiled for every model;
  :func:`.backward.backward`), the forward pass clamps u_k into the box after the feedback law
  (every iterate feasible; the line search and the tests above are unchanged, so J never
  rises), and the gradient tests use the projected gradient (components pushing into an active
  bound do not count). The final check reports the KKT residual and the active set. Indefinite
  Q_uu: the same lambda rule, applied to the whole Q_uu + lambda I before each box QP.

The solver talks to the problem only through :class:`geoddp.problem.contract.OptimalControlProblem`.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from ..problem.contract import Linearisation, OptimalControlProblem, Trajectory
from ..problem.limits import active_set, projected_gradient
from ..validate import InputError
from .backward import Workspace, backward, factorisable_gains, gradient, regularised_backward
from .callbacks import Finish, History, Start, Step, VerboseTable
from .forward import line_search
from .options import SolverOptions
from .policy import ANTICIPATE, CERTIFY_EARLY, ExpansionPolicy
from .result import Result, result_class
from .saddle import MAX_ESCAPES, escape_saddle
from .status import (
    STATUS_CONVERGED_COST,
    STATUS_CONVERGED_GRAD,
    STATUS_LINALG,
    STATUS_MAX_ITER,
    STATUS_MAX_REG,
    STATUS_NO_DESCENT,
    STATUS_NON_FINITE,
    STATUS_SADDLE,
    STATUS_STALLED,
)

_EPS = np.finfo(float).eps


def cost_gradient(problem: OptimalControlProblem, controls: np.ndarray) -> tuple[float, np.ndarray]:
    """J(U) and dJ/dU (H, m) by the psi recursion of Lemma V.1 (eq. (32); exact, not a DDP step)."""
    U = problem.check_controls(controls, "controls")
    traj = problem.trajectory(U)
    ws = Workspace(problem.horizon, problem.nu, problem.nx)
    return problem.trajectory_cost(traj), gradient(problem.linearise(traj, 1), ws).copy()


class _Solve:
    """The state of one solve: the iterate, lambda, the counters, the policy, the callbacks and the buffers."""

    def __init__(self, problem: OptimalControlProblem, opt: SolverOptions, U: np.ndarray, certify: bool = True) -> None:
        self.problem, self.opt = problem, opt
        self.certify = certify  # False: a passed stopping test ends the solve without the exact pass
        self.t_start = time.perf_counter()
        self.timings = {"derivatives": 0.0, "backward": 0.0, "forward": 0.0, "final_check": 0.0}
        self.traj: Trajectory = problem.trajectory(U)
        # control limits: an optional member of the contract
        self.bounds = problem.control_bounds() if hasattr(problem, "control_bounds") else None
        self.ws = Workspace(problem.horizon, problem.nu, problem.nx, self.bounds)
        self.J = problem.trajectory_cost(self.traj)
        if not np.isfinite(self.J):
            # bad input, not a solver failure: nothing finite to return (huge controls, a spin
            # that overflows the integrator, a degenerate model)
            raise InputError("initial_controls", f"the initial guess gives a non-finite cost J = {self.J}: the "
                             "rollout or the cost overflowed; start from smaller controls or check the model")
        self.policy = ExpansionPolicy(opt, self.J, self.bounds)
        self.pending: Linearisation | None = None  # exact linearisation at the iterate, for its next direction
        self.anticipated_at = -1  # the iteration whose iterate first order's anticipated check has seen
        self.lam = opt.reg_init
        self.it = 0
        self.gnorm: float | None = None  # ||dJ/dU|| of the iterate, as first computed there (None: not yet)
        self.status, self.message, self.converged = STATUS_MAX_ITER, f"reached max_iter = {opt.max_iter}", False
        self.escapes: list[dict] = []
        self.checked: Linearisation | None = None  # exact (order 2) linearisation at the iterate, if checked there
        self.checked_node = -1  # its lambda = 0 backward pass outcome (gains stay in ws.k, ws.K)
        self.checked_d = (np.nan, np.nan)  # and that pass's (d1, d2)
        self.optimality: dict = {}
        self.history = History(opt.record_controls)
        self.callbacks = [self.history, *([VerboseTable(opt.stream or sys.stdout)] if opt.verbose else []),
                          *opt.callbacks]
        start = Start(self.J, U, time.perf_counter() - self.t_start)
        for cb in self.callbacks:
            cb.on_start(start)

    # ------------------------------------------------------------------ Algorithm 1
    def iterate(self) -> bool:
        """One iteration of Algorithm 1. Returns False when the solve stops (the status says why)."""
        opt = self.opt
        lam_in = self.lam
        if self.certify and self.anticipated_at != self.it and \
                self.policy.anticipates_certificate(self.J, self.traj.u):
            # first order, converging superlinearly, predicts a next decrease below ANTICIPATE of
            # the final check's threshold: the check runs here, and certifies this iterate or not
            # (then its linearisation is dropped: first order goes on with Gauss-Newton's, and a
            # step the line search refuses does not run the check again at the same iterate)
            self.anticipated_at = self.it
            if self.certified_deep():
                d1, d2 = self.checked_d
                return self.stop(STATUS_CONVERGED_COST, (
                    f"Gauss-Newton's next decrease predicted below {ANTICIPATE:g} x "
                    f"{self.policy.newton_threshold(self.J):.1e}, and the exact pass at this iterate gives "
                    f"{d1 - 0.5 * d2:.1e} <= {CERTIFY_EARLY:g} x {self.policy.newton_threshold(self.J):.1e}"), True)
            self.pending = None
        order = self.policy.order(self.it, self.J, self.traj.u)  # first or second order: the switch
        lin, gnorm = self.direction(order)  # expansion at the nominal, eq. (3); ||dJ/dU||, eq. (32)
        if not np.isfinite(gnorm):
            return self.stop(STATUS_NON_FINITE, f"the order-{order} linearisation at iteration {self.it} is not finite "
                             "(||dJ/dU|| = nan or inf); the last finite iterate is returned")
        gtol = opt.grad_tolerance(self.J, self.policy.J0)  # max(grad_tol, grad_rtol |J|), relative by default
        if gnorm <= gtol:
            return self.converge(STATUS_CONVERGED_GRAD, f"||dJ/dU|| = {gnorm:.3e} <= " + (
                "grad_tol" if opt.absolute() and opt.grad_rtol is None else f"{gtol:.1e}"))
        d1, d2, rungs = self.backward_pass(lin)  # eqs. (19), (14), (17), (18); lambda restarts
        if not (np.isfinite(d1) and np.isfinite(d2)):
            return self.stop(STATUS_NON_FINITE, f"the backward pass at iteration {self.it} produced non-finite gains; "
                             "the last finite iterate is returned")
        if self.lam > opt.reg_max and order == 2 and self.policy.hand_back():
            # no lambda up to reg_max makes the exact Q_uu positive definite: first order goes on
            # from this iterate, with the lambda it had (the policy says until when)
            self.lam = lam_in
            return True
        if self.lam > opt.reg_max:
            return self.stop(STATUS_MAX_REG, f"Q_uu not positive definite with lambda up to {opt.reg_max:.1e}")
        lam_used, quu_min = self.lam, float(self.ws.quu_eig.min())
        stationary = self.decrease_test(lin, d1, d2, lam_used, quu_min)  # round-off, early certificate
        if stationary is not None:
            return self.converge(STATUS_CONVERGED_COST, *stationary)
        # The model's full-step decrease below the cost tolerance, from an undamped pass: no step along
        # this direction can decrease J by more than tol, so a full step that does not decrease J
        # ends the search (the cost test's stop, without a step) instead of shrinking gamma through
        # a dozen rollouts that could each gain less than tol (ANYmal's trot: 8 rollouts for 1e-12).
        full_step_decrease = d1 - 0.5 * d2
        tol = self.policy.cost_tol(self.J)
        within_tol = abs(full_step_decrease) <= tol and lam_used <= 1e-3 * quu_min
        found = self.try_step(within_tol)  # forward passes, gamma = 1, h, h^2, ... until J <= J_bar
        if found is None and within_tol:
            return self.cost_test(0.0, 1.0, lam_used, quu_min, full_step_decrease, message=(
                f"predicted decrease of the full step {abs(full_step_decrease):.1e} <= {tol:.1e} and that step "
                "does not decrease J"))
        if found is None:
            return self.increase_regularisation()  # no descent: redo with a larger lambda
        traj, J_new, gamma = found
        dJ = J_new - self.J
        self.accept(traj, J_new, gamma, self.policy.expansion, rungs, lam=lam_used)  # the new nominal
        self.update_regularisation(gamma, lin, quu_min)
        return self.cost_test(dJ, gamma, lam_used, quu_min, d1 - 0.5 * d2)  # |dJ| <= tol, or the hand-over

    # ------------------------------------------------------------------ its steps
    def direction(self, order: int) -> tuple[Linearisation, float]:
        """Linearise at the iterate; returns it and ||dJ/dU|| (projected with limits)."""
        t0 = time.perf_counter()
        if order == 2 and self.pending is not None:  # the check's exact linearisation, at this very iterate
            lin, self.pending = self.pending, None
        else:
            lin = self.problem.linearise(self.traj, order)
        self.policy.linearised(order, lin.gauss_newton)
        gnorm = self.grad_norm(lin)
        self.timings["derivatives"] += time.perf_counter() - t0
        self.gradient_known(gnorm)
        return lin, gnorm

    def grad_norm(self, lin: Linearisation) -> float:
        """||dJ/dU||, or with control limits the norm of the projected gradient (the components
        that push into an active bound do not count: the KKT residual of the box problem)."""
        g = gradient(lin, self.ws)
        if self.bounds is not None:
            g = projected_gradient(self.traj.u, g, *self.bounds)
        return float(np.linalg.norm(g))

    def gradient_known(self, gnorm: float) -> None:
        """The iterate's gradient norm, computed: the first value at an iterate is its record."""
        if self.gnorm is None:
            self.gnorm = gnorm
            for cb in self.callbacks:
                cb.on_gradient(gnorm)

    def backward_pass(self, lin: Linearisation) -> tuple[float, float, int]:
        """The backward recursion with Q_uu regularisation (lambda restarts, Remark V.1): gains into
        the workspace, lambda updated; returns the pass's (d1, d2) and the ladder rungs climbed."""
        t0 = time.perf_counter()
        self.lam, d1, d2, rungs = regularised_backward(lin, self.ws, self.lam, self.opt, self.traj.u)
        self.timings["backward"] += time.perf_counter() - t0
        return d1, d2, rungs

    def decrease_test(self, lin: Linearisation, d1: float, d2: float, lam_used: float,
                      quu_min: float) -> tuple[str, Linearisation | None, tuple[float, float] | None] | None:
        """Stopping tests on the model's decrease of the full step, delta = d1 - d2 / 2, before any
        step: (the message, and the exact lambda = 0 pass this was when it was one) if the iterate
        is stationary, else None."""
        full_step_decrease = d1 - 0.5 * d2
        # At machine-precision stationarity the model's full-step decrease is below the round-off
        # of J: no trial step can show a decrease, so stop here (after the exact check) instead of
        # shrinking gamma through a dozen rollouts.
        if abs(full_step_decrease) <= 4.0 * _EPS * abs(self.J) and lam_used <= 1e-3 * quu_min:
            exact = lin.order == 2 and lam_used == 0.0
            return (f"predicted decrease {abs(full_step_decrease):.1e} below the round-off of J",
                    lin if exact else None, (d1, d2) if exact else None)
        # With a Gauss-Newton first order, an exact unregularised pass (a second-order iteration,
        # or switch's anticipated one) that already certifies this iterate ends the solve here:
        # the final check reuses it instead of linearising again after one more Newton step.
        U = self.traj.u
        if lin.order == 2 and lam_used == 0.0 and self.policy.certifies_early(U) and \
                self.policy.certifies(full_step_decrease, self.J, U):
            return (f"predicted decrease of a full Newton step {full_step_decrease:.1e} <= "
                    f"{CERTIFY_EARLY:g} x {self.policy.newton_threshold(self.J):.1e}", lin, (d1, d2))
        return None

    def try_step(self, full_step_only: bool = False) -> tuple[Trajectory, float, float] | None:
        """The forward pass with line search (eq. (17), Algorithm 1's inner repeat): (trajectory,
        J, gamma) of the first gamma that does not increase J, or None (``full_step_only``: gamma =
        1 alone)."""
        t0 = time.perf_counter()
        found = line_search(self.problem, self.traj, self.J, self.ws.k, self.ws.K, self.opt, full_step_only)
        self.timings["forward"] += time.perf_counter() - t0
        return found

    def increase_regularisation(self) -> bool:
        """No descent along this direction: be more conservative and redo the iteration (False
        past reg_max: the solve stops)."""
        self.lam = max(self.lam * 10.0, self.opt.reg_min)
        if self.lam > self.opt.reg_max:
            return self.stop(STATUS_NO_DESCENT, "no gamma >= min_step decreased J, even with maximal regularisation")
        return True

    def accept(self, traj: Trajectory, J: float, step: float, expansion: str, rungs: int, escape: bool = False,
               lam: float = 0.0) -> None:
        """The step to ``traj`` (cost J), taken with regularisation ``lam``, becomes the iterate; the
        policy and the callbacks hear of it."""
        record = Step(self.it, self.J, self.gnorm, J, self.lam, step, expansion, rungs, escape, traj.u,
                      time.perf_counter() - self.t_start)
        self.policy.stepped(abs(J - self.J), step, expansion, lam)
        self.traj, self.J = traj, J
        self.it += 1
        self.gnorm = None
        for cb in self.callbacks:
            cb.on_iteration(record)

    def update_regularisation(self, gamma: float, lin: Linearisation, quu_min: float) -> None:
        """After an accepted step: lambda down after a long step (the last iterations run
        unregularised), up after a short Gauss-Newton one."""
        opt = self.opt
        if gamma >= 0.5:
            self.lam = self.lam / 10.0 if self.lam / 10.0 >= opt.reg_min else 0.0
        elif gamma < 0.1 and lin.gauss_newton:
            # A Gauss-Newton Q_uu is positive definite, so the restart rule never damps it; a step
            # the line search cut below 0.1 says the model overshoots (with control limits: a
            # Newton step far outside the box, then clamped). Raise lambda to the scale of Q_uu's
            # smallest eigenvalue, as Crocoddyl raises its regularisation after a short step.
            # (Quadrotor with thrust limits: first order 73 -> 38 iterations.)
            self.lam = min(max(self.lam * 10.0, quu_min), opt.reg_max)

    def cost_test(self, dJ: float, gamma: float, lam_used: float, quu_min: float, full_step_decrease: float,
                  message: str | None = None) -> bool:
        """The stopping test on |dJ| after an accepted step (or, with dJ = 0 and its own ``message``,
        where no step can change J by more than tol). Returns False when the solve stops."""
        opt = self.opt
        # A small |dJ| after a damped step says nothing about optimality. The cost test counts
        # only after an undamped Newton-like step: gamma = 1 (or a model decrease below tol) and
        # lambda negligible against Q_uu (with S_u = 1e-8, lambda = 0.03 would dominate Q_uu and
        # shrink every step to a gradient step with a tiny dJ, far from the optimum) ...
        tol = self.policy.cost_tol(self.J)  # at the accepted iterate: max(tol, rtol |J_i|)
        undamped = (gamma == 1.0 or abs(full_step_decrease) <= tol) and lam_used <= 1e-3 * quu_min
        # ... unless J no longer changes beyond round-off: no step can make progress then.
        at_roundoff = abs(dJ) <= 4.0 * _EPS * abs(self.J)
        if not (abs(dJ) <= tol and (undamped or at_roundoff)):
            return True
        message = message or self.policy.cost_test_message(dJ, self.J)
        if self.policy.switching() and self.certify:
            # first order has done what it can: second order finishes (quadratically) and
            # the exact check decides, instead of stopping at a linearly converging point ...
            if not self.policy.gauss_newton or not self.certified_deep():
                self.policy.hand_over()
                return True
            # ... unless the exact check certifies this point already, to CERTIFY_EARLY of the
            # final check's threshold (then a Newton step would change J by less than that)
            return self.stop(STATUS_CONVERGED_COST, message, True)
        return self.converge(STATUS_CONVERGED_COST, message)

    # ------------------------------------------------------------------ stopping
    def stop(self, status: str, message: str, converged: bool = False) -> bool:
        """End the solve with this status; returns False (the loop's "stop")."""
        self.status, self.message, self.converged = status, message, converged
        return False

    def converge(self, status: str, message: str, lin2: Linearisation | None = None,
                 d: tuple[float, float] | None = None) -> bool:
        """A stopping test passed: stop as converged, unless the iterate is a saddle that a step
        along negative curvature escapes (then True: the solve goes on). ``lin2`` and its (d1, d2)
        ``d``: the exact lambda = 0 pass that was just run at the iterate, if one was."""
        if self.escaped(lin2, d):
            return True
        return self.stop(status, message, True)

    def escaped(self, lin2: Linearisation | None = None, d: tuple[float, float] | None = None) -> bool:
        """A stopping test passed at the iterate: run the final check's exact lambda = 0 pass now
        (unless the caller hands in ``lin2`` and its (d1, d2) ``d``, where that very pass just
        succeeded) and, at a saddle, take an escape step as an iteration. True after an escape;
        False means stop (``checked`` then holds the check's linearisation for the final check)."""
        if lin2 is None and not self.certify:
            return False  # uncertified: the stopping test ends the solve (final_check adds nothing)
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
        if self.gnorm is None:  # the gradient of an iterate reached by a step
            self.gradient_known(self.grad_norm(lin2))
        traj, J_new, info = step
        info.update(iteration=self.it, cost_before=float(self.J), cost_after=float(J_new))
        self.escapes.append(info)
        self.accept(traj, J_new, abs(info["alpha"]), "second", 0, escape=True)
        self.checked = None
        return True

    def exact_pass(self) -> tuple[Linearisation, int, float, float]:
        """The final check's work at the iterate: the exact (order 2) linearisation and its
        lambda = 0 backward pass (gains into ws). Returns (lin2, failed node or -1, d1, d2)."""
        lin2 = self.problem.linearise(self.traj, 2)
        return (lin2, *backward(lin2, self.ws, 0.0, self.traj.u))

    def certified_deep(self) -> bool:
        """At a first-order stop of switch: the exact lambda = 0 pass at the iterate (the final
        check's). True if it factorises with a Newton decrement <= CERTIFY_EARLY of the final
        check's threshold (:meth:`.policy.ExpansionPolicy.certifies`): the check's outcome is kept
        for the final check. Otherwise its linearisation becomes the next (second-order)
        iteration's, so the work is not repeated."""
        t0 = time.perf_counter()
        lin2, failed, d1, d2 = self.exact_pass()
        self.timings["final_check"] += time.perf_counter() - t0
        if failed < 0 and self.policy.certifies(d1 - 0.5 * d2, self.J, self.traj.u):
            self.checked, self.checked_node, self.checked_d = lin2, failed, (d1, d2)
            return True
        self.pending = lin2
        return False

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
          Q_u^T k_k, d2 = sum_k k_k^T Q_uu k_k), is <= max(tol, 16 eps |J|). delta is a squared
          gradient norm in the metric of H^-1: invariant under any rescaling of the controls or of
          individual weights, in units of J like tol, and it bounds the distance to the local
          optimum in cost for a quadratic J (Boyd & Vandenberghe, Convex Optimization, 9.5.1).
          Otherwise: stalled (a small cost change at a linearly convergent step, far from the
          optimum).
        """
        if not self.certify:
            # uncertified: no exact pass; the gains are those of the last backward pass, the
            # gradient that of the last linearisation (NaN when the iterate was reached by a step)
            self.optimality = {"certified": False}
            gnorm = self.gnorm if self.gnorm is not None else float("nan")
            if self.gnorm is None:
                self.gradient_known(gnorm)
            return gnorm
        t0 = time.perf_counter()
        # the exact linearisation at the iterate, made once: by the check of a stopping test, or by
        # a first-order cost test whose hand-over max_iter cut short (pending), or here
        lin = self.checked if self.checked is not None else self.pending if self.pending is not None \
            else self.problem.linearise(self.traj, 2)
        gnorm = self.grad_norm(lin)
        self.gradient_known(gnorm)
        # the check already ran this exact lambda = 0 pass when a stopping test passed here
        if self.checked is not None:
            failed, (d1, d2) = self.checked_node, self.checked_d
        else:
            failed, d1, d2 = backward(lin, self.ws, 0.0, self.traj.u)
        quu_min = float(self.ws.quu_eig.min()) if failed < 0 else None
        decrease = float(d1 - 0.5 * d2) if failed < 0 else None
        threshold = self.policy.newton_threshold(self.J)
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
        """Tell the callbacks how the solve ended (``gnorm``: the final check's ||dJ/dU||), then
        assemble the Result, of the kind the problem's description names, from the trajectory, the
        recorder and the description."""
        solve_time = time.perf_counter() - self.t_start
        end = Finish(self.status, self.message, self.converged, self.J, gnorm, self.it, solve_time)
        for cb in self.callbacks:
            cb.on_finish(end)
        p = self.problem
        model = p.describe()
        return result_class(model)(
            times=np.arange(p.horizon + 1) * p.dt, q=self.traj.q, v=self.traj.v, model=model,
            controls=self.traj.u, feedforward=self.ws.k.copy(), feedback=self.ws.K.copy(),
            cost=float(self.J), iterations=self.it, converged=self.converged, status=self.status,
            message=self.message, **self.history.arrays(), solve_time_s=solve_time, timings=self.timings,
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
        raise InputError("problem", f"expected an optimal control problem (geoddp.problem.contract.OptimalControlProblem: "
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
          initial_controls: np.ndarray | None = None, *, certify: bool = True) -> Result:
    """Solve ``problem`` with geometric DDP (Algorithm 1) and return a :class:`Result`.

    Args:
        problem: anything satisfying :class:`geoddp.problem.contract.OptimalControlProblem`
            (:class:`geoddp.problem.Problem`, satellite or multibody).
        options: :class:`SolverOptions`; the switch expansion (sigma = 0.1) and the stopping tests
            relative to |J| (rtol = 1e-11) by default; ``tol=1e-8`` gives the paper's absolute test.
        initial_controls: (H, m) initial guess (it must lie inside the problem's control limits,
            if any). By default the problem's ``quasi_static_controls()``: the controls that hold
            the initial posture against gravity where the actuation can, clipped into the
            limits; zeros (the paper's guess) without gravity, and for a problem that does not
            offer them (then projected into the limits).
        certify: True (the default): the final check (:meth:`_Solve.final_check`) at the returned
            iterate, an exact lambda = 0 backward pass that verifies a stopping test and gives the
            gains. False: a stopping test ends the solve as ``converged`` without it (no saddle
            escape either): the gains are the last iteration's, ``extra["optimality"]`` is
            ``{"certified": False}`` and the last gradient NaN unless a gradient test stopped the
            solve. For a solve whose iterate only warm-starts another (the inner solves of
            :func:`geoddp.constraints.solve_constrained` before its last, certified, one).

    A :class:`geoddp.constraints.ConstrainedProblem` (hard constraints) goes to its augmented
    Lagrangian outer loop, :func:`geoddp.constraints.solve_constrained`, which runs this solver on
    its inner problems (the last one certified).
    """
    outer_loop = getattr(problem, "solve_constrained", None)
    if callable(outer_loop):
        return outer_loop(options, initial_controls)
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
        s = _Solve(problem, opt, U, certify)
        try:
            while s.it < opt.max_iter and s.iterate():
                pass
        except np.linalg.LinAlgError as exc:
            s.stop(STATUS_LINALG, f"linear algebra failed at iteration {s.it} ({exc}); the last iterate is returned")
        except (FloatingPointError, OverflowError, ZeroDivisionError) as exc:
            s.stop(STATUS_NON_FINITE, f"{type(exc).__name__} at iteration {s.it} ({exc}); the last finite iterate "
                   "is returned")
        return _checked_result(s)


def check(problem: OptimalControlProblem, options: SolverOptions | None = None,
          controls: np.ndarray | None = None) -> Result:
    """The final check of :func:`solve` alone, at ``controls`` (no iterations): a Result at those
    controls with the exact lambda = 0 pass's gains, ``extra["optimality"]`` and gradient
    (``converged`` False: no stopping test ran). What an uncertified solve (``certify=False``)
    leaves out, for the iterate it returned."""
    _check_problem(problem, options)
    opt = options or SolverOptions()
    U = problem.check_controls(controls, "controls")
    with np.errstate(all="ignore"):
        s = _Solve(problem, opt, U)
        s.stop(STATUS_MAX_ITER, "no iterations (the final check alone)")
        return _checked_result(s)


def _checked_result(s: _Solve) -> Result:
    """The Result of ``s`` after its final check; a check that fails makes it not converged and
    says why in the message."""
    try:
        gnorm = s.final_check()
    except (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError) as exc:
        s.converged = False
        s.message += f"; the final check failed ({type(exc).__name__}: {exc})"
        gnorm = float("nan")
    return s.result(gnorm)
