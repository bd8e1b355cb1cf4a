// R_ww, the variational residual's second derivatives along w = (eta, dv, y) at a node, after
// its first order (see variational_residual.hpp's residual_hessians). Compiled inside
// dynamics/variational_algorithms.cpp.
#include "dynamics/variational_residual.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <vector>

#include "dynamics/variational_fixed.hpp"
#include "lie/joint_blocks.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {
namespace var {

// the block-diagonal reconstruction operators (lie/joint_blocks.hpp)
using lie::block_transpose_times;
using lie::times_block;

namespace {

// residual_hessians' columns for such a body (after the q+ model L), on fixed-size matrices, exactly:
// the d/dp[K(c p)^T M p] parts from phi_hessian, and chain-rule terms for everything Sq touches
// (below). Along dv,
// J = [Sq Ad_exp(-dt v'), dt Sq Jr(dt v') - d/dp[K(dt p)^T M p](v'), R_y] with R_y fixed (the
// root's pose moves the body rigidly: L.dRy all zero) and Sq that of L at q+' = q exp(dt v');
// along y only R_y = d/dp[K(-dt p)^T M p](y') moves.
template <int N>
void one_body_columns(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& v,
                      const Eigen::VectorXd& y) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const double dt = vm.dt;
  const QplusLinear& lin = nw.lin;
  VariationalWork& w = nw.w;
  const Mat M = w.M0;  // M(q) = M(q+): constant for such a body
  const Vec v0 = v, y0 = y;
  const bool Sq_zero = lin.Sq_zero;
  // Sq = dR/deta+ moves only through q+ = q exp(eta) exp(dt (v + dv)), along q+'s first-order model
  // Sq(xi) = Sq0 + sum_k xi_k dSq[k], xi = difference(q+0, q+), whose derivatives are exact closed
  // forms (no integrate/difference per differenced point):
  //   d xi / d eta = Ad_exp(-omega0) = A0, since exp(-omega0) exp(eta) exp(omega0) = exp(A0 eta);
  //   d xi / d dv  = dt Jr(omega0) = dt Jv0, since exp(-omega0) exp(omega0 + dt dv) = exp(dt Jv0 dv + ...).
  // The terms Sq multiplies are exact too: d/d dv_l Ad_exp(-dt v) = -dt A0 ad(Jr(-omega0) e_l) and
  // d/d dv_l Jr(dt v) = dt dJr(omega0)/dx_l.
  const Vec omega0 = dt * v0;
  Mat Dv[N], Dy[N];  // dJr at omega0 = dt v0 and at -dt y0 (phi_hessian's points)
  L::djr(omega0, Dv);
  L::djr(Vec(-dt * y0), Dy);
  Mat A0, Jv0, dSq_eta[N], dSq_dv[N], dA[N], dJv[N];
  if (!Sq_zero) {
    A0 = w.A;  // the base call's (one_body_jacobian)
    Jv0 = w.Jv;
    const Vec xm = -omega0;
    const Mat Jm = L::jr(xm, L::coefficients(xm));  // Jr(-omega0)
    for (int l = 0; l < N; ++l) {
      dSq_eta[l].setZero();
      dSq_dv[l].setZero();
      for (int k = 0; k < N; ++k) {
        if (lin.dSq_zero[k]) continue;
        dSq_eta[l] += A0(k, l) * lin.dSq[k];
        dSq_dv[l] += (dt * Jv0(k, l)) * lin.dSq[k];
      }
      dA[l] = -dt * (A0 * L::ad(Jm.col(l)));
      dJv[l] = Dv[l] * dt;
    }
  }
  const Mat Sq0 = Sq_zero ? Mat::Zero() : Mat(lin.Sq0);
  // eta (the root's pose): only Sq moves, with A and Jv those of the base point: T's column j is
  // [dSq_j A0, dt dSq_j Jv0, 0]
  if (Sq_zero) {
    for (int i = 0; i < N; ++i) nw.T[i].leftCols(N).setZero();
  } else {
    for (int j = 0; j < N; ++j) {
      const Mat Teta = dSq_eta[j] * A0, Tdv = dt * (dSq_eta[j] * Jv0);
      for (int i = 0; i < N; ++i) {
        Eigen::MatrixXd& T = nw.T[i];
        T.col(j).head(N) = Teta.row(i).transpose();
        T.col(j).segment(N, N) = Tdv.row(i).transpose();
        T.col(j).tail(N).setZero();
      }
    }
  }
  // dv: J = [Sq A, dt Sq Jv - d/dp[K(dt p)^T M p](v), R_y] with R_y fixed (the root's pose moves
  // the body rigidly: L.dRy all zero); the product rule on Sq A and Sq Jv
  Mat Hv[N], Hy[N];  // d/dv_l and d/dy_l of the velocity Jacobians d/dp[K(c p)^T M p]
  phi_hessian<N>(M, v0, dt, Dv, Hv);
  phi_hessian<N>(M, y0, -dt, Dy, Hy);
  for (int l = 0; l < N; ++l) {
    Mat Tdv = -Hv[l];
    Mat Teta;
    if (!Sq_zero) {
      Tdv.noalias() += dt * (dSq_dv[l] * Jv0);
      Tdv.noalias() += dt * (Sq0 * dJv[l]);
      Teta.noalias() = dSq_dv[l] * A0;
      Teta.noalias() += Sq0 * dA[l];
    }
    const int j = N + l;
    for (int i = 0; i < N; ++i) {
      Eigen::MatrixXd& T = nw.T[i];
      if (Sq_zero) T.col(j).head(N).setZero();
      else T.col(j).head(N) = Teta.row(i).transpose();
      T.col(j).segment(N, N) = Tdv.row(i).transpose();
      T.col(j).tail(N).setZero();  // R_y does not move along dv
    }
  }
  for (int l = 0; l < N; ++l) {
    const Mat& Ty = Hy[l];
    const int j = 2 * N + l;
    for (int i = 0; i < N; ++i) {
      Eigen::MatrixXd& T = nw.T[i];
      T.col(j).tail(N) = Ty.row(i).transpose();
      for (int a = 0; a < 2 * N; ++a) T(a, j) = T(j, a);
    }
  }
}

// D(q, e_l) = d(M(q) e_l)/dq from a dM/dq at q (mass_tensors; column-major (i, j, k), page
// k the nv x nv slice at k nv^2): D(q, e_l)(i, k) = dM(i, l)/dq_k, column l of every page.
void D_unit(const std::vector<double>& dMdq, int nv, int l, Eigen::MatrixXd& out) {
  out = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>(dMdq.data() + (size_t)l * nv, nv, nv,
                                                                  Eigen::OuterStride<>((Eigen::Index)nv * nv));
}

// H[c] = d/dx_c of d/dx [K(x)^T p] at fixed p on one SO(3) or SE(3) group's block (dKT's block
// there: its columns du_a = -K^T G_a(u), u = K^T p), exactly (implicit_second_derivative), from
// the block's K = Jr(x)^-1 and dJr's matrices D at x.
template <int N>
void kt_hessian(const typename FixedLie<N>::Vec& x, const typename FixedLie<N>::Vec& p,
                const typename FixedLie<N>::Mat& K, const typename FixedLie<N>::Mat D[N],
                typename FixedLie<N>::Mat H[N]) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  const typename L::Coef k = L::coefficients(x);
  const typename L::Vec u = K.transpose() * p;
  Mat Nu;
  L::djr_transpose_apply(x, u, Nu, k);
  const Mat du = -(K.transpose() * Nu);
  implicit_second_derivative<N>(x, k, K, D, u, du, 1.0, H);
}

