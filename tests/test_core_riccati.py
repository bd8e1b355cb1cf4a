"""The compiled backward pass (geoddp._core.backward_pass, also geoddp.kernels.backward_pass)
against a numpy transcription of the recursion (paper eqs. Qfunctions, dustar, backv; Remark
rem:theta): the same failed node, d1, d2, gains k, K and Q_uu eigenvalue proxy, to 1e-12
relative, first and second order, with and without regularisation, on random problems of several
sizes (n = 6 runs the pass with its sizes fixed at compile time, m = 3 and m = 2; symmetric blocks
are given with a non-symmetric lower triangle: the pass reads the upper one only) and on one where
Q_uu is indefinite part-way."""
from __future__ import annotations

import numpy as np
import pytest

from geoddp.models import compiled



def _problem(rng, H, n, m, scale_quu=1.0):
    def sym_upper(shape):
        A = rng.standard_normal(shape)
        # SPD-ish upper triangle, garbage below it (never read)
        S = A @ np.swapaxes(A, -1, -2) / shape[-1] + np.eye(shape[-1])
        return np.triu(S) + np.tril(rng.standard_normal(shape), -1)
    Phi = np.eye(n) + 0.1 * rng.standard_normal((H, n, n))
    B = 0.3 * rng.standard_normal((H, n, m))
    lx, lu = rng.standard_normal((H, n)), rng.standard_normal((H, m))
    lxx, luu = sym_upper((H, n, n)), scale_quu * sym_upper((H, m, m))
    lux = 0.1 * rng.standard_normal((H, m, n))
    Vx, Vxx = rng.standard_normal(n), rng.standard_normal((n, n))
    Vxx = Vxx @ Vxx.T + np.eye(n)
    Theta = 0.01 * rng.standard_normal((H, n, n, n))
    Gamma = 0.01 * rng.standard_normal((H, n, n, m))
    Xi = 0.01 * rng.standard_normal((H, n, m, m))
    return Phi, B, lx, lu, lxx, lux, luu, Vx, Vxx, Theta, Gamma, Xi


def _run(fn, args, second, reg, H, n, m):
    k, K, eig = np.full((H, m), 7.0), np.full((H, m, n), 7.0), np.full(H, 7.0)
    out = fn(*args, second, reg, k, K, eig)
    return (int(out[0]), float(out[1]), float(out[2])), k, K, eig


def _reference_pass(Phi, B, lx, lu, lxx, lux, luu, Vx, Vxx, Theta, Gamma, Xi, second, reg, k_ff, K_fb, eig):
    """numpy, node by node: Q blocks, their second-order terms, Cholesky of Q_uu + reg I, gains and
    the value backup, reading the symmetric inputs' upper triangles (the kernels' documented rule)."""
    def sym(A):
        return np.triu(A) + np.triu(A, 1).swapaxes(-1, -2)

    H, n, m = B.shape
    Vx, Vxx = Vx.copy(), Vxx.copy()
    d1 = d2 = 0.0
    for k in range(H - 1, -1, -1):
        P, Bk = Phi[k], B[k]
        Qx, Qu = lx[k] + P.T @ Vx, lu[k] + Bk.T @ Vx
        Qxx = sym(lxx[k]) + P.T @ Vxx @ P
        Qux = lux[k] + Bk.T @ Vxx @ P
        Quu = sym(luu[k]) + Bk.T @ Vxx @ Bk
        if second:
            Qxx = Qxx + np.einsum("i,iab->ab", Vx, sym(Theta[k]))
            Qux = Qux + np.einsum("i,iac->ca", Vx, Gamma[k])
            Quu = Quu + np.einsum("i,iab->ab", Vx, sym(Xi[k]))
        try:
            L = np.linalg.cholesky(Quu + reg * np.eye(m))
        except np.linalg.LinAlgError:
            return k, d1, d2
        eig[k] = np.min(np.diag(L) ** 2)
        kk = np.linalg.solve(Quu + reg * np.eye(m), Qu)
        KK = np.linalg.solve(Quu + reg * np.eye(m), Qux)
        k_ff[k], K_fb[k] = kk, KK
        d1 += Qu @ kk
        d2 += kk @ Quu @ kk
        Vx = Qx - Qux.T @ kk
        Vxx = Qxx - Qux.T @ KK
        Vxx = np.triu(Vxx) + np.triu(Vxx, 1).T
    return -1, d1, d2


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


