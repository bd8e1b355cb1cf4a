// Cholesky factorisation and triangular solves for the small dense blocks of the backward passes
// (Q_uu, m x m; V_xx mirrored), written out in a fixed order of operations (that of the first
// Python kernels), so that the passes (riccati/riccati.cpp, riccati/contracted.cpp) keep geoddp's
// results bit for bit: reordering a sum changes its last bits.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "runtime/arrays.hpp"

namespace geoddp {
namespace smallchol {


// Lower Cholesky factor of a small SPD matrix in place. False if not
// positive definite (also on NaN).
inline bool cholesky_inplace(RowMat& A) {
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

// Solve (L L^T) x = b in place for each column of b (n, k). Row operations over all columns at
// once (b is row-major: contiguous, vectorised), in the scalar loop's order for each entry: start
// from b(i, c), subtract L(i, p) b(p, c) for p ascending (descending rows in the back
// substitution: p = i + 1 ..), divide by L(i, i); so the same result bit for bit as one column at
// a time, which would leave the gains' solve (m x n) the slowest part of the pass outside its
// products.
template <typename M>
inline void cholesky_solve(const RowMat& L, M& b) {
  const int n = (int)L.rows();
  for (int i = 0; i < n; ++i) {
    for (int p = 0; p < i; ++p) b.row(i) -= L(i, p) * b.row(p);
    b.row(i) /= L(i, i);
  }
  for (int i = n - 1; i >= 0; --i) {
    for (int p = i + 1; p < n; ++p) b.row(i) -= L(p, i) * b.row(p);
    b.row(i) /= L(i, i);
  }
}

// Mirror the upper triangle into the lower one.
inline void upper_to_full(RowMat& A) {
  for (int i = 0; i < A.rows(); ++i)
    for (int j = 0; j < i; ++j) A(i, j) = A(j, i);
}

}  // namespace smallchol
}  // namespace geoddp
