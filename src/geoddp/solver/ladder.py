"""Which regularisation a backward pass restarts with once Q_uu + lambda I failed (Remark rem:theta).

lambda climbs the ladder lam_0 = lambda, lam_{j+1} = max(reg_increase lam_j, reg_min) (the paper's
factor 1.9) to the lowest rung whose pass factorises (Q_uu + lam I positive definite at every
node). One rung per restart had cost 30-46 passes in the first second-order iteration of every
benchmark case (23 % of the docking scene's second-order solve). :class:`LadderSearch` gallops
instead (rungs 1, 3, 7, 15, ... above the last failure; two passes at a time: 1 and 2, 4 and 6,
10 and 14, ...) until a pass factorises, then bisects between the highest rung that failed and
the lowest that factorised: rung 30 takes 9 passes one at a time or 6 rounds two at a time
(the one-rung loop: 30 passes, 15 rounds); rungs 31-46 take 9-11 passes or 7-8 rounds (against
16-23 rounds).

Where factorising is monotone in lambda (a pass that factorises at lambda factorises at every
larger one, the usual case: lambda I only adds to Q_uu, and the value functions it feeds back
stay positive semidefinite) the rung found is exactly the one the one-rung restarts reached, so
lambda, the gains and (d1, d2) are those of the paper's loop (tested). Otherwise it is a rung
that factorises directly above one that does not. ``cpp/riccati/contracted.cpp``'s
``regularised_contracted`` runs the same search (the same probes in the same order) in C++.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

from ..validate import InputError


def ladder(lam: float, reg_increase: float, reg_min: float, reg_max: float) -> list[float]:
    """[lam_0 = lam, lam_1, ..., lam_T]: lam_{j+1} = max(reg_increase lam_j, reg_min), computed
    one product at a time (the values of the one-rung loop, bit for bit), ending with the first
    rung T >= 1 above reg_max (reaching it means giving up). The ladder is finite only for a
    finite lam >= 0, reg_increase > 1, reg_min > 0 and a finite reg_max: anything else raises
    InputError (SolverOptions validates its own; this guards options changed after it)."""
    for name, value, ok in (("lam", lam, math.isfinite(lam) and lam >= 0.0),
                            ("reg_increase", reg_increase, reg_increase > 1.0),
                            ("reg_min", reg_min, math.isfinite(reg_min) and reg_min > 0.0),
                            ("reg_max", reg_max, math.isfinite(reg_max))):
        if not ok:
            raise InputError(name, f"expected a value for which the regularisation ladder ends, got {value!r}")
    rungs = [lam]
    while True:
        rungs.append(max(rungs[-1] * reg_increase, reg_min))
        if rungs[-1] > reg_max:
            return rungs


class LadderSearch:
    """The rungs to try next, given those tried: lo (the highest known to fail; rung 0 failed
    before the search starts) and hi (the lowest known to factorise, or the top rung T, never
    tried). Done when hi = lo + 1: rung hi is the answer if ``found``, else the search gave up.

    ``two``: two passes run side by side (one worker each), so each round offers two rungs.
    """

    def __init__(self, top: int, two: bool) -> None:
        self.lo, self.hi, self.found, self.two = 0, top, False, two
        self._step = 1

    def probes(self) -> tuple[int, ...]:
        """The next round's rungs, ascending; () when the search is done."""
        lo, hi = self.lo, self.hi
        gap = hi - lo
        if gap <= 1:
            return ()
        if self.found:  # bisect (lo, hi), in halves or thirds
            if not self.two or gap == 2:
                return (lo + gap // 2,)
            return (lo + gap // 3, lo + 2 * gap // 3)
        # gallop: lo + step (and lo + 2 step), below the top
        a = min(lo + self._step, hi - 1)
        b = min(lo + 2 * self._step, hi - 1)
        return (a, b) if self.two and b > a else (a,)

    def record(self, probes: Sequence[int], factorised: Sequence[bool]) -> int | None:
        """Record a round's outcomes (in the order of ``probes``); returns the position of the
        rung that factorised (the lowest; higher ones are not looked at), or None."""
        for i, (rung, ok) in enumerate(zip(probes, factorised)):
            if ok:
                self.hi, self.found = rung, True
                return i
            self.lo = rung
        if not self.found:
            self._step *= 2
        return None
