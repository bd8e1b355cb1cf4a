"""When a solve changes its expansion, and when an exact pass certifies its iterate early.

The paper's Algorithm 1 leaves the expansion order open; these rules choose it per iteration and
decide when the exact (second-order, lambda = 0) pass that certifies an iterate may end a solve
before the final check (:meth:`geoddp.solver.loop._Solve.final_check`). Equation numbers are the
paper's printed ones.

* First order and the switch: a first-order iteration drops the dynamics' second-order terms
  (Theta, Gamma, Xi of eq. (3)); where the costs offer it (multibody residual terms) it also takes
  their Gauss-Newton Hessians (``Linearisation.gauss_newton``), so the model is FDDP's. "switch"
  hands over to second order after ``switch_after`` iterations, when a first-order step passes
  the cost test (the loop's :meth:`~geoddp.solver.loop._Solve.cost_test`: second order then
  finishes instead of stopping at a linearly converging point) or, for an exact first-order model
  only, at the paper's J_i / J_0 < sigma. With a Gauss-Newton model, switch_after counts full
  steps only and waits while they converge superlinearly, and the cost test first runs the exact
  check, which may certify the point (:meth:`ExpansionPolicy.order`, :meth:`ExpansionPolicy.certifies`).
* Hand back (second and switch): an exact model that no lambda up to reg_max makes positive
  definite sends the iterations back to first order, from the same iterate, until a first-order
  step is full (gamma = 1) and unregularised (lambda = 0); then second order resumes
  (:meth:`ExpansionPolicy.hand_back`). A solve at first order still stops there.
* Early certification (Gauss-Newton first order, no input on a control limit; the satellite
  keeps the paper's rules): an exact lambda = 0 pass whose Newton decrement is at most
  CERTIFY_EARLY = 0.1 of the final check's threshold ends the solve at its iterate, before the
  step (the final check reuses it), and switch linearises exactly one iterate early when
  Gauss-Newton predicts that its next step would change J by less than ANTICIPATE = 0.01 of that
  threshold (:meth:`ExpansionPolicy.converged_next`); first order runs the exact check there
  instead of one more Gauss-Newton iteration (:meth:`ExpansionPolicy.anticipates_certificate`). Crocoddyl stops on the direction it computed
  at the previous iterate; here the certificate at the returned iterate costs one exact
  linearisation, and these rules keep it to one.
"""
from __future__ import annotations

import numpy as np

from ..problem.limits import active_set
from .options import SolverOptions

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


