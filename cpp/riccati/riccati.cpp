// The backward Riccati recursion (see riccati/riccati.hpp): the node's dense products through
// riccati/riccati_blocks.hpp (linalg/small_gemm.hpp); the Cholesky factor and its solves in a fixed
// order of operations (linalg/small_cholesky.hpp).
#include "riccati/riccati.hpp"
#include "riccati/riccati_blocks.hpp"
#include "linalg/small_cholesky.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

namespace geoddp {
namespace ric {

using smallchol::cholesky_inplace;
using smallchol::cholesky_solve;
using smallchol::upper_to_full;

namespace {

// The unconstrained pass with n = N known at compile time (and m = M, or m at run time for M = 0):
// scalar loops over row-major blocks, which the compiler unrolls. At n = 6 (TSO(3): the satellite,
// any one body on a spherical root) this beats the general pass's product kernels, whose dispatch
// costs more than a 6 x 6 block's arithmetic. The order of every sum is fixed (the products row
// by row, p ascending; Q_xx, Q_uu and V_xx on their upper triangles, then mirrored): it is the order
// the satellite's results were first computed in, kept so that they stay the same bit for bit.
template <int N, int M>
int fixed_pass(int H, int m_runtime, const double* Phi, const double* B, const double* lx, const double* lu,
               const double* lxx, const double* lux, const double* luu, const double* Vx_final,
               const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi, bool second_order,
               double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1, double* d2) {
  constexpr int n = N;
  const int m = M > 0 ? M : m_runtime;
  double Vx[N], Vxx[N * N], Qx[N], Qxx[N * N], VxxPhi[N * N];
  std::copy(Vx_final, Vx_final + n, Vx);
  std::copy(Vxx_final, Vxx_final + n * n, Vxx);
  std::vector<double> buf((size_t)m * (1 + n + m + n));
  double *Qu = buf.data(), *Qux = Qu + m, *Quu = Qux + (size_t)m * n, *VxxB = Quu + (size_t)m * m;
  RowMat Lf(m, m);  // Q_uu + reg I, then its Cholesky factor
  double s1 = 0.0, s2 = 0.0;
  for (int k = H - 1; k >= 0; --k) {
    const double* P = Phi + (size_t)k * n * n;
    const double* Bk = B + (size_t)k * n * m;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        double s = 0.0;
        for (int p = 0; p < n; ++p) s += Vxx[i * n + p] * P[p * n + j];
        VxxPhi[i * n + j] = s;
      }
      for (int j = 0; j < m; ++j) {
        double s = 0.0;
        for (int p = 0; p < n; ++p) s += Vxx[i * n + p] * Bk[p * m + j];
        VxxB[i * m + j] = s;
      }
    }
    for (int i = 0; i < n; ++i) {
      double s = lx[(size_t)k * n + i];
      for (int p = 0; p < n; ++p) s += P[p * n + i] * Vx[p];
      Qx[i] = s;
      for (int j = i; j < n; ++j) {
        double t = lxx[(size_t)k * n * n + i * n + j];
        for (int p = 0; p < n; ++p) t += P[p * n + i] * VxxPhi[p * n + j];
        Qxx[i * n + j] = t;
      }
    }
    for (int a = 0; a < m; ++a) {
      double s = lu[(size_t)k * m + a];
      for (int p = 0; p < n; ++p) s += Bk[p * m + a] * Vx[p];
      Qu[a] = s;
      for (int j = 0; j < n; ++j) {
        double t = lux[(size_t)k * m * n + a * n + j];
        for (int p = 0; p < n; ++p) t += Bk[p * m + a] * VxxPhi[p * n + j];
        Qux[a * n + j] = t;
      }
      for (int b = a; b < m; ++b) {
        double t = luu[(size_t)k * m * m + a * m + b];
        for (int p = 0; p < n; ++p) t += Bk[p * m + a] * VxxB[p * m + b];
        Quu[a * m + b] = t;
      }
    }
    if (second_order) {  // sum_i V_x'_i Theta_i, Gamma_i^T, Xi_i (Remark rem:theta), upper triangles
      const double* Th = Theta + (size_t)k * n * n * n;
      const double* Ga = Gamma + (size_t)k * n * n * m;
      const double* X = Xi + (size_t)k * n * m * m;
      for (int i = 0; i < n; ++i) {
        const double v = Vx[i];
        if (v == 0.0) continue;
        for (int a = 0; a < n; ++a) {
          for (int b = a; b < n; ++b) Qxx[a * n + b] += v * Th[(i * n + a) * n + b];
          for (int c = 0; c < m; ++c) Qux[c * n + a] += v * Ga[((size_t)i * n + a) * m + c];
        }
        for (int a = 0; a < m; ++a)
          for (int b = a; b < m; ++b) Quu[a * m + b] += v * X[((size_t)i * m + a) * m + b];
      }
    }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < i; ++j) Qxx[i * n + j] = Qxx[j * n + i];
    for (int a = 0; a < m; ++a) {
      for (int b = 0; b < a; ++b) Quu[a * m + b] = Quu[b * m + a];
      for (int b = 0; b < m; ++b) Lf(a, b) = Quu[a * m + b];
      Lf(a, a) += reg;
    }
    if (!cholesky_inplace(Lf)) {
      *d1 = s1;
      *d2 = s2;
      return k;
    }
    double mn = Lf(0, 0) * Lf(0, 0);
    for (int a = 1; a < m; ++a)
      if (Lf(a, a) * Lf(a, a) < mn) mn = Lf(a, a) * Lf(a, a);
    quu_eig[k] = mn;
    double* kk = k_ff + (size_t)k * m;
    double* KK = K_fb + (size_t)k * m * n;
    std::copy(Qu, Qu + m, kk);
    std::copy(Qux, Qux + (size_t)m * n, KK);
    Eigen::Map<Eigen::VectorXd> kv(kk, m);
    Eigen::Map<RowMat> Kv(KK, m, n);
    cholesky_solve(Lf, kv);
    cholesky_solve(Lf, Kv);
    for (int a = 0; a < m; ++a) {
      s1 += Qu[a] * kk[a];
      double s = 0.0;
      for (int b = 0; b < m; ++b) s += Quu[a * m + b] * kk[b];
      s2 += kk[a] * s;
    }
    for (int i = 0; i < n; ++i) {
      double s = Qx[i];
      for (int a = 0; a < m; ++a) s -= Qux[a * n + i] * kk[a];
      Vx[i] = s;
      for (int j = i; j < n; ++j) {
        double t = Qxx[i * n + j];
        for (int a = 0; a < m; ++a) t -= Qux[a * n + i] * KK[a * n + j];
        Vxx[i * n + j] = t;
      }
    }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < i; ++j) Vxx[i * n + j] = Vxx[j * n + i];
  }
  *d1 = s1;
  *d2 = s2;
  return -1;
}

}  // namespace

