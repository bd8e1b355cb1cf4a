"""Saddle escape: one step along negative curvature from a stationary point that is not a minimum.

When a stopping test passes, the exact (order 2) lambda = 0 backward pass decides: if Q_uu is
indefinite at some node, for exact second-order DDP the reduced Hessian of J(U) is indefinite
there, and a step along the eigenvector of the most negative eigenvalue of that node's Q_uu (with
the lambda = 0 feedback of the later nodes) decreases J. The solver takes the best of a few step
lengths as an iteration, at most MAX_ESCAPES times per solve. Not options: these only matter on
degenerate problems (a target at exactly pi from the start, for instance).

With control limits the node's Q_uu comes from the unconstrained recursion (:func:`node_quu`),
not the box pass's, and the trial rollouts clamp into the box: a trial is still taken only if
it lowers J, so an escape stays feasible and monotone, but its direction may be less apt there.
"""
from __future__ import annotations

import numpy as np

from ..problem.contract import Linearisation, OptimalControlProblem, Trajectory
from .backward import Workspace, node_quu

MAX_ESCAPES = 10
ESCAPE_ALPHAS = 10.0 ** np.arange(2.0, -7.0, -1.0)  # times max(1, max|u|): step lengths tried


def escape_saddle(
    problem: OptimalControlProblem, lin2: Linearisation, node: int, ws: Workspace, traj: Trajectory, J: float
) -> tuple[Trajectory, float, dict] | None:
    """One step along negative curvature from ``traj`` whose exact Q_uu fails at ``node``.

    ``ws.K[node+1:]`` must hold the lambda = 0 gains of the exact pass that failed at ``node``.
    Returns (trajectory, J_new, info) with J_new < J, or None if no trial decreased J.
    """
    Quu = node_quu(lin2, node)
    w, V = np.linalg.eigh(Quu)
    if not w[0] < 0.0:  # singular but not indefinite: no negative curvature to follow
        return None
    v = V[:, 0] * (1.0 if V[np.argmax(np.abs(V[:, 0])), 0] > 0 else -1.0)  # deterministic sign
    U = traj.u
    H, m = U.shape
    kff = np.zeros((H, m))
    K = ws.K.copy()
    K[: node + 1] = 0.0  # states up to node are unchanged (zeta = 0); stale gains must not matter
    scale = max(1.0, float(np.max(np.abs(U))))
    best = None
    for alpha in ESCAPE_ALPHAS * scale:
        for sgn in (1.0, -1.0):
            kff[node] = -sgn * alpha * v  # the rollout applies u_k = u_bar_k - gamma k_k - K_k zeta_k
            trial = problem.rollout_policy(traj, kff, K, 1.0)
            Jn = problem.trajectory_cost(trial) if trial is not None else np.inf
            if np.isfinite(Jn) and Jn < J and (best is None or Jn < best[1]):
                best = (trial, Jn, {"node": int(node), "eigenvalue": float(w[0]), "alpha": float(sgn * alpha)})
    return best
