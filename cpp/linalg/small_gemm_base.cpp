// linalg/small_gemm.hpp's kernel for any x86-64 (or any other target): the project's baseline flags.
#define GEODDP_GEMM_NS base
#define GEODDP_GEMM_VW 2
#include "linalg/small_gemm_impl.hpp"
