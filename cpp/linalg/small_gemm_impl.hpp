// The kernel of linalg/small_gemm.hpp, compiled once per instruction set: the including file defines
// GEODDP_GEMM_NS (the namespace of its build) and GEODDP_GEMM_VW (doubles per vector register: 2
// for SSE2, 4 for AVX2) and is compiled with that set's flags (-O3: the fixed-size loops over the
// accumulators must unroll into registers).
// Register blocking: 4 rows x 2 vectors of C in eight accumulators, k innermost; the column tail
// in one-vector and then scalar steps, the row tail with fewer rows.
#if !defined(GEODDP_GEMM_NS) || !defined(GEODDP_GEMM_VW)
#error "define GEODDP_GEMM_NS and GEODDP_GEMM_VW before including linalg/small_gemm_impl.hpp"
#endif

namespace geoddp {
namespace gemm {
namespace GEODDP_GEMM_NS {

constexpr int VW = GEODDP_GEMM_VW;
typedef double vec __attribute__((vector_size(8 * GEODDP_GEMM_VW)));

static inline vec loadv(const double* p) {
  vec r;
  __builtin_memcpy(&r, p, sizeof(r));
  return r;
}
static inline void storev(double* p, vec v) { __builtin_memcpy(p, &v, sizeof(v)); }

// op(A)(r, k) for the block whose first row is A (trans: A points at column r = 0 of row k = 0)
template <bool T>
static inline double a_at(const double* A, int lda, int r, int k) {
  return T ? A[(long)k * lda + r] : A[(long)r * lda + k];
}

// R rows x NV vectors of C in R * NV accumulators
template <bool T, int R, int NV>
static inline void blockv(int K, double alpha, const double* A, int lda, const double* B, int ldb, bool acc,
                          double* C, int ldc) {
  vec c[R][NV];
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < NV; ++v) c[r][v] = vec{};
  for (int k = 0; k < K; ++k) {
    vec b[NV];
    for (int v = 0; v < NV; ++v) b[v] = loadv(B + (long)k * ldb + v * VW);
    for (int r = 0; r < R; ++r) {
      const double a = a_at<T>(A, lda, r, k);
      for (int v = 0; v < NV; ++v) c[r][v] += a * b[v];
    }
  }
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < NV; ++v) {
      double* p = C + (long)r * ldc + v * VW;
      storev(p, acc ? loadv(p) + alpha * c[r][v] : alpha * c[r][v]);
    }
}

template <bool T, int R>
static inline void block1(int K, double alpha, const double* A, int lda, const double* B, int ldb, bool acc,
                          double* C, int ldc) {
  double c0[R];
  for (int r = 0; r < R; ++r) c0[r] = 0.0;
  for (int k = 0; k < K; ++k) {
    const double b = B[(long)k * ldb];
    for (int r = 0; r < R; ++r) c0[r] += a_at<T>(A, lda, r, k) * b;
  }
  for (int r = 0; r < R; ++r) {
    double* c = C + (long)r * ldc;
    *c = acc ? *c + alpha * c0[r] : alpha * c0[r];
  }
}

template <bool T, int R>
static inline void row_block(int N, int K, double alpha, const double* A, int lda, const double* B, int ldb,
                             bool acc, double* C, int ldc) {
  int j = 0;
  for (; j + 2 * VW <= N; j += 2 * VW) blockv<T, R, 2>(K, alpha, A, lda, B + j, ldb, acc, C + j, ldc);
  for (; j + VW <= N; j += VW) blockv<T, R, 1>(K, alpha, A, lda, B + j, ldb, acc, C + j, ldc);
  for (; j < N; ++j) block1<T, R>(K, alpha, A, lda, B + j, ldb, acc, C + j, ldc);
}

template <bool T>
static void run(int M, int N, int K, double alpha, const double* A, int lda, const double* B, int ldb, bool acc,
                double* C, int ldc) {
  // the first row of op(A) block i: row i of A, or column i of A^T
  auto a_block = [&](int i) { return T ? A + i : A + (long)i * lda; };
  int i = 0;
  for (; i + 4 <= M; i += 4) row_block<T, 4>(N, K, alpha, a_block(i), lda, B, ldb, acc, C + (long)i * ldc, ldc);
  switch (M - i) {
    case 3: row_block<T, 3>(N, K, alpha, a_block(i), lda, B, ldb, acc, C + (long)i * ldc, ldc); break;
    case 2: row_block<T, 2>(N, K, alpha, a_block(i), lda, B, ldb, acc, C + (long)i * ldc, ldc); break;
    case 1: row_block<T, 1>(N, K, alpha, a_block(i), lda, B, ldb, acc, C + (long)i * ldc, ldc); break;
    default: break;
  }
}

void gemm(bool trans_a, int M, int N, int K, double alpha, const double* A, int lda, const double* B, int ldb,
          bool accumulate, double* C, int ldc) {
  if (M <= 0 || N <= 0) return;
  if (trans_a) run<true>(M, N, K, alpha, A, lda, B, ldb, accumulate, C, ldc);
  else run<false>(M, N, K, alpha, A, lda, B, ldb, accumulate, C, ldc);
}

}  // namespace GEODDP_GEMM_NS
}  // namespace gemm
}  // namespace geoddp
