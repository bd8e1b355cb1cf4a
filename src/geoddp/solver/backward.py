"""The backward pass (paper eqs. Qfunctions, dustar, backv, vfinal) and the cost gradient (Lemma
lemm:psi): thin wrappers over the compiled kernels, plus the regularisation loop around them."""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..problem.contract import Linearisation
from ..validate import threads_from_environment
from .ladder import LadderSearch, ladder
from .options import SolverOptions

# Every pass is compiled (geoddp._core, cpp/riccati/riccati.cpp, reached through geoddp.kernels): the
# dense one (at nx = 6, the satellite's TSO(3) state, with its sizes fixed at compile time), and,
# for a second-order Linearisation whose terms are factored (lin.second_order, compiled multibody
# models), _core.backward_pass_contracted, which contracts them with V_x' node by node instead of
# reading Theta, Gamma, Xi.
_core = kernels.core
# Below this nx a pass runs on one thread (no speculative pass beside it), as the satellite's did
# while they were numba's, which held the GIL: its solves run as they did. (A whole pass at nx = 6
# costs about 0.1 ms at H = 300, 0.38 us per node.)
SPECULATE_MIN_NX = 7


class Workspace:
    """Per-solve buffers (Crocoddyl's 'data'): allocated once, reused every iteration.

    k (H, m) feedforward and K (H, m, nx) feedback gains of the last backward pass, grad (H, m)
    the last gradient, quu_eig (H,) the smallest eigenvalue of each node's regularised Q_uu. With
    control limits also bounds, active (H, m), k_box (H, m) and the value function at node 0.
    """

    def __init__(self, horizon: int, nu: int, nx: int, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        H, m = horizon, nu
        # control limits (lower, upper), each (H, m), or None: then every pass is the unconstrained one
        self.bounds = bounds
        self.active = np.zeros((H, m), dtype=np.int8)  # the last box pass's active set (-1 lower, +1 upper)
        self.k_box = np.zeros((H, m))  # the last box pass's feedforward: the next one's warm start
        self.Vx0, self.Vxx0 = np.zeros(nx), np.zeros((nx, nx))
        self.k = np.zeros((H, m))
        self.K = np.zeros((H, m, nx))
        self.grad = np.zeros((H, m))
        self.quu_eig = np.zeros(H)
        # placeholders for first-order passes: the kernel never indexes them (memory stays O(H))
        self.empty_theta = np.zeros((0, nx, nx, nx))
        self.empty_gamma = np.zeros((0, nx, nx, m))
        self.empty_xi = np.zeros((0, nx, m, m))
        self._spares: list[Workspace] = []

    def spare(self, i: int = 0) -> "Workspace":
        """Spare buffers of the same shapes (for speculative passes), made once: spare(0), spare(1)."""
        while len(self._spares) <= i:
            self._spares.append(Workspace(self.k.shape[0], self.k.shape[1], self.K.shape[2]))
        return self._spares[i]

    def take(self, other: "Workspace", failed: int) -> None:
        """Copy what a pass into ``other`` that stopped at node ``failed`` (-1: none) wrote: the
        gains and quu_eig of nodes failed+1 .. H-1, exactly as if that pass had run here."""
        lo = failed + 1
        self.k[lo:] = other.k[lo:]
        self.K[lo:] = other.K[lo:]
        self.quu_eig[lo:] = other.quu_eig[lo:]


def backward(lin: Linearisation, ws: Workspace, reg: float, u_bar: np.ndarray | None = None) -> tuple[int, float, float]:
    """One backward pass with Q_uu + reg I; gains into ws.k, ws.K.

    With control limits (ws.bounds; ``u_bar`` (H, m) the nominal controls) the unconstrained pass
    runs first: when every full-step control u_bar_k - k_k of the nodes it solved lies in the box,
    each of those nodes' box QP has that unconstrained minimiser as its solution (a strictly convex
    QP whose unconstrained minimiser is feasible) and the value functions coincide, so its gains
    (or its failure at a node where Q_uu + reg I is not positive definite) are the box pass's, bit
    for bit the unconstrained solver's (inactive limits change nothing). The
    unconstrained attempt is skipped while the last box pass had inputs on a bound. Otherwise
    the compiled box pass (geoddp._core.backward_pass_box, cpp/riccati/riccati.cpp, for every model)
    recomputes the gains: box QP per node by projected Newton, warm-started from its previous
    feedforward; the active set goes to ws.active.

    Returns (failed node or -1, d1, d2): the model's decrease for a step gamma is
    -(gamma d1 - gamma^2 / 2 d2) (so d1 - d2 / 2 at gamma = 1).
    """
    second = lin.order == 2
    theta = lin.Theta if second else ws.empty_theta
    gamma = lin.Gamma if second else ws.empty_gamma
    xi = lin.Xi if second else ws.empty_xi
    # the unconstrained pass, unless the last box pass had inputs on a bound (then it is wasted work)
    if ws.bounds is None or not ws.active.any():
        out = _unconstrained(lin, ws, reg)
        if ws.bounds is None:
            return out
        # nodes failed+1 .. H-1 were solved (all of them on success): if every full-step control
        # there is inside the box, the box pass would compute exactly these nodes and stop at the
        # same node (the same whole-Q_uu rule), so this outcome is the box pass's
        done = slice(out[0] + 1, None)
        u_full = u_bar[done] - ws.k[done]
        lower, upper = ws.bounds
        if np.all((u_full >= lower[done]) & (u_full <= upper[done])):  # NaN fails: the box pass decides
            if out[0] < 0:
                ws.k_box[:] = ws.k
            return out
    lower, upper = ws.bounds
    ws.k[:] = ws.k_box  # warm start of every node's box QP
    if second and lin.second_order is not None:  # factored second order: contracted with V_x' in the box pass
        out = _core.backward_pass_box_contracted(
            lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx, lin.second_order,
            reg, u_bar, lower, upper, ws.k, ws.K, ws.quu_eig, ws.active, ws.Vx0, ws.Vxx0, _pass_workers(lin))
    else:
        out = _core.backward_pass_box(
            lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx,
            theta, gamma, xi, second, reg, u_bar, lower, upper, ws.k, ws.K, ws.quu_eig, ws.active, ws.Vx0, ws.Vxx0,
        )
    if out[0] < 0:
        ws.k_box[:] = ws.k
    return out


def _unconstrained(lin: Linearisation, ws: Workspace, reg: float) -> tuple[int, float, float]:
    """The unconstrained pass: contracted (factored second order) or dense."""
    second = lin.order == 2
    if second and lin.second_order is not None:  # factored terms: contracted with V_x' in the pass
        return _core.backward_pass_contracted(
            lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx,
            lin.second_order, reg, ws.k, ws.K, ws.quu_eig, _pass_workers(lin))
    return kernels.backward_pass(
        lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx,
        lin.Theta if second else ws.empty_theta,
        lin.Gamma if second else ws.empty_gamma,
        lin.Xi if second else ws.empty_xi,
        second, reg, ws.k, ws.K, ws.quu_eig,
    )


def gradient(lin: Linearisation, ws: Workspace) -> np.ndarray:
    """dJ/dU (H, m) by the psi recursion of Lemma lemm:psi, into ws.grad (first-order terms only)."""
    kernels.gradient(lin.Phi, lin.B, lin.l_x, lin.l_u, lin.lf_x, ws.grad)
    return ws.grad


_SPECULATION: dict = {"pid": None, "pool": None}


def _can_speculate(lin: Linearisation) -> bool:
    """Whether a pass may use two workers: two passes side by side after a failure, or, for the
    contracted pass, each node's contraction on the second worker (``workers``; bitwise the
    same results). Only with two or more cores, nx >= SPECULATE_MIN_NX (or factored second-order
    terms) and GEODDP_THREADS not set to 1 (a sweep's worker on a core of its own)."""
    if _core.default_threads() < 2:
        return False
    if lin.second_order is None and lin.Phi.shape[1] < SPECULATE_MIN_NX:
        return False
    return threads_from_environment() != 1  # read after the structure: small passes never look


def _pass_workers(lin: Linearisation) -> int:
    """The contracted passes' ``workers``: 0 (the core picks one or two workers, whichever has been
    faster here for passes of this shape; bitwise the same results) where two may be used, else 1."""
    return 0 if _can_speculate(lin) else 1


def _speculation_pool(lin: Linearisation):
    """A one-worker thread pool for speculative passes, or None where they cannot run side by side
    (:func:`_can_speculate`). Made per process (a forked child gets its own: the parent's worker
    thread does not exist there)."""
    if not _can_speculate(lin):
        return None
    import os

    if _SPECULATION["pid"] != os.getpid():
        from concurrent.futures import ThreadPoolExecutor

        _SPECULATION["pool"] = ThreadPoolExecutor(max_workers=1, thread_name_prefix="geoddp-backward")
        _SPECULATION["pid"] = os.getpid()
    return _SPECULATION["pool"]


def regularised_backward(lin: Linearisation, ws: Workspace, lam: float, opt: SolverOptions,
                         u_bar: np.ndarray | None = None) -> tuple[float, float, float, int]:
    """Backward pass restarted from k = H with a larger lambda while Q_uu + lambda I is not
    positive definite (Remark rem:theta): lambda takes the lowest rung of the ladder
    lambda_{j+1} = max(reg_increase lambda_j, reg_min) whose pass factorises, found by galloping and
    bisection (:mod:`.ladder`; the same rung as one restart per rung wherever factorising is
    monotone in lambda), or gives up above opt.reg_max.

    With control limits the same rule holds for the box pass, one rung at a time: it fails at a
    node where the whole Q_uu + lambda I is not positive definite, so every box QP it solves is
    strictly convex.

    Returns (lambda, d1, d2, rungs climbed); lambda > opt.reg_max means it gave up.

    Once a pass has failed (the first iterations climb 30-50 rungs on the real robots), each round
    of the search runs two rungs side by side where two cores may be used (the compiled pass
    releases the GIL; the higher rung into ``ws.spare()``). Each pass is deterministic and
    independent of the other, so the result is that of the same search one pass at a time
    (tested). For the unconstrained contracted pass (compiled multibody models) the whole search
    runs in C++ (geoddp._core.regularised_contracted, on the core's two workers): a restart there
    costs no Python call and no thread hand-off, which had been 3-5 % of a second-order solve. A
    pass that runs alone there may put each node's contraction on the second worker, beside the
    node's first-order blocks (0.55-0.79x the one-worker pass's time on the seven benchmark cases,
    idle); the core runs whichever way has been faster for passes of that shape (:func:`_pass_workers`).
    """
    if lin.order == 2 and lin.second_order is not None and ws.bounds is None:
        # the contracted pass: the same loop in C++ (no Python, no thread hand-off per restart)
        spare = ws.spare()
        lam, _, d1, d2, restarts = _core.regularised_contracted(
            lin.Phi, lin.B, lin.l_x, lin.l_u, lin.l_xx, lin.l_ux, lin.l_uu, lin.lf_x, lin.lf_xx, lin.second_order,
            lam, opt.reg_increase, opt.reg_min, opt.reg_max, _can_speculate(lin), ws.k, ws.K, ws.quu_eig,
            spare.k, spare.K, spare.quu_eig)
        return lam, d1, d2, restarts
    return _regularised_loop(lin, ws, lam, opt, u_bar)


def _regularised_loop(lin: Linearisation, ws: Workspace, lam: float, opt: SolverOptions,
                      u_bar: np.ndarray | None = None) -> tuple[float, float, float, int]:
    """regularised_backward's loop in Python (every pass but the unconstrained contracted one,
    whose loop runs in C++: geoddp._core.regularised_contracted, tested against this).

    After a failed pass, lambda climbs its ladder by :class:`.ladder.LadderSearch` (galloping, then
    bisection); the box pass, which warm-starts from the previous pass's feedforward in ws, climbs
    it one rung at a time. Returns (lambda, d1, d2, rungs climbed)."""
    failed, d1, d2 = backward(lin, ws, lam, u_bar)
    if failed < 0:
        return lam, d1, d2, 0
    rungs = ladder(lam, opt.reg_increase, opt.reg_min, opt.reg_max)
    top = len(rungs) - 1
    if ws.bounds is not None:
        j = 1
        while j < top:
            failed, d1, d2 = backward(lin, ws, rungs[j], u_bar)
            if failed < 0:
                return rungs[j], d1, d2, j
            j += 1
        return rungs[top], d1, d2, top
    # speculative (side by side) passes only without limits
    pool = _speculation_pool(lin)
    search = LadderSearch(top, two=pool is not None)
    while probes := search.probes():
        # before a pass factorised, the lower probe runs in ws (whose partial gains, like the
        # one-rung loop's, are then those of the highest failed rung); after, ws keeps the
        # factorised pass and the probes run in spares
        if not search.found:
            bufs = [ws, ws.spare()][:len(probes)]
        else:
            bufs = [ws.spare(1), ws.spare()] if len(probes) == 2 else [ws.spare()]
        if len(probes) == 2:
            ahead = pool.submit(backward, lin, bufs[1], rungs[probes[1]])
            outs = [backward(lin, bufs[0], rungs[probes[0]]), ahead.result()]
        else:
            outs = [backward(lin, bufs[0], rungs[probes[0]])]
        ok = search.record(probes, [out[0] < 0 for out in outs])
        if ok is not None:
            failed, d1, d2 = outs[ok]
            if bufs[ok] is not ws:
                ws.take(bufs[ok], -1)
        elif not search.found:
            failed, d1, d2 = outs[-1]
            if bufs[-1] is not ws:
                ws.take(bufs[-1], failed)
    if search.found:
        return rungs[search.hi], d1, d2, search.hi
    return rungs[top], d1, d2, top


def factorisable_gains(lin: Linearisation, ws: Workspace, opt: SolverOptions, u_bar: np.ndarray | None = None) -> None:
    """Gains for the user where the lambda = 0 pass failed: the smallest lambda >= reg_min (on the
    reg_increase grid, up to reg_max) whose Q_uu factorises."""
    lam = opt.reg_min
    while backward(lin, ws, lam, u_bar)[0] >= 0 and lam < opt.reg_max:
        lam *= opt.reg_increase


def _upper_sym(A: np.ndarray) -> np.ndarray:
    # kernels.backward_pass reads only the upper triangle of its symmetric blocks; mirror that.
    return np.triu(A) + np.triu(A, 1).T


def node_quu(lin: Linearisation, node: int) -> np.ndarray:
    """Q_uu (lambda = 0) at ``node``: numpy mirror of kernels.backward_pass from H-1 down to node.

    Only used on the (rare) saddle path, where the compiled pass stops at the failing node without
    returning its Q_uu. Nodes > node factorised there, so the recursion is well defined.
    """
    second = lin.order == 2
    Vx, Vxx = lin.lf_x.copy(), _upper_sym(lin.lf_xx)
    for k in range(lin.Phi.shape[0] - 1, node - 1, -1):
        P, Bk = lin.Phi[k], lin.B[k]
        Qx = lin.l_x[k] + P.T @ Vx
        Qu = lin.l_u[k] + Bk.T @ Vx
        Qxx = lin.l_xx[k] + P.T @ Vxx @ P
        Qux = lin.l_ux[k] + Bk.T @ Vxx @ P
        Quu = lin.l_uu[k] + Bk.T @ Vxx @ Bk
        if second and lin.second_order is not None:
            S = lin.second_order.contract(k, Vx)
            n = Vx.shape[0]
            Qxx, Qux, Quu = Qxx + S[:n, :n], Qux + S[n:, :n], Quu + S[n:, n:]
        elif second:
            Qxx = Qxx + np.einsum("i,iab->ab", Vx, lin.Theta[k])
            Qux = Qux + np.einsum("i,iac->ca", Vx, lin.Gamma[k])
            Quu = Quu + np.einsum("i,iab->ab", Vx, lin.Xi[k])
        Qxx, Quu = _upper_sym(Qxx), _upper_sym(Quu)
        if k == node:
            return Quu
        kk = np.linalg.solve(Quu, Qu)
        KK = np.linalg.solve(Quu, Qux)
        Vx = Qx - Qux.T @ kk
        Vxx = _upper_sym(Qxx - Qux.T @ KK)
    raise AssertionError("unreachable")
