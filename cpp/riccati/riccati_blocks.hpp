// The two dense steps every backward pass shares (riccati/riccati.cpp: plain and box-constrained;
// riccati/contracted.cpp): the Q-function's blocks from the next node's value function (paper eq.
// Qfunctions, first-order part) and the value function's Hessian update (eq. backv). Products go
// through linalg/small_gemm.hpp; symmetric results are computed on their upper triangle only and
// completed by the caller (upper_to_full), as the passes always did.
#pragma once

#include <Eigen/Core>
#include <algorithm>

#include "runtime/arrays.hpp"
#include "linalg/small_cholesky.hpp"
#include "linalg/small_gemm.hpp"

namespace geoddp {
namespace ric {

// Node k's blocks, Phi (n, n) and B (n, m) row-major, l* its cost derivatives (row-major, l_xx
// and l_uu read in full): Qx = lx + Phi^T Vx, Qu = lu + B^T Vx, Qxx = lxx + Phi^T Vxx Phi (upper
// triangle exact, lower = lxx's plus junk), Qux = lux + B^T Vxx Phi, Quu = luu + B^T Vxx B (upper
// exact). VxxPhi (n, n) and VxxB (n, m) are scratch. Vxx must be full (both triangles).
inline void q_blocks(int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                     const double* lxx, const double* lux, const double* luu, const Eigen::VectorXd& Vx,
                     const RowMat& Vxx, RowMat& VxxPhi, RowMat& VxxB, Eigen::VectorXd& Qx,
                     Eigen::VectorXd& Qu, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
  const CMatMap P(Phi, n, n), Bk(B, n, m);
  Qx = CVecMap(lx, n);
  Qx.noalias() += P.transpose() * Vx;
  Qu = CVecMap(lu, m);
  Qu.noalias() += Bk.transpose() * Vx;
  gemm::gemm(false, n, n, n, 1.0, Vxx.data(), n, Phi, n, false, VxxPhi.data(), n);
  gemm::gemm(false, n, m, n, 1.0, Vxx.data(), n, B, m, false, VxxB.data(), m);
  Qxx = CMatMap(lxx, n, n);
  gemm::gemm_upper(true, n, n, 1.0, Phi, n, VxxPhi.data(), n, true, Qxx.data(), n);
  Qux = CMatMap(lux, m, n);
  gemm::gemm(true, m, n, n, 1.0, B, m, VxxPhi.data(), n, true, Qux.data(), n);
  Quu = CMatMap(luu, m, m);
  gemm::gemm_upper(true, m, n, 1.0, B, m, VxxB.data(), m, true, Quu.data(), m);
}

// Vxx += alpha X^T Y on the upper triangle, X and Y (m, n) row-major (Vxx (n, n)).
inline void add_xt_y_upper(double alpha, const RowMat& X, const RowMat& Y, RowMat& Vxx) {
  const int n = (int)Vxx.rows(), m = (int)X.rows();
  gemm::gemm_upper(true, n, m, alpha, X.data(), n, Y.data(), n, true, Vxx.data(), n);
}

// Node k's second-order terms from the dense tensors Theta (H, n, n, n), Gamma (H, n, n, m), Xi
// (H, n, m, m): Qxx += sum_i V_x'_i Theta_i, Qux += sum_i V_x'_i Gamma_i^T, Quu += sum_i V_x'_i Xi_i
// (Remark rem:theta).
inline void add_dense_second_order(int n, int m, const double* Theta, const double* Gamma, const double* Xi, int k,
                                   const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
  // plain loops over the row-major blocks: at n = 6 (the satellite) Eigen's dynamic-size
  // expressions cost more in dispatch than their arithmetic (the same sums either way)
  const double* Th = Theta + (size_t)k * n * n * n;
  const double* Ga = Gamma + (size_t)k * n * n * m;
  const double* X = Xi + (size_t)k * n * m * m;
  double *qxx = Qxx.data(), *qux = Qux.data(), *quu = Quu.data();
  for (int i = 0; i < n; ++i) {
    const double v = Vx[i];
    if (v == 0.0) continue;
    const double* Ti = Th + (size_t)i * n * n;
    for (int a = 0; a < n * n; ++a) qxx[a] += v * Ti[a];
    const double* Gi = Ga + (size_t)i * n * m;  // (n, m): Qux(a, b) += v Gamma_i(b, a)
    for (int a = 0; a < m; ++a)
      for (int b = 0; b < n; ++b) qux[a * n + b] += v * Gi[b * m + a];
    const double* Xi_ = X + (size_t)i * m * m;
    for (int a = 0; a < m * m; ++a) quu[a] += v * Xi_[a];
  }
}

// Nothing to do when a node's V_x' is final (unconstrained_pass's default vx_final).
struct NoHandOver {
  void operator()(int, const Eigen::VectorXd&) const {}
};

// The unconstrained recursion (paper eqs. Qfunctions, dustar, backv) with the inputs, outputs and
// failure rule of riccati/riccati.hpp's backward_pass. add_second(k, Vx, Qxx, Qux, Quu) adds node k's
// second-order terms contracted with V_x' (the dense tensors, or riccati/contracted.cpp's factors; a no-op
// for first order) before the blocks are completed and factored. vx_final(k, Vx) runs as soon as
// node k's V_x' (the Vx of node k + 1) is known, before the rest of node k + 1's work, so that
// riccati/contracted.cpp's two-worker pass can start node k's contraction early; Vx is not written again
// until node k's add_second has returned.
template <typename AddSecond, typename HandOver = NoHandOver>
int unconstrained_pass(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                       const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                       const double* Vxx_final, AddSecond&& add_second, double reg, double* k_ff, double* K_fb,
                       double* quu_eig, double* d1, double* d2, HandOver&& vx_final = HandOver()) {
  using smallchol::cholesky_inplace;
  using smallchol::cholesky_solve;
  using smallchol::upper_to_full;
  Eigen::VectorXd Vx = CVecMap(Vx_final, n), Qx(n), Qu(m), kk(m);
  RowMat Vxx = CMatMap(Vxx_final, n, n);  // as given (all of it is read, not only a triangle)
  RowMat Qxx(n, n), Qux(m, n), Quu(m, m), L(m, m), VxxPhi(n, n), VxxB(n, m), KK(m, n);
  double s1 = 0.0, s2 = 0.0;
  *d1 = 0.0;
  *d2 = 0.0;
  if (H > 0) vx_final(H - 1, Vx);
  for (int k = H - 1; k >= 0; --k) {
    q_blocks(n, m, Phi + (size_t)k * n * n, B + (size_t)k * n * m, lx + (size_t)k * n, lu + (size_t)k * m,
             lxx + (size_t)k * n * n, lux + (size_t)k * m * n, luu + (size_t)k * m * m, Vx, Vxx, VxxPhi, VxxB, Qx, Qu,
             Qxx, Qux, Quu);
    add_second(k, Vx, Qxx, Qux, Quu);
    upper_to_full(Qxx);
    upper_to_full(Quu);
    L = Quu;
    L.diagonal().array() += reg;
    if (!cholesky_inplace(L)) {
      *d1 = s1;
      *d2 = s2;
      return k;
    }
    double mn = L(0, 0) * L(0, 0);
    for (int a = 1; a < m; ++a) mn = std::min(mn, L(a, a) * L(a, a));
    quu_eig[k] = mn;
    kk = Qu;
    cholesky_solve(L, kk);
    Vx = Qx;  // V_x' of node k - 1 first (eq. backv): its hand-over starts that node's contraction
    Vx.noalias() -= Qux.transpose() * kk;
    if (k > 0) vx_final(k - 1, Vx);
    KK = Qux;
    cholesky_solve(L, KK);
    Eigen::Map<Eigen::VectorXd>(k_ff + (size_t)k * m, m) = kk;
    MatMap(K_fb + (size_t)k * m * n, m, n) = KK;
    s1 += Qu.dot(kk);
    s2 += kk.dot(Quu * kk);
    Vxx = Qxx;
    add_xt_y_upper(-1.0, Qux, KK, Vxx);
    upper_to_full(Vxx);
  }
  *d1 = s1;
  *d2 = s2;
  return -1;
}

}  // namespace ric
}  // namespace geoddp