// R_ww's columns along dv for the dofs of one SO(3) or SE(3) group g (at o = g.idx_v), after the
// base call: w holds its A0 = Ad_exp(-dt v), Jv0 = Jr(dt v), K0 = K(dt v), M0 = M(q), and nw its
// D(q, v) (Dbase), q+'s first-order model (lin) and dM/dq at q (dMq). Along dv_l, l = o + c, only
// g's blocks of A, Jv and K0 move:
//   dJv = dt dJr(omega0)/dx_c,  dK0 = -K0 dJv K0,
//   dA = -dt A0 ad(Jr(-omega0) e_c)  (exp(-omega0 - dt h e_c) = exp(-omega0) exp(-dt h Jr(-omega0) e_c)
//   to first order);
// q+ moves by xi = dt h Jv0 e_c (within g: so Sq and R_y by dt h sum_k Jv0(k, c) dSq[k], dRy[k]),
// D(q, v) by h D(q, e_l), and Kt = d/dx[K(x)^T M0 v] at x = omega0 by its x-derivative along
// dt e_c on g's block (kt_hessian) plus d/dx[K(x)^T M0 e_l] (linear in its vector). So
//   d_l R_eta = dSq A0 + Sq0 dA - dK0^T D0 - K0^T D(q, e_l),
//   d_l R_dv = dt (dSq Jv0 + Sq0 dJv) - dK0^T M0 - dt d_l Kt,  d_l R_y = dRy,
// where central differences of the whole Jacobian would take two residual_jacobian calls per
// direction (integrate and difference, every group's blocks, the linear model's nv-term sums).
template <int N>
void dv_columns_group(const VariationalModel& vm, VariationalNodeWork& nw, const JointGroup& g,
                      const Eigen::VectorXd& v) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const int nv = vm.model->nv, o = g.idx_v;
  const double dt = vm.dt;
  VariationalWork& w = nw.w;
  const QplusLinear& lin = nw.lin;
  const Vec x0 = dt * Vec(v.template segment<N>(o));
  const Mat A0 = w.A.block<N, N>(o, o), Jv0 = w.Jv.block<N, N>(o, o), K0 = w.K0.block<N, N>(o, o);
  Mat dJr[N];  // dJr at x0 on g's block, as kt0 formed them
  const Eigen::Matrix<double, 6, 6>* D0 = nw.kt0.djr(o);
  for (int c = 0; c < N; ++c) dJr[c] = D0[c].template topLeftCorner<N, N>();
  const Vec xm = -x0;
  const Mat Jm = L::jr(xm, L::coefficients(xm));  // Jr(-omega0)
  w.tmp.noalias() = w.M0 * v;
  const Vec p = w.tmp.template segment<N>(o);  // (M0 v) on g
  Mat Hk[N];
  kt_hessian<N>(x0, p, K0, dJr, Hk);
  for (int c = 0; c < N; ++c) {
    const int l = o + c, j = nv + l;
    bool sq_moves = false, ry_moves = false;
    nw.dSqj.setZero();
    nw.dRyj.setZero();
    for (int k = 0; k < N; ++k) {
      const double a = dt * Jv0(k, c);
      if (a == 0.0) continue;
      if (!lin.dSq_zero[o + k]) nw.dSqj += a * lin.dSq[o + k], sq_moves = true;
      if (!lin.dRy_zero[o + k]) nw.dRyj += a * lin.dRy[o + k], ry_moves = true;
    }
    const Mat dJv = dt * dJr[c];
    const Mat dK0 = -(K0 * dJv * K0);
    const Mat dA = -dt * (A0 * L::ad(Jm.col(c)));
    D_unit(nw.dMq, nv, l, nw.Dl);  // D(q, e_l)
    // eta rows
    block_transpose_times(vm.groups, w.K0, nw.Dl, w.P2);
    if (sq_moves) times_block(vm.groups, nw.dSqj, w.A, nw.X);
    else nw.X.setZero();
    nw.X -= w.P2;
    if (!lin.Sq_zero) nw.X.template middleCols<N>(o).noalias() += lin.Sq0.template middleCols<N>(o) * dA;
    nw.X.template middleRows<N>(o).noalias() -= dK0.transpose() * nw.Dbase.template middleRows<N>(o);
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).head(nv) = nw.X.row(i).transpose();
    // dv rows
    w.tmp = w.M0.col(l);
    nw.kt0.apply(w.tmp, w.S);
    w.S.block<N, N>(o, o) += Hk[c] * dt;
    if (sq_moves) {
      times_block(vm.groups, nw.dSqj, w.Jv, nw.X);
      nw.X *= dt;
    } else {
      nw.X.setZero();
    }
    if (!lin.Sq_zero) nw.X.template middleCols<N>(o).noalias() += dt * (lin.Sq0.template middleCols<N>(o) * dJv);
    nw.X.template middleRows<N>(o).noalias() -= dK0.transpose() * w.M0.template middleRows<N>(o);
    nw.X -= dt * w.S;
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).segment(nv, nv) = nw.X.row(i).transpose();
    // y rows: R_y moves only with q+
    for (int i = 0; i < nv; ++i) {
      if (ry_moves) nw.T[i].col(j).tail(nv) = nw.dRyj.row(i).transpose();
      else nw.T[i].col(j).tail(nv).setZero();
    }
  }
}

