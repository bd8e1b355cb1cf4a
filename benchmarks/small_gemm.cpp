// The Riccati node products (cpp/riccati/riccati_blocks.hpp's q_blocks and value update, dense) with
// Eigen's product against cpp/linalg/small_gemm.hpp's two builds, interleaved in one process. Built and
// run by benchmarks/small_gemm.py; prints one line per (n, m, variant).
#include "linalg/small_gemm.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RM;
using geoddp::gemm::gemm_variant;

// One node's products: VxxPhi = Vxx Phi, VxxB = Vxx B, Qxx = Phi^T VxxPhi, Qux = B^T VxxPhi,
// Quu = B^T VxxB, Vxx -= Qux^T K (full blocks, to compare like with like).
static void node(int variant, int n, int m, const RM& Vxx, const RM& P, const RM& B, RM& VP, RM& VB, RM& Qxx, RM& Qux,
                 RM& Quu, RM& V) {
  if (variant < 0) {
    VP.noalias() = Vxx * P;
    VB.noalias() = Vxx * B;
    Qxx.noalias() = P.transpose() * VP;
    Qux.noalias() = B.transpose() * VP;
    Quu.noalias() = B.transpose() * VB;
    V.noalias() -= 1e-9 * (Qux.transpose() * Qux);
    return;
  }
  gemm_variant(variant, false, n, n, n, 1.0, Vxx.data(), n, P.data(), n, false, VP.data(), n);
  gemm_variant(variant, false, n, m, n, 1.0, Vxx.data(), n, B.data(), m, false, VB.data(), m);
  gemm_variant(variant, true, n, n, n, 1.0, P.data(), n, VP.data(), n, false, Qxx.data(), n);
  gemm_variant(variant, true, m, n, n, 1.0, B.data(), m, VP.data(), n, false, Qux.data(), n);
  gemm_variant(variant, true, m, m, n, 1.0, B.data(), m, VB.data(), m, false, Quu.data(), m);
  gemm_variant(variant, true, n, n, m, -1e-9, Qux.data(), n, Qux.data(), n, true, V.data(), n);
}

int main() {
  const int sizes[][2] = {{12, 6}, {18, 12}, {36, 12}, {60, 20}, {100, 44}};
  for (const auto& sz : sizes) {
    const int n = sz[0], m = sz[1];
    RM Vxx = RM::Random(n, n), P = RM::Random(n, n), B = RM::Random(n, m), V = RM::Random(n, n);
    RM VP(n, n), VB(n, m), Qxx(n, n), Qux(m, n), Quu(m, m);
    const int reps = std::max(50, (int)(4e8 / (2.0 * n * n * (n + m))));
    std::vector<double> t[3];
    for (int round = 0; round < 7; ++round)
      for (int v = -1; v < 2; ++v) {  // interleaved: Eigen, baseline, AVX2
        const auto t0 = std::chrono::steady_clock::now();
        for (int r = 0; r < reps / 7; ++r) node(v, n, m, Vxx, P, B, VP, VB, Qxx, Qux, Quu, V);
        t[v + 1].push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() /
                           (reps / 7));
      }
    double med[3];
    for (int v = 0; v < 3; ++v) {
      std::sort(t[v].begin(), t[v].end());
      med[v] = t[v][t[v].size() / 2];
    }
    std::printf("n %3d m %3d  eigen %8.2f us  baseline %8.2f us (%.2fx)  avx2+fma %8.2f us (%.2fx)  [%s]\n", n, m,
                med[0], med[1], med[1] / med[0], med[2], med[2] / med[0], geoddp::gemm::isa());
  }
  return 0;
}
