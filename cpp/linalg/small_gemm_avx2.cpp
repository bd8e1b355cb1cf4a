// linalg/small_gemm.hpp's kernel built with -mavx2 -mfma (CMakeLists.txt sets them for this file only, on
// x86-64). Called only when the CPU reports both (linalg/small_gemm.cpp).
#if defined(GEODDP_GEMM_AVX2)
#if !defined(__AVX2__) || !defined(__FMA__)
#error "linalg/small_gemm_avx2.cpp must be compiled with -mavx2 -mfma (CMakeLists.txt)"
#endif
#define GEODDP_GEMM_NS avx2
#define GEODDP_GEMM_VW 4
#include "linalg/small_gemm_impl.hpp"
#endif
