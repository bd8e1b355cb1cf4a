// Dispatch of linalg/small_gemm.hpp: the AVX2/FMA build when the CPU has both, else the baseline one,
// decided once (the first call) and then fixed for the life of the process.
#include "linalg/small_gemm.hpp"

namespace geoddp {
namespace gemm {

namespace base {
void gemm(bool, int, int, int, double, const double*, int, const double*, int, bool, double*, int);
}
#if defined(GEODDP_GEMM_AVX2)  // set by CMakeLists.txt on x86-64, with linalg/small_gemm_avx2.cpp's flags
#define GEODDP_GEMM_HAS_AVX2_BUILD 1
namespace avx2 {
void gemm(bool, int, int, int, double, const double*, int, const double*, int, bool, double*, int);
}
#endif

bool has_avx2_fma() {
#ifdef GEODDP_GEMM_HAS_AVX2_BUILD
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
#else
  return false;
#endif
}

const char* isa() {
#ifdef GEODDP_GEMM_HAS_AVX2_BUILD
  return has_avx2_fma() ? "avx2+fma" : "x86-64";
#else
  return "generic";
#endif
}

void gemm_variant(int variant, bool trans_a, int M, int N, int K, double alpha, const double* A, int lda,
                  const double* B, int ldb, bool accumulate, double* C, int ldc) {
#ifdef GEODDP_GEMM_HAS_AVX2_BUILD
  if (variant == 1 && has_avx2_fma()) {
    avx2::gemm(trans_a, M, N, K, alpha, A, lda, B, ldb, accumulate, C, ldc);
    return;
  }
#endif
  (void)variant;
  base::gemm(trans_a, M, N, K, alpha, A, lda, B, ldb, accumulate, C, ldc);
}

void gemm(bool trans_a, int M, int N, int K, double alpha, const double* A, int lda, const double* B, int ldb,
          bool accumulate, double* C, int ldc) {
  typedef void (*Kernel)(bool, int, int, int, double, const double*, int, const double*, int, bool, double*, int);
#ifdef GEODDP_GEMM_HAS_AVX2_BUILD
  static const Kernel kernel = has_avx2_fma() ? &avx2::gemm : &base::gemm;  // chosen once
#else
  static const Kernel kernel = &base::gemm;
#endif
  kernel(trans_a, M, N, K, alpha, A, lda, B, ldb, accumulate, C, ldc);
}

void gemm_upper(bool trans_a, int n, int K, double alpha, const double* A, int lda, const double* B, int ldb,
                bool accumulate, double* C, int ldc) {
  for (int i = 0; i < n; i += 4) {
    const int rows = n - i < 4 ? n - i : 4;
    const double* Ai = trans_a ? A + i : A + (long)i * lda;
    gemm(trans_a, rows, n - i, K, alpha, Ai, lda, B + i, ldb, accumulate, C + (long)i * ldc + i, ldc);
  }
}

}  // namespace gemm
}  // namespace geoddp