// R_ww's y-rows of the columns along y for the dofs of one SO(3) or SE(3) group g, with q+ and
// M1 = M(q+) the base call's (nw.M1b), x1full = -dt y, K1 = K(x1full) and dM/dq at q+ (w.dMdq).
// R_y = K1^T M1 - dt Kt1 - dt D(q+, y)^T with Kt1 = d/dx[K(x)^T M1 y] at x = -dt y; along y_l
// (l = o + c) x moves by -dt h e_c on g's block, so dJr1 = -dt dJr(x1)/dx_c, dK1 = -K1 dJr1 K1
// there, and
//   d_l R_y = dK1^T M1 - dt d_l Kt1 - dt D(q+, e_l)^T,
// d_l Kt1 the x-derivative on g's block (kt_hessian) plus d/dx[K(x)^T M1 e_l]: one dKT instead of
// two velocity_jacobian calls of central differences.
template <int N>
void y_columns_group(const VariationalModel& vm, VariationalNodeWork& nw, const JointGroup& g,
                     const Eigen::VectorXd& y, const Eigen::VectorXd& x1full, const Eigen::MatrixXd& K1,
                     Eigen::MatrixXd& R) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const int nv = vm.model->nv, o = g.idx_v;
  const double dt = vm.dt;
  VariationalWork& w = nw.w;
  const Vec x1 = x1full.template segment<N>(o);
  const Mat K1g = K1.block<N, N>(o, o);
  Mat dJr[N];  // dJr at x1 on g's block, as kt1 formed them
  const Eigen::Matrix<double, 6, 6>* D1 = nw.kt1.djr(o);
  for (int c = 0; c < N; ++c) dJr[c] = D1[c].template topLeftCorner<N, N>();
  w.tmp.noalias() = nw.M1b * y;
  const Vec p1 = w.tmp.template segment<N>(o);
  Mat Hk[N];
  kt_hessian<N>(x1, p1, K1g, dJr, Hk);
  for (int c = 0; c < N; ++c) {
    const int l = o + c, j = 2 * nv + l;
    D_unit(w.dMdq, nv, l, nw.Dl);  // D(q+, e_l)
    const Mat dK1 = dt * (K1g * dJr[c] * K1g);  // -K1 (-dt dJr) K1
    w.tmp = nw.M1b.col(l);
    nw.kt1.apply(w.tmp, w.S);
    w.S.block<N, N>(o, o) -= Hk[c] * dt;
    R = -dt * w.S;
    R.noalias() -= dt * nw.Dl.transpose();
    R.template middleRows<N>(o).noalias() += dK1.transpose() * nw.M1b.template middleRows<N>(o);
    for (int i = 0; i < nv; ++i)
      for (int a = 0; a < nv; ++a) nw.T[i](2 * nv + a, j) = R(i, a);
  }
}

}  // namespace

