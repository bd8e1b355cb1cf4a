// The variational step's derivatives at the nodes of a trajectory by implicit differentiation:
// F1 = -R_y^-1 [R_eta, R_dv, -dt H] and F2 = -R_y^-1 P^T R_ww P, or R_ww's factors for the
// contracted pass (see dynamics/variational.hpp). Compiled inside dynamics/variational_algorithms.cpp.
#include "dynamics/variational.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/LU>
#include <memory>

#include "dynamics/variational_fixed.hpp"
#include "dynamics/variational_residual.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

VariationalNodeWork::VariationalNodeWork(const VariationalModel& vm) : w(vm) {
  if (vm.root_dirs > 0 && !vm.gravity_free) turned = std::make_unique<TurnedGravity>(*vm.model);
  const int nq = vm.model->nq, nv = vm.model->nv, nz = 2 * nv + vm.m, nw = 3 * nv;
  qp.resize(nq);
  e.resize(2 * nv);  // a step along (eta, dv): the root's pose under gravity (residual_hessians)
  vp.resize(nv);
  Rz.resize(nv, nz);
  F1k.resize(nv, nz);
  Jm.resize(nv, nw);
  Tj.resize(nv, nw);
  Ts.resize(nw, nw);
  G.resize(2 * nv, nz);
  CF.resize(nv, nz);
  stack.resize(nv, (Eigen::Index)nz * (nz + 1) / 2);  // the upper triangle of each P^T Ts_i P
  T.assign(nv, Eigen::MatrixXd(nw, nw));
  for (Eigen::MatrixXd* M : {&Dbase, &Dl, &M1b, &Hp, &dSqj, &dRyj, &X}) M->resize(nv, nv);
  dMq.assign((size_t)nv * nv * nv, 0.0);
  d2qq.assign((size_t)nv * nv * nv, 0.0);
  lin.qn.resize(nq);
  lin.xi.resize(nv);
  lin.Sq0.resize(nv, nv);
  lin.Ry0.resize(nv, nv);
  lin.dSq.assign(nv, Eigen::MatrixXd(nv, nv));
  lin.dRy.assign(nv, Eigen::MatrixXd(nv, nv));
  lin.dSq_zero.assign(nv, 0);
  lin.dRy_zero.assign(nv, 0);
}

namespace var {

namespace {

// residual_jacobian at the base point for such a body, on fixed-size matrices: with M constant and
// D = 0, Sq = dR/deta+ = dt G(q+) (G the generalised gravity's derivative; zero without gravity),
//   J = [Sq Ad_exp(-dt v), dt Sq Jr(dt v) - d/dp[K(dt p)^T M p](v), d/dp[K(-dt p)^T M p](y)],
// the general path's terms with its zero D products, CRBA calls and dynamic blocks dropped. Fills
// what residual_hessians and one_body_columns read from the base call: w.qn, w.omega, w.Sq, w.Ry,
// w.K1, w.Jv = Jr(dt v), w.A = Ad_exp(-dt v) (under gravity only), w.M0 = w.M1 = M and
// w.D0 = w.D1 = 0, and J.
template <int N>
void one_body_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const double dt = vm.dt;
  const Mat M = vm.M_body;
  const Vec omega = dt * Vec(v), x1 = -dt * Vec(y);
  w.omega = omega;
  libpin::integrate(*vm.model, q, w.omega, w.qn);
  Mat Jv;
  const Mat Jdv = -phi_jacobian<N>(M, Vec(v), dt, &Jv);
  const typename L::Coef k1 = L::coefficients(x1);
  const Mat K1 = L::inverse(L::jr(x1, k1));
  const Mat Ry = phi_jacobian_K<N>(M, Vec(y), -dt, K1, k1);
  Mat Sq = Mat::Zero();
  if (vm.gravity_free) {
    w.J.leftCols(N).setZero();
  } else {
    w.T.setZero();
    libpin::computeGeneralizedGravityDerivatives(*vm.model, w.data, w.qn, w.T);
    Sq = dt * Mat(w.T);
    const Mat A = L::ad_exp_minus(omega);
    w.A = A;
    w.J.leftCols(N) = Sq * A;
  }
  w.J.middleCols(N, N) = Jdv + dt * (Sq * Jv);
  w.J.rightCols(N) = Ry;
  w.Sq = Sq;
  w.Ry = Ry;
  w.K1 = K1;
  w.Jv = Jv;
  w.M0 = M;
  w.M1 = M;
  w.D0.setZero();
  w.D1.setZero();
}

// The first order at a node: the base residual_jacobian (it computes everything the differences
// below may keep; with `second`, the tensors dM/dq and d/dq D at q+ they read), R_y's LU in nw.lu_y
// and F1 = -R_y^-1 [R_eta, R_dv, -dt H] in nw.F1k and F1.
void node_first_order(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, bool second) {
  const int nv = vm.model->nv, m = vm.m, nz = 2 * nv + m;
  CMatMap Hm(vm.H, nv, m);
  VariationalWork& w = nw.w;
  if (vm.configuration_free) {
    if (nv == 6) one_body_jacobian<6>(vm, w, q, v, y);
    else one_body_jacobian<3>(vm, w, q, v, y);
  } else {
    Keep base;
    base.tensors = second;
    residual_jacobian(vm, w, q, v, y, w.J, base);
  }
  nw.lu_y.compute(w.J.rightCols(nv));
  nw.Rz.leftCols(2 * nv) = w.J.leftCols(2 * nv);
  nw.Rz.rightCols(m) = -vm.dt * Hm;
  nw.F1k = -nw.lu_y.solve(nw.Rz);
  Eigen::Map<RowMat>(F1, nv, nz) = nw.F1k;
}

}  // namespace
}  // namespace var

