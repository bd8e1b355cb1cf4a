// The backward Riccati recursion (see riccati.hpp): Eigen products on the node's blocks instead of
// numba's scalar loops; the Cholesky factor and its solves follow the numba kernel's arithmetic.
#include "riccati.hpp"

#include <Eigen/Core>
#include <cmath>

namespace geoddp {
namespace ric {

typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMat;
typedef Eigen::Map<const RowMat> CMat;
typedef Eigen::Map<const Eigen::VectorXd> CVec;

// Lower Cholesky factor of a small SPD matrix in place (numba's _cholesky_inplace). False if not
// positive definite (also on NaN).
static bool cholesky_inplace(RowMat& A) {
  const int n = (int)A.rows();
  for (int j = 0; j < n; ++j) {
    double s = A(j, j);
    for (int p = 0; p < j; ++p) s -= A(j, p) * A(j, p);
    if (!(s > 0.0)) return false;
    const double d = std::sqrt(s);
    A(j, j) = d;
    for (int i = j + 1; i < n; ++i) {
      double t = A(i, j);
      for (int p = 0; p < j; ++p) t -= A(i, p) * A(j, p);
      A(i, j) = t / d;
    }
    for (int i = 0; i < j; ++i) A(i, j) = 0.0;
  }
  return true;
}

// Solve (L L^T) x = b in place for each column of b (n, k).
template <typename M>
static void cholesky_solve(const RowMat& L, M& b) {
  const int n = (int)L.rows();
  for (int c = 0; c < b.cols(); ++c) {
    for (int i = 0; i < n; ++i) {
      double s = b(i, c);
      for (int p = 0; p < i; ++p) s -= L(i, p) * b(p, c);
      b(i, c) = s / L(i, i);
    }
    for (int i = n - 1; i >= 0; --i) {
      double s = b(i, c);
      for (int p = i + 1; p < n; ++p) s -= L(p, i) * b(p, c);
      b(i, c) = s / L(i, i);
    }
  }
}

// Mirror the upper triangle into the lower one.
static void upper_to_full(RowMat& A) {
  for (int i = 0; i < A.rows(); ++i)
    for (int j = 0; j < i; ++j) A(i, j) = A(j, i);
}

int backward_pass(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                  const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                  const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi,
                  bool second_order, double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1,
                  double* d2) {
  Eigen::VectorXd Vx = CVec(Vx_final, n), Qx(n), Qu(m), kk(m);
  RowMat Vxx = CMat(Vxx_final, n, n);  // as given (the numba kernel reads all of it)
  RowMat Qxx(n, n), Qux(m, n), Quu(m, m), L(m, m), VxxPhi(n, n), VxxB(n, m), KK(m, n);
  double s1 = 0.0, s2 = 0.0;
  *d1 = 0.0;
  *d2 = 0.0;
  for (int k = H - 1; k >= 0; --k) {
    CMat P(Phi + (size_t)k * n * n, n, n), Bk(B + (size_t)k * n * m, n, m);
    VxxPhi.noalias() = Vxx * P;
    VxxB.noalias() = Vxx * Bk;
    Qx = CVec(lx + (size_t)k * n, n);
    Qx.noalias() += P.transpose() * Vx;
    Qu = CVec(lu + (size_t)k * m, m);
    Qu.noalias() += Bk.transpose() * Vx;
    Qxx = CMat(lxx + (size_t)k * n * n, n, n);
    Qxx.noalias() += P.transpose() * VxxPhi;
    Qux = CMat(lux + (size_t)k * m * n, m, n);
    Qux.noalias() += Bk.transpose() * VxxPhi;
    Quu = CMat(luu + (size_t)k * m * m, m, m);
    Quu.noalias() += Bk.transpose() * VxxB;
    if (second_order) {
      // sum_i V_x'_i Theta_i, Gamma_i^T, Xi_i (Remark rem:theta)
      const double* Th = Theta + (size_t)k * n * n * n;
      const double* Ga = Gamma + (size_t)k * n * n * m;
      const double* X = Xi + (size_t)k * n * m * m;
      for (int i = 0; i < n; ++i) {
        const double v = Vx[i];
        if (v == 0.0) continue;
        Qxx += v * CMat(Th + (size_t)i * n * n, n, n);
        Qux += v * CMat(Ga + (size_t)i * n * m, n, m).transpose();
        Quu += v * CMat(X + (size_t)i * m * m, m, m);
      }
    }
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
    KK = Qux;
    cholesky_solve(L, kk);
    cholesky_solve(L, KK);
    Eigen::Map<Eigen::VectorXd>(k_ff + (size_t)k * m, m) = kk;
    Eigen::Map<RowMat>(K_fb + (size_t)k * m * n, m, n) = KK;
    s1 += Qu.dot(kk);
    s2 += kk.dot(Quu * kk);
    Vx = Qx;
    Vx.noalias() -= Qux.transpose() * kk;
    Vxx = Qxx;
    Vxx.noalias() -= Qux.transpose() * KK;
    upper_to_full(Vxx);
  }
  *d1 = s1;
  *d2 = s2;
  return -1;
}

}  // namespace ric
}  // namespace geoddp