// (see variational_residual.hpp)
void residual_hessians(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y) {
  const Model& model = *vm.model;
  const int nv = model.nv;
  const double dt = vm.dt, h = VARIATIONAL_FD_STEP;
  VariationalWork& w = nw.w;
  // J depends on q+ = q exp(eta) exp(dt (v + dv)) only through Sq = dR/deta+ and R_y (M(q+), D(q+, y), the
  // kinetic-energy Hessian and the gravity terms). Those are taken once along q+'s own nv directions into the
  // first-order model QplusLinear, and each eta or dv column reads them by the chain rule at xi =
  // difference(q+, q+'), which halves the kinetic-energy Hessians (one per joint direction of q+ and sign,
  // instead of one per joint direction of eta and of dv and sign). A free-flyer or spherical root's pose
  // moves the mechanism rigidly (local frames, gravity-free model): along it M, D and the kinetic-energy
  // Hessian do not change, only the gravity terms (nothing at all without gravity: those dSq, dRy are exactly
  // zero, skipped). One body: every direction is the root's.
  const int root = vm.root_dirs;
  QplusLinear& L = nw.lin;
  L.qn = w.qn;  // the base call's q+, Sq, R_y and the terms they came from
  L.Sq0 = w.Sq;
  L.Ry0 = w.Ry;
  nw.M1b = w.M1;
  const Eigen::MatrixXd K1 = w.K1;  // K(-dt y): y is fixed throughout
  // Along the root's pose only the generalised gravity's derivative G(q+) moves (rigid: M, D and
  // the kinetic-energy Hessian do not), and Sq = ... + dt G. G depends on the root's attitude only
  // through the gravity seen from the root, g_r = W^T g (W the root's world rotation), linearly;
  // q+ exp(xi) turns g_r at the rate g_r x e_k along a rotation direction k, which is g's turn
  // g x (W e_k) at fixed W. So dSq[k] = dt G(q+) under the gravity g x (W e_k), exactly, from one
  // Pinocchio call (two for the central difference it replaces), and the root's translation
  // directions give exactly zero.
  const int rot0 = root == 6 ? 3 : 0;  // the root's rotation directions: rot0 .. root - 1
  if (root > 0 && !vm.gravity_free) {
    VariationalNodeWork::TurnedGravity& tg = *nw.turned;
    libpin::forwardKinematics(tg.model, tg.data, L.qn);
    const Eigen::Matrix3d W = tg.data.oMi[1].rotation();
    const Eigen::Vector3d g = vm.model->gravity.linear();
    for (int k = 0; k < root; ++k) {
      L.dRy_zero[k] = 1;
      L.dSq_zero[k] = k < rot0;
      if (k < rot0) continue;
      tg.model.gravity.linear() = g.cross(W.col(k - rot0));
      w.T.setZero();
      libpin::computeGeneralizedGravityDerivatives(tg.model, tg.data, L.qn, w.T);
      L.dSq[k] = dt * w.T;
    }
  }
  for (int k = 0; k < root; ++k) {  // without gravity the root's pose changes nothing
    if (!vm.gravity_free) break;
    L.dSq_zero[k] = L.dRy_zero[k] = 1;
  }
  // Along a joint direction k of q+, M(q+) and D(q+, y) move with the base call's own tensors
  // (dM/dq and dD/dq at (q+, y), mass_tensors, in the order of differentiating the trivialised D
  // along q+ exp(h e_k)). So
  //   dRy[k] = K1^T dM_k - dt d/dx[K(x)^T dM_k y]|_(x = -dt y) - dt dD_k^T   (exact: R_y is linear in
  //   M and D), and Sq = K1^T D - dt H gives dSq[k] = K1^T dD_k - dt dH_k,
  // where only H (the kinetic-energy Hessian less the gravity's derivative) is differenced: one
  // kinetic-energy Hessian (the recursion of rigid_body/kinetic_hessian.hpp) and one gravity derivative per
  // point instead of also M, D and R_y there.
  // (w.dMdq, w.d2q: the base call's, column-major (i, j, k); page k is the nv x nv slice at k nv^2)
  const size_t nn = (size_t)nv * nv;
  const Eigen::VectorXd x1 = -dt * y;
  if (!vm.configuration_free) {  // the base call's K(dt v) and K(-dt y)
    nw.kt0.set(vm.groups, w.omega, w.K0);
    nw.kt1.set(vm.groups, x1, K1);
  }
  for (int k = root; k < nv; ++k) {
    L.dSq_zero[k] = L.dRy_zero[k] = 0;
    const Eigen::Map<const Eigen::MatrixXd> dM(w.dMdq.data() + k * nn, nv, nv), dD(w.d2q.data() + k * nn, nv, nv);
    w.tmp.noalias() = dM * y;
    nw.kt1.apply(w.tmp, w.S);
    block_transpose_times(vm.groups, K1, dM, L.dRy[k]);
    L.dRy[k] -= dt * w.S;
    L.dRy[k].noalias() -= dt * dD.transpose();
    nw.e.setZero();
    nw.e[k] = h;
    libpin::integrate(model, L.qn, nw.e.head(nv), nw.qp);
    lagrangian_hessian(vm, w, nw.qp, y);
    nw.Hp = w.Hk;
    nw.e[k] = -h;
    libpin::integrate(model, L.qn, nw.e.head(nv), nw.qp);
    lagrangian_hessian(vm, w, nw.qp, y);
    block_transpose_times(vm.groups, K1, dD, L.dSq[k]);
    L.dSq[k] -= (dt / (2.0 * h)) * (nw.Hp - w.Hk);
  }
  L.fixed = true;
  for (int k = 0; k < nv; ++k) L.fixed = L.fixed && L.dSq_zero[k] && L.dRy_zero[k];
  L.Sq_zero = L.fixed && L.Sq0.isZero(0.0);
  // D(q, x) is linear in x: along dv (q the base's) it moves by h D(q, e_l) (dv_columns_group)
  if (!vm.configuration_free) nw.Dbase = w.D0;  // the base call's D(q, v)
  // central differences of the whole Jacobian along eta_j (the root's pose under gravity)
  auto difference_along = [&](int j, Keep keep) {
    nw.e.setZero();
    nw.e[j] = h;
    libpin::integrate(model, q, nw.e.head(nv), nw.qp);
    nw.vp = v + nw.e.tail(nv);
    residual_jacobian(vm, w, nw.qp, nw.vp, y, w.Jp, keep);
    nw.e = -nw.e;
    libpin::integrate(model, q, nw.e.head(nv), nw.qp);
    nw.vp = v + nw.e.tail(nv);
    residual_jacobian(vm, w, nw.qp, nw.vp, y, nw.Jm, keep);
    nw.Tj = (w.Jp - nw.Jm) / (2.0 * h);
    for (int i = 0; i < nv; ++i) nw.T[i].col(j) = nw.Tj.row(i).transpose();
  };
  Keep keep;
  keep.lin = &L;
  if (vm.configuration_free) {  // one body: every column on fixed-size matrices
    if (nv == 6) one_body_columns<6>(vm, nw, v, y);
    else one_body_columns<3>(vm, nw, v, y);
    return;
  }
  // Along eta's joint directions, exactly, from the base call's terms (w: A = Ad_exp(-dt v),
  // Jv = Jr(dt v), K0 = K(dt v), none of which moves with eta) and the tensors at (q, v)
  // (mass_tensors): q exp(h e_j) moves M(q) by h dM_j and D(q, v) by h dD_j (pages j of dM/dq and
  // dD/dq, as at q+ above), and q+ = q exp(eta) exp(dt v) by xi = h Ad_exp(-dt v) e_j, so Sq
  // and R_y by h sum_k A(k, j) dSq[k], dRy[k] (QplusLinear). Then with dSq_j, dRy_j those sums,
  //   d_j R_eta = dSq_j A - K0^T dD_j,  d_j R_dv = dt dSq_j Jv - K0^T dM_j - dt d/dx[K(x)^T dM_j v],
  //   d_j R_y = dRy_j,
  // where central differences would take two residual_jacobian calls (two mass matrices, two RNEA
  // derivatives) per direction. The same tensors give D(q, e_l) along dv below.
  mass_tensors(vm.free_model, w.fdata, w.kh, q, v, nw.dMq.data(), nw.d2qq.data());
  for (int j = root; j < nv; ++j) {
    nw.dSqj.setZero();
    nw.dRyj.setZero();
    for (int k = 0; k < nv; ++k) {
      const double a = w.A(k, j);
      if (a == 0.0) continue;
      if (!L.dSq_zero[k]) nw.dSqj += a * L.dSq[k];
      if (!L.dRy_zero[k]) nw.dRyj += a * L.dRy[k];
    }
    const Eigen::Map<const Eigen::MatrixXd> dM(nw.dMq.data() + j * nn, nv, nv), dD(nw.d2qq.data() + j * nn, nv, nv);
    times_block(vm.groups, nw.dSqj, w.A, nw.X);
    block_transpose_times(vm.groups, w.K0, dD, w.P2);
    nw.X -= w.P2;
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).head(nv) = nw.X.row(i).transpose();
    w.tmp.noalias() = dM * v;
    nw.kt0.apply(w.tmp, w.S);
    times_block(vm.groups, nw.dSqj, w.Jv, nw.X);
    nw.X *= dt;
    block_transpose_times(vm.groups, w.K0, dM, w.P2);
    nw.X -= w.P2;
    nw.X -= dt * w.S;
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).segment(nv, nv) = nw.X.row(i).transpose();
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).tail(nv) = nw.dRyj.row(i).transpose();
  }
  for (int j = 0; j < root; ++j) {  // eta along the root's pose: M(q), D(q, v) do not change
    if (vm.gravity_free) {  // nor does anything else: exactly zero
      for (int i = 0; i < nv; ++i) nw.T[i].col(j).setZero();
      continue;
    }
    keep.v_terms = keep.M0 = keep.D0 = true;
    difference_along(j, keep);
  }
  // dv along a dof of a commutative group (vector, SO(2): Ad = Jr = I there), exactly. Only linear
  // terms move: A, Jr(dt v), K(dt v) do not (their blocks belong to the other groups), q+ moves by
  // xi = dt h e_l (so Sq and R_y by dt h dSq[l], dRy[l] in QplusLinear), D(q, v) by h D(q, e_l),
  // and d/dx[K(x)^T M0 v] by h d/dx[K(x)^T M0 e_l] (linear in its vector). So
  //   d_l R_eta = dt dSq[l] A - K0^T D(q, e_l),  d_l R_dv = dt^2 dSq[l] Jv - dt d/dx[K(x)^T M0 e_l],
  //   d_l R_y = dt dRy[l],
  // exactly, where central differences would take two residual_jacobian calls each (and agree
  // to their round-off, ~1e-11). Taken first, while w holds the base call's blocks (the
  // differences below move them).
  for (int l = 0; l < nv; ++l) {
    if (!vm.flat_dof[l]) continue;
    const int j = nv + l;
    D_unit(nw.dMq, nv, l, nw.Dl);  // D(q, e_l)
    block_transpose_times(vm.groups, w.K0, nw.Dl, w.P2);
    if (L.dSq_zero[l]) {
      nw.X = -w.P2;
    } else {
      times_block(vm.groups, L.dSq[l], w.A, nw.X);
      nw.X *= dt;
      nw.X -= w.P2;
    }
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).head(nv) = nw.X.row(i).transpose();
    w.tmp = w.M0.col(l);
    nw.kt0.apply(w.tmp, w.S);
    if (L.dSq_zero[l]) {
      nw.X = -dt * w.S;
    } else {
      times_block(vm.groups, L.dSq[l], w.Jv, nw.X);
      nw.X *= dt * dt;
      nw.X -= dt * w.S;
    }
    for (int i = 0; i < nv; ++i) nw.T[i].col(j).segment(nv, nv) = nw.X.row(i).transpose();
    for (int i = 0; i < nv; ++i) {
      if (L.dRy_zero[l]) nw.T[i].col(j).tail(nv).setZero();
      else nw.T[i].col(j).tail(nv) = dt * L.dRy[l].row(i).transpose();
    }
  }
  for (const JointGroup& g : vm.groups) {  // dv along an SO(3) or SE(3) group's dofs
    if (g.kind == SE3) dv_columns_group<6>(vm, nw, g, v);
    else if (g.kind == SO3) dv_columns_group<3>(vm, nw, g, v);
  }
  // Along y, q and v (so q+ = q exp(dt v) and M(q+)) stay fixed and only R_y = K1^T M1 - dt Kt1 -
  // dt D(q+, y)^T moves: exactly along a commutative group's dof (below) and along an SO(3) or
  // SE(3) group's (y_columns_group, with Kt1's own x-derivative on the group's block from
  // kt_hessian). The (eta, dv) rows of a y-direction are the mixed partials d_y d_eta R, d_y
  // d_dv R, already taken along eta and dv: y is a flat coordinate of R, so they commute with it
  // (only eta-eta does not: the right-trivialised base point moves), T[i](a, y) = T[i](y, a).
  Eigen::MatrixXd& R = w.Kx;  // the step's scratch, free here
  for (int l = 0; l < nv; ++l) {
    if (!vm.flat_dof[l]) continue;
    // a dof of a commutative group: K(-dt y) does not move along it and R_y is linear in y there,
    // d_l R_y = -dt d/dx[K(x)^T M1 e_l]|_(x = -dt y) - dt D(q+, e_l)^T
    D_unit(w.dMdq, nv, l, nw.Dl);  // D(q+, e_l), from the base call's dM/dq at q+
    w.tmp = nw.M1b.col(l);
    nw.kt1.apply(w.tmp, w.S);
    R = -dt * w.S;
    R.noalias() -= dt * nw.Dl.transpose();
    for (int i = 0; i < nv; ++i)
      for (int a = 0; a < nv; ++a) nw.T[i](2 * nv + a, 2 * nv + l) = R(i, a);
  }
  for (const JointGroup& g : vm.groups) {
    if (g.kind == SE3) y_columns_group<6>(vm, nw, g, y, x1, K1, R);
    else if (g.kind == SO3) y_columns_group<3>(vm, nw, g, y, x1, K1, R);
  }
  for (int l = 0; l < nv; ++l) {
    const int j = 2 * nv + l;
    for (int i = 0; i < nv; ++i)
      for (int a = 0; a < 2 * nv; ++a) nw.T[i](a, j) = nw.T[i](j, a);
  }
}

}  // namespace var
}  // namespace dyn
}  // namespace geoddp