@pytest.mark.parametrize("n, m", [(6, 3), (6, 2), (12, 4), (12, 6), (18, 3), (30, 12)])
@pytest.mark.parametrize("second", [False, True])
@pytest.mark.parametrize("reg", [0.0, 1e-3])
def test_backward_pass_equals_the_numpy_recursion(n, m, second, reg):
    rng = np.random.default_rng(1000 * n + 10 * m + second)
    H = 40
    args = _problem(rng, H, n, m)
    (fc, d1c, d2c), kc, Kc, ec = _run(compiled._core.backward_pass, args, second, reg, H, n, m)
    (fp, d1p, d2p), kp, Kp, ep = _run(_reference_pass, args, second, reg, H, n, m)
    assert fc == fp == -1
    assert abs(d1c - d1p) <= 1e-12 * abs(d1p) and abs(d2c - d2p) <= 1e-12 * abs(d2p)
    assert _rel(kc, kp) <= 1e-12 and _rel(Kc, Kp) <= 1e-12 and _rel(ec, ep) <= 1e-12


@pytest.mark.parametrize("second", [False, True])
@pytest.mark.parametrize("n, m", [(12, 4), (6, 3)])
def test_backward_pass_stops_at_the_same_node(second, n, m):
    rng = np.random.default_rng(7)
    H = 30
    args = list(_problem(rng, H, n, m))
    args[6] = args[6].copy()
    args[6][11] = -10.0 * np.eye(m)  # Q_uu indefinite at node 11
    (fc, d1c, d2c), kc, Kc, ec = _run(compiled._core.backward_pass, args, second, 0.0, H, n, m)
    (fp, d1p, d2p), kp, Kp, ep = _run(_reference_pass, args, second, 0.0, H, n, m)
    assert fc == fp == 11
    assert abs(d1c - d1p) <= 1e-12 * abs(d1p) and abs(d2c - d2p) <= 1e-12 * abs(d2p)
    # nodes H-1 .. 12 written, node 11 and below untouched (7.0) by both
    assert _rel(kc, kp) <= 1e-12 and _rel(Kc, Kp) <= 1e-12 and _rel(ec, ep) <= 1e-12
    assert np.all(kc[: fc + 1] == 7.0) and np.all(kp[: fp + 1] == 7.0)


def test_backward_pass_rejects_wrong_shapes():
    rng = np.random.default_rng(3)
    H, n, m = 5, 12, 4
    args = list(_problem(rng, H, n, m))
    args[2] = args[2][:, :-1]  # lx (H, n-1)
    with pytest.raises(ValueError, match="lx"):
        _run(compiled._core.backward_pass, args, True, 0.0, H, n, m)


def test_passes_refuse_bad_outputs_and_box_arrays():
    """The bindings' checks (cpp/bindings/checks.hpp): a wrong shape, a read-only or a Fortran-order
    output, and the box pass's bounds and outputs are refused naming the array; the same call with
    the right arrays runs and keeps the feedforward in its box."""
    rng = np.random.default_rng(4)
    H, n, m = 5, 12, 4
    args = list(_problem(rng, H, n, m))
    core = compiled._core
    k, K, eig = np.zeros((H, m)), np.zeros((H, m, n)), np.zeros(H)
    with pytest.raises(ValueError, match="K_fb"):
        core.backward_pass(*args, True, 0.0, k, np.zeros((H, n, m)), eig)
    read_only = np.zeros((H, m))
    read_only.flags.writeable = False
    with pytest.raises(ValueError, match="k_ff: expected a writeable C-contiguous"):
        core.backward_pass(*args, True, 0.0, read_only, K, eig)
    with pytest.raises(ValueError, match="k_ff: expected a writeable C-contiguous"):
        core.backward_pass(*args, True, 0.0, np.zeros((m, H)).T, K, eig)  # Fortran order
    U, lo, hi = np.zeros((H, m)), -np.ones((H, m)), np.ones((H, m))
    act, Vx0, Vxx0 = np.zeros((H, m), np.int8), np.zeros(n), np.zeros((n, n))
    with pytest.raises(ValueError, match="lower"):
        core.backward_pass_box(*args, True, 0.0, U, lo[:, :-1], hi, k, K, eig, act, Vx0, Vxx0)
    with pytest.raises(ValueError, match="active"):
        core.backward_pass_box(*args, True, 0.0, U, lo, hi, k, K, eig, act[:-1], Vx0, Vxx0)
    with pytest.raises(ValueError, match="Vxx0"):
        core.backward_pass_box(*args, True, 0.0, U, lo, hi, k, K, eig, act, Vx0, np.zeros((n, n + 1)))
    failed, _, _ = core.backward_pass_box(*args, True, 0.0, U, lo, hi, k, K, eig, act, Vx0, Vxx0)
    # u = u_bar - k - K zeta in [lower, upper] at zeta = 0: -1 <= k <= 1
    assert failed == -1 and np.all(np.abs(k) <= 1.0 + 1e-12) and np.all(np.isfinite(Vxx0))