int backward_pass(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                  const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                  const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi,
                  bool second_order, double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1,
                  double* d2) {
  if (n == 6 && m == 3)
    return fixed_pass<6, 3>(H, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi, second_order,
                            reg, k_ff, K_fb, quu_eig, d1, d2);
  if (n == 6)
    return fixed_pass<6, 0>(H, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, Theta, Gamma, Xi, second_order,
                            reg, k_ff, K_fb, quu_eig, d1, d2);
  const auto add = [&](int k, const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
    if (second_order) add_dense_second_order(n, m, Theta, Gamma, Xi, k, Vx, Qxx, Qux, Quu);
  };
  return unconstrained_pass(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, add, reg, k_ff, K_fb,
                            quu_eig, d1, d2);
}

void gradient(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
              const double* lx_final, double* out) {
  std::vector<double> psi(lx_final, lx_final + n), nxt(n);
  for (int k = H - 1; k >= 0; --k) {
    const double* Bk = B + (size_t)n * m * k;
    const double* Pk = Phi + (size_t)n * n * k;
    for (int a = 0; a < m; ++a) {
      double s = lu[(size_t)m * k + a];
      for (int p = 0; p < n; ++p) s += Bk[(size_t)m * p + a] * psi[p];
      out[(size_t)m * k + a] = s;
    }
    for (int i = 0; i < n; ++i) {
      double s = lx[(size_t)n * k + i];
      for (int p = 0; p < n; ++p) s += Pk[(size_t)n * p + i] * psi[p];
      nxt[i] = s;
    }
    psi.swap(nxt);
  }
}

