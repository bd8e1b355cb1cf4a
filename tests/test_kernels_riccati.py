"""Compiled recursions against independent references."""
import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from geoddp import kernels


@pytest.mark.parametrize("n,m", [(6, 3), (6, 2), (4, 2), (9, 4)])  # n = 6 takes the specialised branch
def test_backward_pass_reproduces_the_lqr_riccati_gain(rng, n, m):
    """Linear dynamics, quadratic cost, terminal value = the algebraic Riccati solution P: every
    node's feedback gain must be the steady-state LQR gain (R + B'PB)^-1 B'PA."""
    H = 25
    A = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    Bm = rng.normal(size=(n, m))
    Q = np.diag(rng.uniform(0.5, 2.0, n))
    Rw = np.diag(rng.uniform(0.1, 1.0, m))
    P = solve_discrete_are(A, Bm, Q, Rw)
    K_ref = np.linalg.solve(Rw + Bm.T @ P @ Bm, Bm.T @ P @ A)
    tile = lambda M: np.ascontiguousarray(np.broadcast_to(M, (H,) + M.shape))
    k, K, q = np.zeros((H, m)), np.zeros((H, m, n)), np.zeros(H)
    failed, d1, d2 = kernels.backward_pass(
        tile(A), tile(Bm), np.zeros((H, n)), np.zeros((H, m)), tile(Q), np.zeros((H, m, n)), tile(Rw),
        np.zeros(n), P, np.zeros((0, n, n, n)), np.zeros((0, n, n, m)), np.zeros((0, n, m, m)),
        False, 0.0, k, K, q)
    assert failed == -1
    assert np.abs(K - K_ref).max() < 1e-10 * max(1.0, np.abs(K_ref).max())
    assert np.abs(k).max() == 0.0 and d1 == 0.0


def test_backward_pass_reports_the_failing_node():
    H, n, m = 5, 6, 1
    Phi = np.ascontiguousarray(np.broadcast_to(np.eye(n), (H, n, n)))
    B = np.ones((H, n, m))
    luu = np.ones((H, m, m))
    luu[3] = -10.0  # V stays 0 (no state cost), so Q_uu = l_uu: negative at node 3
    failed, _, _ = kernels.backward_pass(
        Phi, B, np.zeros((H, n)), np.zeros((H, m)), np.zeros((H, n, n)), np.zeros((H, m, n)), luu,
        np.zeros(n), np.zeros((n, n)), np.zeros((0, n, n, n)), np.zeros((0, n, n, m)), np.zeros((0, n, m, m)),
        False, 0.0, np.zeros((H, m)), np.zeros((H, m, n)), np.zeros(H))
    assert failed == 3
