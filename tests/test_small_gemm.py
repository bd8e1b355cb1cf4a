"""The Riccati products' kernels (cpp/linalg/small_gemm.hpp) against numpy, in both builds.

The backward passes (plain, box-constrained, contracted) form their Q blocks and value updates
with these kernels; a wrong edge case (a row or column tail, the transposed operand, the
accumulate flag) would show there only as a slightly wrong gain. Here every tail is hit:
rows 1..13 (blocks of 4 plus 1-3), columns 1..19 (vector blocks plus the scalar tail), K = 0..9.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from geoddp.models.compiled import _core

VARIANTS = (0, 1)  # 0 baseline x86-64, 1 AVX2/FMA (the baseline again on a CPU without it)


def _reference(trans_a, alpha, A, B, C0, accumulate):
    opA = A.T if trans_a else A
    P = alpha * (opA @ B)
    return C0 + P if accumulate else P


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_tail_against_numpy(variant):
    rng = np.random.default_rng(variant)
    worst = 0.0
    for M, N, K in itertools.product(range(1, 14), range(1, 20), (0, 1, 4, 9)):
        for trans_a, accumulate in itertools.product((False, True), (False, True)):
            A = rng.standard_normal((K, M) if trans_a else (M, K))
            B = rng.standard_normal((K, N))
            C0 = rng.standard_normal((M, N))
            C = C0.copy() if accumulate else np.full((M, N), np.nan)  # overwritten, even NaN
            _core.testing.gemm(variant, trans_a, -1.5, A, B, accumulate, C)
            ref = _reference(trans_a, -1.5, A, B, C0, accumulate)
            scale = 1.0 + np.abs(ref).max()
            worst = max(worst, np.abs(C - ref).max() / scale)
    assert worst < 1e-14, worst


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("n,m", [(12, 6), (36, 12), (61, 20)])
def test_node_sized_products(variant, n, m):
    """The products of one node at the robots' sizes (UR5 n 12, Solo12 n 36, Talos-sized n 61)."""
    rng = np.random.default_rng(n)
    V = rng.standard_normal((n, n))
    P = rng.standard_normal((n, n))
    B = rng.standard_normal((n, m))
    VP = np.empty((n, n))
    _core.testing.gemm(variant, False, 1.0, V, P, False, VP)
    np.testing.assert_allclose(VP, V @ P, rtol=0, atol=1e-13 * np.abs(V @ P).max())
    Q = rng.standard_normal((m, n))
    Q0 = Q.copy()
    _core.testing.gemm(variant, True, 1.0, B, VP, True, Q)
    np.testing.assert_allclose(Q, Q0 + B.T @ VP, rtol=0, atol=1e-13 * np.abs(B.T @ VP).max())


def test_builds_agree_to_rounding_and_isa_is_reported():
    rng = np.random.default_rng(7)
    A, B = rng.standard_normal((36, 36)), rng.standard_normal((36, 36))
    C0, C1 = np.empty((36, 36)), np.empty((36, 36))
    _core.testing.gemm(0, True, 1.0, A, B, False, C0)
    _core.testing.gemm(1, True, 1.0, A, B, False, C1)
    assert np.abs(C0 - C1).max() <= 1e-13 * np.abs(C0).max()
    assert _core.gemm_isa() == "avx2+fma" if _core.testing.has_avx2_fma() else _core.gemm_isa() in ("x86-64", "generic")


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match="shapes"):
        _core.testing.gemm(0, False, 1.0, np.ones((3, 4)), np.ones((5, 2)), False, np.empty((3, 2)))
    with pytest.raises(TypeError):
        _core.testing.gemm(0, False, 1.0, np.ones((3, 4)), np.ones((4, 2)), False, np.empty((3, 2), dtype=np.float32))