// ------------------------------------------------------------------ box-constrained pass (control limits)
// Projected Newton on a box (Tassa, Mansard and Todorov, "Control-limited differential dynamic
// programming", ICRA 2014, Algorithm 3; written from the paper): each iteration fixes the inputs
// at a bound whose gradient pushes outward, takes the Newton step on the free face and an Armijo
// line search along its projection onto the box.
static const int BOX_MAX_ITER = 100;
static const double BOX_ARMIJO = 0.1;      // sufficient decrease, fraction of the first-order model
static const double BOX_STEP_FACTOR = 0.6;
static const double BOX_MIN_STEP = 1e-12;  // below: the decrease is round-off, the face solve polishes

namespace {

struct BoxWork {
  Eigen::VectorXd g, rhs, xt, dx, Hy;
  std::vector<signed char> cl, prev;
  std::vector<int> fidx;
  RowMat Lf;
};

// -1 where x sits at lo and the gradient pushes below it, +1 at hi pushing above, else 0; an
// input with lo == hi is always clamped (sign by its gradient). Returns the number of free inputs.
int clamp_set(const Eigen::VectorXd& x, const Eigen::VectorXd& g, const double* lo, const double* hi,
              std::vector<signed char>& cl) {
  int nf = 0;
  for (int i = 0; i < (int)x.size(); ++i) {
    signed char c = 0;
    if (lo[i] == hi[i]) c = g[i] >= 0.0 ? -1 : 1;
    else if (x[i] <= lo[i] && g[i] > 0.0) c = -1;
    else if (x[i] >= hi[i] && g[i] < 0.0) c = 1;
    cl[i] = c;
    if (!c) ++nf;
  }
  return nf;
}

// Cholesky factor of the free block of Hq into w.Lf (free indices into w.fidx).
bool factor_free(const RowMat& Hq, BoxWork& w) {
  w.fidx.clear();
  for (int i = 0; i < (int)w.cl.size(); ++i)
    if (!w.cl[i]) w.fidx.push_back(i);
  const int nf = (int)w.fidx.size();
  w.Lf.resize(nf, nf);
  for (int a = 0; a < nf; ++a)
    for (int b = 0; b < nf; ++b) w.Lf(a, b) = Hq(w.fidx[a], w.fidx[b]);
  return cholesky_inplace(w.Lf);
}

// Minimiser of the QP on the current face: x_f = Hq_ff^-1 (q_f - Hq_fc x_c), into out.
void face_newton(const RowMat& Hq, const Eigen::VectorXd& q, const Eigen::VectorXd& x, BoxWork& w,
                 Eigen::VectorXd& out) {
  const int nf = (int)w.fidx.size(), m = (int)x.size();
  w.rhs.resize(nf);
  for (int a = 0; a < nf; ++a) {
    const int i = w.fidx[a];
    double r = q[i];
    for (int j = 0; j < m; ++j)
      if (w.cl[j]) r -= Hq(i, j) * x[j];
    w.rhs[a] = r;
  }
  cholesky_solve(w.Lf, w.rhs);
  out = x;
  for (int a = 0; a < nf; ++a) out[w.fidx[a]] = w.rhs[a];
}

double qp_value(const RowMat& Hq, const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::VectorXd& Hy) {
  Hy.noalias() = Hq * y;
  return 0.5 * y.dot(Hy) - q.dot(y);
}

// The projected Newton iteration (see box_qp in riccati/riccati.hpp); on return w.cl, w.fidx, w.Lf
// describe the final face (Lf factorises Hq_ff) and x is the face minimiser clipped to the box.
int box_qp_impl(const RowMat& Hq, const Eigen::VectorXd& q, const double* lo, const double* hi,
                Eigen::VectorXd& x, BoxWork& w) {
  const int m = (int)x.size();
  w.cl.assign(m, 0);
  w.prev.assign(m, 2);
  for (int i = 0; i < m; ++i) {
    if (!std::isfinite(x[i])) x[i] = 0.0;
    x[i] = std::min(std::max(x[i], lo[i]), hi[i]);
  }
  bool prev_full = false, have_factor = false;
  int it = 0;
  for (; it < BOX_MAX_ITER; ++it) {
    w.g.noalias() = Hq * x - q;
    const int nf = clamp_set(x, w.g, lo, hi, w.cl);
    if (nf == 0) break;
    const bool changed = w.cl != w.prev;
    if (!changed && prev_full) break;  // a full, unclipped face step and the same face: KKT holds
    if (changed || !have_factor) {
      if (!factor_free(Hq, w)) return -1;
      have_factor = true;
    }
    face_newton(Hq, q, x, w, w.xt);
    w.dx = w.xt - x;
    const double sdotg = w.dx.dot(w.g);
    w.prev = w.cl;
    if (!(sdotg < 0.0)) {  // the face minimiser is x itself
      prev_full = true;
      continue;
    }
    const double f0 = qp_value(Hq, q, x, w.Hy);
    double step = 1.0;
    bool ok = false, clipped = false;
    while (step >= BOX_MIN_STEP) {
      clipped = false;
      for (int i = 0; i < m; ++i) {
        const double y = x[i] + step * w.dx[i];
        const double c = std::min(std::max(y, lo[i]), hi[i]);
        clipped |= c != y;
        w.xt[i] = c;
      }
      if (qp_value(Hq, q, w.xt, w.Hy) - f0 <= BOX_ARMIJO * step * sdotg) {
        ok = true;
        break;
      }
      step *= BOX_STEP_FACTOR;
    }
    if (!ok) break;
    x = w.xt;
    prev_full = step == 1.0 && !clipped;
  }
  // Polish on the final face: the same factor then gives the feedback rows.
  w.g.noalias() = Hq * x - q;
  clamp_set(x, w.g, lo, hi, w.cl);
  if (!factor_free(Hq, w)) return -1;
  face_newton(Hq, q, x, w, w.xt);
  for (int i = 0; i < m; ++i) x[i] = std::min(std::max(w.xt[i], lo[i]), hi[i]);
  return it;
}

}  // namespace