void variational_node(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, double* F2) {
  const int nv = vm.model->nv, nz = 2 * nv + vm.m;
  var::node_first_order(vm, nw, q, v, y, F1, F2 != nullptr);
  if (F2 == nullptr) return;
  var::residual_hessians(vm, nw, q, v, y);
  const Eigen::PartialPivLU<Eigen::MatrixXd>& lu = nw.lu_y;
  // Differentiating the right-trivialised Jacobian along integrate(q, h e_j) adds an antisymmetric bracket
  // term to the eta-eta block: the symmetric part Ts is the (0)-Hessian. R is affine in u, so u enters only
  // through P = dw/dz = [I 0; 0 I; F1]: P^T Ts P on its upper triangle (dynamics/second_order_terms.hpp,
  // variational_projection_upper), a third of the two dense (3nv)^2 nz products it replaces.
  const int nu = nz * (nz + 1) / 2;
  for (int i = 0; i < nv; ++i) {
    nw.Ts = 0.5 * (nw.T[i] + nw.T[i].transpose());
    int c = 0;
    variational_projection_upper(nw.Ts, nw.F1k, nw.G, nw.CF, [&](int, int, double s) { nw.stack(i, c++) = s; });
  }
  // F2 = -R_y^-1 P^T Ts P: the LU factors applied column by column (nv <= a few tens: plain loops,
  // not Eigen's blocked triangular solves, which dominated at nv = 6)
  nw.stack = lu.permutationP() * nw.stack;
  const Eigen::MatrixXd& LU = lu.matrixLU();
  for (int c = 0; c < nu; ++c) {
    double* x = nw.stack.col(c).data();
    for (int r = 1; r < nv; ++r) {
      double s = x[r];
      for (int j = 0; j < r; ++j) s -= LU(r, j) * x[j];
      x[r] = s;
    }
    for (int r = nv - 1; r >= 0; --r) {
      double s = x[r];
      for (int j = r + 1; j < nv; ++j) s -= LU(r, j) * x[j];
      x[r] = s / LU(r, r);
    }
  }
  // exactly symmetric, as the Python oracle's F2
  for (int i = 0; i < nv; ++i) {
    int c = 0;
    for (int a = 0; a < nz; ++a)
      for (int b = a; b < nz; ++b, ++c) {
        const double f = -nw.stack(i, c);
        F2[((size_t)i * nz + a) * nz + b] = f;
        F2[((size_t)i * nz + b) * nz + a] = f;
      }
  }
}

void variational_node_factored(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                               const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, double* RyInvT,
                               double* Ts) {
  const int nv = vm.model->nv, nw3 = 3 * nv;
  var::node_first_order(vm, nw, q, v, y, F1, true);
  var::residual_hessians(vm, nw, q, v, y);
  // R_y^-T, column by column from the LU factors (a once-per-node nv x nv inverse: the pass then
  // contracts with one matrix-vector product)
  Eigen::Map<RowMat>(RyInvT, nv, nv) = nw.lu_y.inverse().transpose();
  // the symmetric parts (the eta-eta block's antisymmetric bracket term dropped, as in
  // variational_node), upper triangles, i fastest
  for (int i = 0; i < nv; ++i) {
    const Eigen::MatrixXd& T = nw.T[i];
    int c = 0;
    for (int a = 0; a < nw3; ++a)
      for (int b = a; b < nw3; ++b, ++c) Ts[(size_t)c * nv + i] = 0.5 * (T(a, b) + T(b, a));
  }
}

void variational_velocity_derivatives(const VariationalModel& vm, const double* Q, const double* V,
                                      const double* Vnext, int N, int order, int threads, double* F1, double* F2) {
  const int nq = vm.model->nq, nv = vm.model->nv, nz = 2 * nv + vm.m;
  parallel_nodes(N, threads, [&](int begin, int end) {
    VariationalNodeWork nw(vm);
    Eigen::VectorXd q(nq), v(nv), y(nv);
    for (int k = begin; k < end; ++k) {
      q = CVecMap(Q + (size_t)k * nq, nq);
      v = CVecMap(V + (size_t)k * nv, nv);
      y = CVecMap(Vnext + (size_t)k * nv, nv);
      variational_node(vm, nw, q, v, y, F1 + (size_t)k * nv * nz,
                       order >= 2 ? F2 + (size_t)k * nv * nz * nz : nullptr);
    }
  });
}

}  // namespace dyn
}  // namespace geoddp
