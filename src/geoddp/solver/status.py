"""The status strings a solve ends with (``Result.status``); also importable from geoddp.solver."""
from __future__ import annotations

STATUS_CONVERGED_COST = "converged: |J_i - J_(i-1)| <= tol"
STATUS_CONVERGED_GRAD = "converged: gradient norm <= grad_tol"
STATUS_MAX_ITER = "stopped: max_iter reached"
STATUS_NO_DESCENT = "stopped: line search found no descent step"
STATUS_MAX_REG = "stopped: regularisation exceeded its maximum"
STATUS_NON_FINITE = "stopped: non-finite value in the rollout, cost or linearisation"
STATUS_LINALG = "stopped: linear algebra failure"
STATUS_STALLED = "stalled: a stopping test passed but the Newton decrement says J can still decrease"
STATUS_SADDLE = "stopped: stationary point that is not a minimum (reduced Hessian indefinite)"

STATUSES = (STATUS_CONVERGED_COST, STATUS_CONVERGED_GRAD, STATUS_MAX_ITER, STATUS_NO_DESCENT, STATUS_MAX_REG,
            STATUS_SADDLE, STATUS_STALLED, STATUS_NON_FINITE, STATUS_LINALG)