class ExpansionPolicy:
    """The expansion switch and the early-certification rules of one solve.

    The loop asks :meth:`order` at the start of every iteration and tells the policy what it
    learnt: :meth:`linearised` after each linearisation, :meth:`stepped` after each accepted step,
    :meth:`hand_over` when a first-order cost test hands over to second order. ``U`` is the
    iterate's controls (H, m), ``J`` its cost.
    """

    def __init__(self, opt: SolverOptions, J0: float, bounds: tuple[np.ndarray, np.ndarray] | None) -> None:
        self.opt, self.J0, self.bounds = opt, J0, bounds
        self.second = opt.expansion == "second"  # the iterations run second order (switch: from the hand-over)
        self.gauss_newton = False  # what the last order-1 linearisation said
        self.first_steps: list[tuple[float, float]] = []  # (|dJ|, gamma) of the accepted first-order steps
        self.handed_back = False  # an exact model failed beyond reg_max: first order until it runs free
        self.last_first: tuple[float, float] | None = None  # (gamma, lambda) of the last first-order step

    @property
    def expansion(self) -> str:
        """The expansion of the current iterations: "first" or "second"."""
        return "second" if self.second else "first"

    def switching(self) -> bool:
        """A switch solve still in its first-order phase."""
        return self.opt.expansion == "switch" and not self.second

    def hand_over(self) -> None:
        """Switch to second order from the next iteration on."""
        self.second, self.handed_back = True, False

    def hand_back(self) -> bool:
        """The exact model at the iterate is indefinite beyond reg_max (no rung of the ladder
        factorised): the iterations go on at first order (True) until a first-order step is full and
        unregularised (:meth:`order`); a solve already at first order stops (False)."""
        if not self.second:
            return False
        self.second, self.handed_back, self.last_first = False, True, None
        return True

    def linearised(self, order: int, gauss_newton: bool) -> None:
        """A linearisation of ``order`` was made; ``gauss_newton``: its cost Hessians are Gauss-Newton's."""
        if order == 1:
            self.gauss_newton = gauss_newton

    def stepped(self, decrease: float, gamma: float, expansion: str, lam: float = 0.0) -> None:
        """A step of ``expansion`` with line-search ``gamma`` and regularisation ``lam`` changed J by
        ``decrease`` (>= 0) and was accepted."""
        if expansion == "first":
            self.first_steps.append((decrease, gamma))
            self.last_first = (gamma, lam)

    def order(self, it: int, J: float, U: np.ndarray) -> int:
        """The switch rule: second order after switch_after iterations, or once J_i / J_0 <
        switch_ratio (the paper's test) unless the first-order model is a Gauss-Newton one, or
        when first order passes its cost test (:meth:`hand_over`)."""
        opt = self.opt
        if self.handed_back:
            # After a hand back (second and switch): first order until its step is full and
            # unregularised, the regime where Gauss-Newton converges fast and the exact model is
            # near its own. On the Solo12 jump from the quasi-static start the exact Q_uu stayed
            # indefinite beyond reg_max until then: each earlier hand-over crawled (switch handing
            # over at the fifth full step: 145+ iterations against first order's 108) or stopped.
            if self.last_first is not None and self.last_first == (1.0, 0.0):
                self.handed_back, self.second = False, True
            return 2 if self.second else 1
        # The paper's test hands over early because its first-order model carries exact, possibly
        # indefinite cost Hessians. A Gauss-Newton model (lin.gauss_newton) has positive
        # semidefinite ones and keeps converging like FDDP; handing over at J / J_0 < sigma
        # replaced those iterations by second-order ones 2-4x dearer doing the same work (with
        # the rules below, switch solves on the real robots take 0.26-0.59x the time they took:
        # benchmarks/speed_vs_main_2026-11-25b.log).
        paper_test = not self.gauss_newton and self.J0 > 0 and J / self.J0 < opt.switch_ratio
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
        if self.gauss_newton:
            full = sum(1 for _, g in self.first_steps if g == 1.0)
            due = full >= opt.switch_after or it >= 4 * opt.switch_after
        else:
            due = it >= opt.switch_after
        if self.switching() and (paper_test or (due and not superlinear) or self.converged_next(J, U)):
            self.second = True
        return 2 if self.second else 1

    def superlinear(self) -> bool:
        """The last first-order step was a full Gauss-Newton step that cut the decrease of the one
        before at least 100x."""
        return self.gauss_newton and len(self.first_steps) >= 2 and \
            self.first_steps[-1][1] == 1.0 and self.first_steps[-1][0] <= 0.01 * self.first_steps[-2][0]

    def converged_next(self, J: float, U: np.ndarray) -> bool:
        """Gauss-Newton predicts that its next step changes J by less than ANTICIPATE of the final
        check's threshold: the last two first-order steps were full and the last cut the decrease
        at least 100x (superlinear), so the next decrease is about dJ_i^2 / dJ_(i-1)."""
        if not self.certifies_early(U) or not self.superlinear():
            return False
        (d_prev, g_prev), (d_last, _) = self.first_steps[-2:]
        return g_prev == 1.0 and 0.0 < d_prev and d_last * d_last / d_prev <= ANTICIPATE * self.newton_threshold(J)

    def anticipates_certificate(self, J: float, U: np.ndarray) -> bool:
        """A first-order solve (not switch) at an iterate where Gauss-Newton predicts that its next
        step changes J by less than ANTICIPATE of the final check's threshold
        (:meth:`converged_next`): the exact check runs before another Gauss-Newton iteration, and a
        certificate there ends the solve (the iteration it saves could change J by less than a
        hundredth of the threshold)."""
        return self.opt.expansion == "first" and self.converged_next(J, U)

    def cost_tol(self, J: float) -> float:
        """The threshold of the cost test at cost J: max(tol, rtol max(|J|, ZERO_COST |J_0|))
        (:meth:`SolverOptions.cost_tolerance`; relative to |J| by default, the paper's absolute
        tol when a scene or the caller sets ``tol``)."""
        return self.opt.cost_tolerance(J, self.J0)

    def newton_threshold(self, J: float) -> float:
        """The largest Newton decrement the final check calls converged: the cost test's
        threshold (:meth:`cost_tol`), or the round-off of J where that is larger."""
        return max(self.cost_tol(J), 16.0 * _EPS * abs(J))

    def cost_test_message(self, dJ: float, J: float) -> str:
        """The converged message of the cost test: "|dJ| = ... <= tol" (absolute tol, the paper's
        words) or "|dJ| = ... <= 5.1e-09 (rtol = 1e-11)" (relative)."""
        if self.opt.absolute():
            return f"|dJ| = {abs(dJ):.3e} <= tol"
        return f"|dJ| = {abs(dJ):.3e} <= {self.cost_tol(J):.1e} ({self.opt.stopping_rule()})"

    def certifies_early(self, U: np.ndarray) -> bool:
        """Whether the early-certification rules apply: a Gauss-Newton first order (multibody
        costs; the satellite keeps the paper's rules) and no control limits (there the certificate
        users read is the KKT residual, which a point short of the last step leaves at 1e-4..1e-3
        on the thrust-limited quadrotor; the box pass's decrement sees only the free inputs), or
        at least none that an input of the iterate touches."""
        return self.gauss_newton and not self.on_a_bound(U)

    def on_a_bound(self, U: np.ndarray) -> bool:
        """Some input of the iterate sits on a control limit (limits no iterate touches change
        nothing: the solve stays bit for bit the unconstrained one)."""
        return self.bounds is not None and bool(np.any(active_set(U, *self.bounds)))

    def certifies(self, decrease: float, J: float, U: np.ndarray) -> bool:
        """An exact lambda = 0 pass that factorised, with this Newton decrement, certifies the
        iterate early (CERTIFY_EARLY; CERTIFY_WITH_LIMITS with control limits)."""
        bar = CERTIFY_WITH_LIMITS if self.on_a_bound(U) else CERTIFY_EARLY
        return bool(np.isfinite(decrease) and decrease <= bar * self.newton_threshold(J))
