// Small dense products for the Riccati recursion (riccati/riccati.cpp, riccati/contracted.cpp): C = [C +]
// alpha op(A) B on row-major float64 blocks of a few dozen rows, the sizes of one DDP node (n = 2 nv, m
// inputs).
//
// Why not Eigen's product: the extension is compiled for baseline x86-64 (never -march=native, see
// CMakeLists.txt), so Eigen's GEMM runs on 2-wide SSE2 without FMA and packs both operands for
// every 36 x 36 product. These kernels are compiled twice (linalg/small_gemm_base.cpp for any x86-64,
// linalg/small_gemm_avx2.cpp with -mavx2 -mfma) and one of the two is picked once at load time from
// what the CPU reports (__builtin_cpu_supports). They include no Eigen and no Pinocchio header,
// so the two builds share no inline function and cannot mix (no ODR or ABI coupling).
//
// Results differ from Eigen's (and between the two builds) only in rounding: the order of the
// sum over k is the same (k ascending) in both builds; FMA rounds once per term.
#pragma once

namespace geoddp {
namespace gemm {

// C (M, N; row stride ldc) = [C +] alpha op(A) B with op(A) (M, K) and B (K, N; row stride ldb).
// trans_a false: A is (M, K) with row stride lda; true: A is (K, M) with row stride lda and
// op(A) = A^T. accumulate false overwrites C (it may hold anything, even NaN, before the call).
void gemm(bool trans_a, int M, int N, int K, double alpha, const double* A, int lda, const double* B, int ldb,
          bool accumulate, double* C, int ldc);

// The same product restricted to the upper triangle of a square C (M = N = n): rows in blocks of
// four, each from its first diagonal column on (a few entries below the diagonal in each 4 x 4
// diagonal block are written too). About half the work of gemm for symmetric results that are
// completed from their upper triangle afterwards.
void gemm_upper(bool trans_a, int n, int K, double alpha, const double* A, int lda, const double* B, int ldb,
                bool accumulate, double* C, int ldc);

// Which build gemm runs: "avx2+fma" or "x86-64" (or "generic" off x86).
const char* isa();

// Both builds, for the tests: 0 the baseline, 1 the AVX2/FMA one (only if the CPU has it).
void gemm_variant(int variant, bool trans_a, int M, int N, int K, double alpha, const double* A, int lda,
                  const double* B, int ldb, bool accumulate, double* C, int ldc);
bool has_avx2_fma();

}  // namespace gemm
}  // namespace geoddp
