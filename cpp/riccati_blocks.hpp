// The two dense steps every backward pass shares (riccati.cpp: plain and box-constrained;
// contracted.cpp): the Q-function's blocks from the next node's value function (paper eq.
// Qfunctions, first-order part) and the value function's Hessian update (eq. backv). Products go
// through small_gemm.hpp; symmetric results are computed on their upper triangle only and
// completed by the caller (upper_to_full), as the passes always did.
#pragma once

#include "small_gemm.hpp"

#include <Eigen/Core>

namespace geoddp {
namespace ric {

typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> BlockMat;

// Node k's blocks, Phi (n, n) and B (n, m) row-major, l* its cost derivatives (row-major, l_xx
// and l_uu read in full): Qx = lx + Phi^T Vx, Qu = lu + B^T Vx, Qxx = lxx + Phi^T Vxx Phi (upper
// triangle exact, lower = lxx's plus junk), Qux = lux + B^T Vxx Phi, Quu = luu + B^T Vxx B (upper
// exact). VxxPhi (n, n) and VxxB (n, m) are scratch. Vxx must be full (both triangles).
inline void q_blocks(int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                     const double* lxx, const double* lux, const double* luu, const Eigen::VectorXd& Vx,
                     const BlockMat& Vxx, BlockMat& VxxPhi, BlockMat& VxxB, Eigen::VectorXd& Qx,
                     Eigen::VectorXd& Qu, BlockMat& Qxx, BlockMat& Qux, BlockMat& Quu) {
  typedef Eigen::Map<const BlockMat> CMat;
  typedef Eigen::Map<const Eigen::VectorXd> CVec;
  const CMat P(Phi, n, n), Bk(B, n, m);
  Qx = CVec(lx, n);
  Qx.noalias() += P.transpose() * Vx;
  Qu = CVec(lu, m);
  Qu.noalias() += Bk.transpose() * Vx;
  gemm::gemm(false, n, n, n, 1.0, Vxx.data(), n, Phi, n, false, VxxPhi.data(), n);
  gemm::gemm(false, n, m, n, 1.0, Vxx.data(), n, B, m, false, VxxB.data(), m);
  Qxx = CMat(lxx, n, n);
  gemm::gemm_upper(true, n, n, 1.0, Phi, n, VxxPhi.data(), n, true, Qxx.data(), n);
  Qux = CMat(lux, m, n);
  gemm::gemm(true, m, n, n, 1.0, B, m, VxxPhi.data(), n, true, Qux.data(), n);
  Quu = CMat(luu, m, m);
  gemm::gemm_upper(true, m, n, 1.0, B, m, VxxB.data(), m, true, Quu.data(), m);
}

// Vxx += alpha X^T Y on the upper triangle, X and Y (m, n) row-major (Vxx (n, n)).
inline void add_xt_y_upper(double alpha, const BlockMat& X, const BlockMat& Y, BlockMat& Vxx) {
  const int n = (int)Vxx.rows(), m = (int)X.rows();
  gemm::gemm_upper(true, n, m, alpha, X.data(), n, Y.data(), n, true, Vxx.data(), n);
}

}  // namespace ric
}  // namespace geoddp
