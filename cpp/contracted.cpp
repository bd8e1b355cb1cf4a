// Contraction of the factored second-order terms with V_x' and the backward pass using it (see
// contracted.hpp). Eigen only: no Pinocchio algorithm is instantiated here.
#include "contracted.hpp"
#include "riccati_blocks.hpp"

#include <cmath>

namespace geoddp {
namespace ctr {

typedef Eigen::Map<const Eigen::MatrixXd> CColMat;

// S = sum_i Vx_i G2_i. With lq = Vx[:nv], lv = Vx[nv:]:
// * velocity rows (v+ = v + dt a): G2 = dt a_zz with a_zz = -Minv T, T_i = ID_zz,i + P_i + P_i^T,
//   P_i(j, b) = sum_l dM(i, l, j) a_z(l, b) on the q rows j (dynamics.cpp, node_derivatives). The
//   semi-implicit reconstruction adds dt Jr F2 to the q rows, so both contract with
//   c = lv + [semi] dt Jr^T lq, and sum_p c_p F2_p = sum_i mu_i T_i with mu = -dt Minv c;
//   sum_i mu_i ID_zz,i and sum_i mu_i dM(i, ., .) are matrix-vector products over Pinocchio's
//   column-major tensors;
// * reconstruction rows of each SO(3)/SE(3) group s: dt^2 W_s^T (sum_p lq_p Dsym_p) W_s and
//   (sum_p lq_p Mrec_p) on the group's q rows plus its transpose (dynamics.cpp, expansion).
void contract(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S) {
  const int nv = t.nv, m = t.m, nz = t.nz();
  const double dt = t.dt;
  const size_t n3 = (size_t)nv * nv * nv;
  // per-thread scratch: contract runs once per node in the sequential pass
  thread_local Eigen::VectorXd c, mu, r;
  thread_local RowMat R, Dl, Ml, DW;
  CVecMap lq(Vx, nv), lv(Vx + nv, nv);
  S.setZero(nz, nz);
  c = lv;
  if (t.semi) {
    c.noalias() += dt * lq;
    const double* jr = t.Jr.data() + (size_t)k * t.gJ;
    for (const JointGroup& g : t.groups) {
      const int o = g.idx_v, d = g.nv;
      c.segment(o, d) = lv.segment(o, d);
      c.segment(o, d).noalias() += dt * (CMatMap(jr, d, d).transpose() * lq.segment(o, d));
      jr += d * d;
    }
  }
  mu.noalias() = (-dt) * (CMatMap(t.Minv.data() + (size_t)k * nv * nv, nv, nv) * c);
  // r[j + nv l] = sum_i mu_i X(i, j, l) for a column-major tensor X (nv, nv, nv)
  r.resize(nv * nv);
  r.noalias() = CColMat(t.Iqq.data() + k * n3, nv, nv * nv).transpose() * mu;
  for (int j = 0; j < nv; ++j)
    for (int l = 0; l < nv; ++l) S(j, l) = 0.5 * (r[j + nv * l] + r[l + nv * j]);
  r.noalias() = CColMat(t.Ivv.data() + k * n3, nv, nv * nv).transpose() * mu;
  for (int j = 0; j < nv; ++j)
    for (int l = 0; l < nv; ++l) S(nv + j, nv + l) = 0.5 * (r[j + nv * l] + r[l + nv * j]);
  r.noalias() = CColMat(t.Iqv.data() + k * n3, nv, nv * nv).transpose() * mu;
  for (int j = 0; j < nv; ++j)
    for (int l = 0; l < nv; ++l) {
      S(j, nv + l) = r[j + nv * l];
      S(nv + l, j) = r[j + nv * l];
    }
  // Y(l, j) = sum_i mu_i dM(i, l, j); R = Y^T a_z on the q rows, and its transpose. Y is
  // column-major in r, so r read row-major is Y^T.
  r.noalias() = CColMat(t.dM.data() + k * n3, nv, nv * nv).transpose() * mu;
  R.resize(nv, nz);
  gemm::gemm(false, nv, nz, nv, 1.0, r.data(), nv, t.az.data() + (size_t)k * nv * nz, nz, false, R.data(), nz);
  S.topRows(nv) += R;
  S.leftCols(nv) += R.transpose();
  // reconstruction rows of the SO(3)/SE(3) groups
  const double* dsym = t.Dsym.data() + (size_t)k * t.gD;
  const double* mrec = t.Mrec.data() + (size_t)k * t.gM;
  const double* F1 = t.F1.data() + (size_t)k * nv * nz;
  for (const JointGroup& g : t.groups) {
    const int o = g.idx_v, d = g.nv;
    Dl.setZero(d, d);
    Ml.setZero(d, nz);
    for (int p = 0; p < d; ++p) {
      const double l = lq[o + p];
      Dl += l * CMatMap(dsym + (size_t)p * d * d, d, d);
      Ml += l * CMatMap(mrec + (size_t)p * d * nz, d, nz);
    }
    if (t.semi) {  // S += dt^2 Ws^T Dl Ws with Ws = F1's rows of the group
      const double* Ws = F1 + (size_t)o * nz;
      DW.resize(d, nz);
      gemm::gemm(false, d, nz, d, 1.0, Dl.data(), d, Ws, nz, false, DW.data(), nz);
      gemm::gemm(true, nz, nz, d, dt * dt, Ws, nz, DW.data(), nz, true, S.data(), nz);
    } else {  // W_s selects the group's v directions
      S.block(nv + o, nv + o, d, d) += (dt * dt) * Dl;
    }
    S.middleRows(o, d) += Ml;
    S.middleCols(o, d) += Ml.transpose();
    dsym += d * d * d;
    mrec += d * d * nz;
  }
  (void)m;
}

void add_contracted(const dyn::SecondOrderTerms& t, int k, const Eigen::VectorXd& Vx, RowMat& S, RowMat& Qxx,
                    RowMat& Qux, RowMat& Quu) {
  const Eigen::Index n = Qxx.rows(), m = Quu.rows();
  contract(t, k, Vx.data(), S);
  Qxx += S.topLeftCorner(n, n);
  Qux += S.bottomLeftCorner(m, n);
  Quu += S.bottomRightCorner(m, m);
}

int backward_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                             const double* lu, const double* lxx, const double* lux, const double* luu,
                             const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                             double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1, double* d2) {
  RowMat S;
  // sum_i V_x'_i Theta_i, Gamma_i^T, Xi_i (Remark rem:theta), contracted from the factors
  const auto add = [&](int k, const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
    add_contracted(t, k, Vx, S, Qxx, Qux, Quu);
  };
  return ric::unconstrained_pass(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, add, reg, k_ff, K_fb,
                                 quu_eig, d1, d2);
}

}  // namespace ctr
}  // namespace geoddp