int box_qp(int m, const double* Hq, const double* q, const double* lo, const double* hi, double* x,
           signed char* clamped) {
  RowMat H = CMatMap(Hq, m, m);
  Eigen::VectorXd qq = CVecMap(q, m), xx = Eigen::Map<Eigen::VectorXd>(x, m);
  BoxWork w;
  const int it = box_qp_impl(H, qq, lo, hi, xx, w);
  if (it < 0) return -1;
  Eigen::Map<Eigen::VectorXd>(x, m) = xx;
  for (int i = 0; i < m; ++i) clamped[i] = w.cl[i];
  return it;
}

int backward_pass_box(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                      const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                      const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi,
                      bool second_order, double reg, const double* u_bar, const double* lower, const double* upper,
                      double* k_ff, double* K_fb, double* quu_eig, signed char* active, double* Vx0, double* Vxx0,
                      double* d1, double* d2) {
  // sum_i V_x'_i Theta_i, Gamma_i^T, Xi_i from the dense tensors (Remark rem:theta)
  const SecondOrderHook dense = [&](int k, const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
    add_dense_second_order(n, m, Theta, Gamma, Xi, k, Vx, Qxx, Qux, Quu);
  };
  return backward_pass_box_hook(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final,
                                second_order ? &dense : nullptr, reg, u_bar, lower, upper, k_ff, K_fb, quu_eig,
                                active, Vx0, Vxx0, d1, d2);
}

int backward_pass_box_hook(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                           const double* lu, const double* lxx, const double* lux, const double* luu,
                           const double* Vx_final, const double* Vxx_final, const SecondOrderHook* second,
                           double reg, const double* u_bar, const double* lower, const double* upper, double* k_ff,
                           double* K_fb, double* quu_eig, signed char* active, double* Vx0, double* Vxx0, double* d1,
                           double* d2, const HandOverHook* vx_final) {
  // Q blocks as in unconstrained_pass (riccati/riccati_blocks.hpp); the box QP and the full value update
  // below are this pass's own.
  Eigen::VectorXd Vx = CVecMap(Vx_final, n), Qx(n), Qu(m), kk(m), QuuK(m), lo(m), hi(m);
  RowMat Vxx = CMatMap(Vxx_final, n, n);
  RowMat Qxx(n, n), Qux(m, n), Quu(m, m), L(m, m), Hq(m, m), VxxPhi(n, n), VxxB(n, m), KK(m, n), QuuKK(m, n),
      KKf(m, n);
  BoxWork w;
  double s1 = 0.0, s2 = 0.0;
  *d1 = 0.0;
  *d2 = 0.0;
  if (vx_final && H > 0) (*vx_final)(H - 1, Vx);
  for (int k = H - 1; k >= 0; --k) {
    q_blocks(n, m, Phi + (size_t)k * n * n, B + (size_t)k * n * m, lx + (size_t)k * n, lu + (size_t)k * m,
             lxx + (size_t)k * n * n, lux + (size_t)k * m * n, luu + (size_t)k * m * m, Vx, Vxx, VxxPhi, VxxB, Qx, Qu,
             Qxx, Qux, Quu);
    if (second) (*second)(k, Vx, Qxx, Qux, Quu);
    upper_to_full(Qxx);
    upper_to_full(Quu);
    // Regularisation rule: the whole Q_uu + reg I must be positive definite (the caller raises reg
    // otherwise), so every box QP below is strictly convex and its minimiser unique.
    L = Quu;
    L.diagonal().array() += reg;
    Hq = L;
    if (!cholesky_inplace(L)) {
      *d1 = s1;
      *d2 = s2;
      return k;
    }
    double mn = L(0, 0) * L(0, 0);
    for (int a = 1; a < m; ++a) mn = std::min(mn, L(a, a) * L(a, a));
    quu_eig[k] = mn;
    // u = u_bar - k: lower <= u <= upper  <=>  u_bar - upper <= k <= u_bar - lower
    for (int a = 0; a < m; ++a) {
      const size_t i = (size_t)k * m + a;
      lo[a] = u_bar[i] - upper[i];
      hi[a] = u_bar[i] - lower[i];
      kk[a] = k_ff[i];  // warm start: the previous feedforward
    }
    if (box_qp_impl(Hq, Qu, lo.data(), hi.data(), kk, w) < 0) {
      *d1 = s1;
      *d2 = s2;
      return k;
    }
    KK.setZero();
    if (!w.fidx.empty()) {  // free rows: (Q_uu + reg I)_ff^-1 Q_ux,f; clamped rows stay zero
      const int nf = (int)w.fidx.size();
      for (int a = 0; a < nf; ++a) KKf.row(a) = Qux.row(w.fidx[a]);
      auto rhs = KKf.topRows(nf);
      cholesky_solve(w.Lf, rhs);
      for (int a = 0; a < nf; ++a) KK.row(w.fidx[a]) = KKf.row(a);
    }
    for (int a = 0; a < m; ++a) active[(size_t)k * m + a] = (signed char)(-w.cl[a]);  // k at its lower = u at upper
    Eigen::Map<Eigen::VectorXd>(k_ff + (size_t)k * m, m) = kk;
    Eigen::Map<RowMat>(K_fb + (size_t)k * m * n, m, n) = KK;
    QuuK.noalias() = Quu * kk;
    s1 += Qu.dot(kk);
    s2 += kk.dot(QuuK);
    // The full value update: V(zeta) = Q(zeta, -k - K zeta), exact for any k, K (clamped rows,
    // reg > 0); the short form Qx - K^T Qu (Crocoddyl's box solvers) holds only for k = Quu^-1 Qu.
    //   Vx  = Qx  - K^T Qu  - Qux^T k + K^T Quu k = Qx  - Qux^T k + K^T (Quu k - Qu)
    //   Vxx = Qxx - K^T Qux - Qux^T K + K^T Quu K = Qxx - Qux^T K + K^T (Quu K - Qux)
    QuuK -= Qu;
    QuuKK.noalias() = Quu * KK;
    QuuKK -= Qux;
    Vx = Qx;
    Vx.noalias() -= Qux.transpose() * kk;
    Vx.noalias() += KK.transpose() * QuuK;
    if (vx_final && k > 0) (*vx_final)(k - 1, Vx);
    Vxx = Qxx;
    add_xt_y_upper(-1.0, Qux, KK, Vxx);
    add_xt_y_upper(1.0, KK, QuuKK, Vxx);
    upper_to_full(Vxx);  // exactly symmetric
  }
  if (Vx0) Eigen::Map<Eigen::VectorXd>(Vx0, n) = Vx;
  if (Vxx0) Eigen::Map<RowMat>(Vxx0, n, n) = Vxx;
  *d1 = s1;
  *d2 = s2;
  return -1;
}

}  // namespace ric
}  // namespace geoddp
