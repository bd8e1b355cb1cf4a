// Forward variational Euler step and derivatives (see variational.hpp; twin of the tests' oracle
// tests/oracle_variational.py, whose names and order of operations this follows).
#include "variational.hpp"
#include "aba_compiled.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "joint_blocks.hpp"
#include "one_body.hpp"

namespace geoddp {
namespace dyn {

namespace {


// Newton converges quadratically: once a correction is below 1e-9 relative, the velocity is exact
// to round-off (variational.py's NEWTON_TOL, NEWTON_MAX_ITER).
const double NEWTON_TOL = 1e-9;
const int NEWTON_MAX_ITER = 30;

// The stop: a full step of at most NEWTON_TOL relative to the velocity.
bool newton_converged(double alpha, double step, double y_norm) {
  return alpha == 1.0 && step <= NEWTON_TOL * (1.0 + y_norm);
}

// No convergence in NEWTON_MAX_ITER steps: StepNotConverged with |v| (the Python side names dt).
[[noreturn]] void step_not_converged(const Eigen::VectorXd& v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g", v.norm());
  throw StepNotConverged(buf);
}

void mass(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q, Eigen::MatrixXd& M) {
  pinocchio::crba(*vm.model, w.data, q);
  M = w.data.M;
  M.triangularView<Eigen::StrictlyLower>() = M.transpose();
}

// D(q, x) = d(M(q) x)/dq, right-trivialised as RNEA's dtau/dq at (q, 0, x) without gravity (zero
// for one body, whose M is constant in its own frame), from the kinetic-energy recursion
// (kinetic_hessian.hpp's mass_velocity_derivative: O(nv depth) dot products where Pinocchio's RNEA
// derivatives also formed dtau/dv and M).
void Dmat(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q, const Eigen::VectorXd& x,
          Eigen::MatrixXd& D) {
  if (vm.configuration_free) {
    D.setZero(vm.model->nv, vm.model->nv);
    return;
  }
  mass_velocity_derivative(vm.free_model, w.fdata, w.kh, q, x, D);
}

// Jr(x)^-1 into K (block-diagonal).
void Kmat(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, Eigen::MatrixXd& K) {
  blocks(vm.groups, x, nullptr, w.Jr, K);
}

// out = d/dx [K(x)^T p] for fixed p = -K^T dJr[.]^T (K^T p).
void dKT(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, const Eigen::MatrixXd& K,
         const Eigen::VectorXd& p, Eigen::MatrixXd& out) {
  w.s.noalias() = K.transpose() * p;
  djr_transpose_apply(vm.groups, x, w.s, w.N);
  block_transpose_times(vm.groups, K, w.N, out);
  out = -out;
}

}  // namespace

void KtMap::set(const std::vector<JointGroup>& groups, const Eigen::VectorXd& x, const Eigen::MatrixXd& K) {
  blocks.clear();
  for (const JointGroup& g : groups) {
    if (g.kind != SO3 && g.kind != SE3) continue;
    Block b;
    b.o = g.idx_v;
    b.n = g.kind == SE3 ? 6 : 3;
    if (b.n == 6) {
      lie::se3_djr(x.segment<6>(b.o), b.D);
      const lie::Mat6 Kt = K.block<6, 6>(b.o, b.o).transpose();
      for (int c = 0; c < 6; ++c) b.C[c] = -(Kt * b.D[c].transpose()) * Kt;
    } else {
      lie::Mat3 D[3];
      lie::so3_djr(x.segment<3>(b.o), D);
      const lie::Mat3 Kt = K.block<3, 3>(b.o, b.o).transpose();
      for (int c = 0; c < 3; ++c) {
        b.D[c].topLeftCorner<3, 3>() = D[c];
        b.C[c].topLeftCorner<3, 3>() = -(Kt * D[c].transpose()) * Kt;
      }
    }
    blocks.push_back(b);
  }
}

void KtMap::apply(const Eigen::VectorXd& p, Eigen::MatrixXd& out) const {
  out.setZero();
  for (const Block& b : blocks) {
    if (b.n == 6) {
      const Eigen::Matrix<double, 6, 1> pg = p.segment<6>(b.o);
      for (int c = 0; c < 6; ++c) out.block<6, 1>(b.o, b.o + c).noalias() = b.C[c] * pg;
    } else {
      const lie::Vec3 pg = p.segment<3>(b.o);
      for (int c = 0; c < 3; ++c) out.block<3, 1>(b.o, b.o + c).noalias() = b.C[c].topLeftCorner<3, 3>() * pg;
    }
  }
}

namespace {

// d/deta [dL/dq(q exp(eta), v)] at eta = 0 into w.Hk: the kinetic part exact, 1/2 d/dq_j of
// D(q, v)^T v = 1/2 sum_p v_p d2tau_p/dq_i dq_j (the (i, j) order is that of differentiating the
// trivialised D along q exp(h e_j), as the Python oracle's differences do), minus the generalised
// gravity's derivative. The kinetic part comes from the spatial-vector recursion of
// kinetic_hessian.hpp (O(nv depth) dot products; Pinocchio's second-order RNEA at (q, 0, v), whose
// nv^3 entries this had contracted with v, costs 15x more at nv 9, benchmarks/pinocchio_calls.py).
// save_tensors (the second order's base point): the same recursion's tensors dM/dq and
// d/dq D(q, v) (mass_tensors: what Pinocchio's second-order RNEA at (q, 0, v) gave as d2tau_dadq
// and d2tau_dqdq, at about a ninth of its cost at nv 9) go to w.dMdq, w.d2q, which
// residual_hessians reads (VariationalWork); the first order (F1, Phi, B) does not read them.
void lagrangian_hessian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                        const Eigen::VectorXd& v, bool save_tensors = false) {
  const int nv = vm.model->nv;
  if (vm.configuration_free) {
    w.Hkin.setZero();
  } else {
    kinetic_hessian(vm.free_model, w.fdata, w.kh, q, v, w.Hkin);
    if (save_tensors) {
      mass_tensors(vm.free_model, w.fdata, w.kh, q, v, w.dMdq.data(), w.d2q.data());
    }
  }
  if (vm.gravity_free) {  // no gravity: its derivative is zero (no Pinocchio call)
    w.Hk = w.Hkin;
    return;
  }
  w.T.resize(nv, nv);  // reuse as the gravity derivative's buffer
  w.T.setZero();
  pinocchio::computeGeneralizedGravityDerivatives(*vm.model, w.data, q, w.T);
  w.Hk = w.Hkin - w.T;
}

// R at y (into r) with K1 = K(-dt y); M1 = M(q+), g1 = g(q+), b fixed. R needs no D(q+, y), only
// 1/2 D(q+, y)^T y, the kinetic energy's gradient (kinetic_hessian.hpp: O(nv), where Pinocchio's
// RNEA derivatives had formed all of D at every trial point of the step's line search).
void residual_at(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& qn, const Eigen::VectorXd& y,
                 Eigen::VectorXd& r, Eigen::MatrixXd& K1) {
  const double dt = vm.dt;
  w.x = -dt * y;
  Kmat(vm, w, w.x, K1);
  kinetic_gradient(vm.free_model, w.fdata, w.kh, qn, y, w.grad);
  w.tmp.noalias() = w.M1 * y;
  r.noalias() = K1.transpose() * w.tmp;
  r -= dt * w.grad;
  r += dt * w.g1 - w.b;
}

// R_y = K1^T M1 - dt d/dx[K(x)^T M1 y]|_(x = -dt y) - dt D1^T, into out.
void velocity_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::MatrixXd& K1,
                       const Eigen::MatrixXd& D1, const Eigen::VectorXd& y, Eigen::MatrixXd& out) {
  const double dt = vm.dt;
  w.tmp.noalias() = w.M1 * y;
  w.x = -dt * y;
  dKT(vm, w, w.x, K1, w.tmp, w.S);
  block_transpose_times(vm.groups, K1, w.M1, out);
  out -= dt * w.S;
  out.noalias() -= dt * D1.transpose();
}

// What a residual_jacobian call may keep from the previous call on the same work (residual_hessians
// orders its calls so that these hold). Each kept value is the one the call would compute, up to
// round-off where it rests on the root's invariance (VariationalModel::root_dirs).
//   v_terms: v is the previous call's: Ad_exp(-dt v), Jr(dt v), K(dt v) and d/dx[K^T M0 v] (its
//      dual-number dJr), when M0 is kept as well;
//   M0: q differs at most along the root's pose: M0 = M(q);
//   D0: and v is the previous call's: D0 = D(q, v);
//   lin: y is the base call's, and Sq and R_y come from q+'s first-order model (QplusLinear,
//      variational.hpp) instead of M(q+), D(q+, y), the kinetic-energy Hessian and the gravity
//      terms at q+.
struct Keep {
  bool v_terms = false, M0 = false, D0 = false;
  bool tensors = true;  // the base call: keep dM/dq and d/dq D at q+ (lagrangian_hessian)
  const QplusLinear* lin = nullptr;
};

// [R_eta, R_dv, R_y] at any (q, v, y), into J (nv, 3 nv), keeping what `keep` allows.
void residual_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y, Eigen::MatrixXd& J,
                       const Keep& keep = Keep()) {
  const Model& model = *vm.model;
  const int nv = model.nv;
  const double dt = vm.dt;
  const bool keep_v = keep.v_terms && keep.M0;
  // one body without gravity: Sq = 0 and R_y fixed, so q+ and Ad_exp(-dt v) are not needed
  const bool fixed = keep.lin && keep.lin->fixed, Sq_zero = fixed && keep.lin->Sq_zero;
  w.omega = dt * v;
  if (!fixed) pinocchio::integrate(model, q, w.omega, w.qn);
  if (!keep_v) blocks(vm.groups, w.omega, Sq_zero ? nullptr : &w.A, w.Jv, w.K0);  // Ad_exp(-dt v), Jr(dt v), K(dt v)
  if (keep.lin) {
    const QplusLinear& L = *keep.lin;
    w.Sq = L.Sq0;
    w.Ry = L.Ry0;
    if (!fixed) {
      pinocchio::difference(model, L.qn, w.qn, w.xi);
      for (int k = 0; k < nv; ++k) {
        if (!L.dSq_zero[k]) w.Sq += w.xi[k] * L.dSq[k];
        if (!L.dRy_zero[k]) w.Ry += w.xi[k] * L.dRy[k];
      }
    }
  } else {
    w.x = -dt * y;
    Kmat(vm, w, w.x, w.K1);
    mass(vm, w, w.qn, w.M1);
    Dmat(vm, w, w.qn, y, w.D1);
    lagrangian_hessian(vm, w, w.qn, y, keep.tensors);  // the tensors residual_hessians reads
    block_transpose_times(vm.groups, w.K1, w.D1, w.Sq);  // dR/deta+
    w.Sq -= dt * w.Hk;
  }
  if (!keep.M0) mass(vm, w, q, w.M0);
  if (!keep.D0) Dmat(vm, w, q, v, w.D0);
  block_transpose_times(vm.groups, w.K0, w.D0, w.P2);
  if (Sq_zero) {
    J.leftCols(nv) = -w.P2;
  } else {
    times_block(vm.groups, w.Sq, w.A, w.P1);
    J.leftCols(nv) = w.P1 - w.P2;
  }
  if (!keep_v) {
    w.tmp.noalias() = w.M0 * v;
    dKT(vm, w, w.omega, w.K0, w.tmp, w.Kt);
  }
  block_transpose_times(vm.groups, w.K0, w.M0, w.P2);
  if (Sq_zero) {
    J.middleCols(nv, nv) = -w.P2;
  } else {
    times_block(vm.groups, w.Sq, w.Jv, w.P1);
    J.middleCols(nv, nv) = dt * w.P1 - w.P2;
  }
  J.middleCols(nv, nv) -= dt * w.Kt;
  if (!keep.lin) velocity_jacobian(vm, w, w.K1, w.D1, y, w.Ry);
  J.rightCols(nv) = w.Ry;
}

// ---------------------------------------------------------------- one body, fixed size
// A model of one body on a free-flyer (N = 6) or spherical (N = 3) root without configuration
// dependence (VariationalModel::configuration_free: M constant, D = 0): the residual's velocity
// Jacobians are d/dp [K(c p)^T M p] (c = dt for R_dv's, c = -dt for R_y), residual_hessians takes
// their p-derivatives (phi_hessian), and each step's Newton iteration solves with them. Here
// they run on fixed-size matrices, where the general path's dynamic ones spent as long in Eigen's
// GEMM kernels, zero D products and block copies as in the closed forms they wrap (with the SE(3)
// inverse and dJr^T s in closed form, lie::se3_jr_inverse and lie::se3_djr_transpose_apply, the
// docking and quadrotor scenes' contracted expansions take 0.47x the time they took on the dynamic
// path, their rollouts 0.45-0.47x; the same results to round-off).
template <int N>
struct FixedLie;
// Each keeps the scalar coefficients of Jr at a point (Coef) so that Jr(x) and dJr(x)^T s at one x
// share their transcendental functions and Taylor series (lie::se3_jr_coefficients).
template <>
struct FixedLie<6> {
  typedef lie::Mat6 Mat;
  typedef Eigen::Matrix<double, 6, 1> Vec;
  typedef lie::Se3JrCoefficients Coef;
  static Coef coefficients(const Vec& x) { return lie::se3_jr_coefficients(x); }
  static Mat jr(const Vec& x, const Coef& k) { return lie::se3_jr(x, k); }
  static Mat inverse(const Mat& J) { return lie::se3_jr_inverse(J); }
  static void djr_transpose_apply(const Vec& x, const Vec& s, Mat& N, const Coef& k) {
    lie::se3_djr_transpose_apply(x, s, N, k);
  }
  static void jr_transpose_hessian(const Vec& x, const Vec& u, const Coef& k, Mat E[6]) {
    lie::se3_jr_transpose_hessian(x, u, k, E);
  }
  static Mat ad_exp_minus(const Vec& x) { return pinocchio::exp6(pinocchio::Motion(-x)).toActionMatrix(); }
  static void djr(const Vec& x, Mat D[6]) { lie::se3_djr(x, D); }
  // ad(xi) of se(3), xi = [v; w]: [[hat(w), hat(v)], [0, hat(w)]], Pinocchio's motion action matrix
  static Mat ad(const Vec& xi) { return pinocchio::Motion(xi).toActionMatrix(); }
};
template <>
struct FixedLie<3> {
  typedef lie::Mat3 Mat;
  typedef lie::Vec3 Vec;
  struct Coef {
    double a, b, al, be;
  };
  static Coef coefficients(const Vec& x) {
    Coef k;
    lie::so3_coefficients(x.norm(), k.a, k.b, k.al, k.be);
    return k;
  }
  static Mat jr(const Vec& x, const Coef& k) { return lie::so3_jr(x, k.a, k.b); }
  static Mat inverse(const Mat& J) { return J.inverse(); }
  static void djr_transpose_apply(const Vec& x, const Vec& s, Mat& N, const Coef& k) {
    lie::so3_djr_transpose_apply(x, s, k.a, k.b, k.al, k.be, N);
  }
  static void jr_transpose_hessian(const Vec& x, const Vec& u, const Coef& k, Mat E[3]) {
    lie::so3_jr_transpose_hessian(x, u, k.b, k.al, k.be, E);
  }
  static Mat ad_exp_minus(const Vec& x) { return pinocchio::exp3(x).transpose(); }
  static void djr(const Vec& x, Mat D[3]) { lie::so3_djr(x, D); }
  static Mat ad(const Vec& xi) { return lie::hat(xi); }
};

// d/dp [K(c p)^T M p] = K^T M + c d/dx[K(x)^T (M p)] = K^T (M - c N), K = Jr(c p)^-1 given with
// Jr's coefficients k at c p, and N(:, l) = dJr/dx_l^T K^T M p (the general path's dKT and
// velocity_jacobian).
template <int N>
typename FixedLie<N>::Mat phi_jacobian_K(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p,
                                         double c, const typename FixedLie<N>::Mat& K,
                                         const typename FixedLie<N>::Coef& k) {
  typedef FixedLie<N> L;
  const typename L::Vec s = K.transpose() * (M * p);
  typename L::Mat Nm;
  L::djr_transpose_apply(c * p, s, Nm, k);
  return K.transpose() * (M - c * Nm);
}

// The same with Jr and K computed; Jr(c p) into *jr.
template <int N>
typename FixedLie<N>::Mat phi_jacobian(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p,
                                       double c, typename FixedLie<N>::Mat* jr = nullptr) {
  typedef FixedLie<N> L;
  const typename L::Vec x = c * p;
  const typename L::Coef k = L::coefficients(x);
  const typename L::Mat J = L::jr(x, k);
  if (jr) *jr = J;
  return phi_jacobian_K<N>(M, p, c, L::inverse(J), k);
}

// The second derivatives of u(z) solving Jr(c z)^T u = b(z), b affine in z, from u, its first
// derivatives du (column a: du/dz_a) and Jr's coefficients k and inverse K at x = c z. Once more
// differentiating Jr^T du_a = db/dz_a - c G_a(u), G_a(w) = (dJr/dx_a)^T w (djr_transpose_apply's
// column a), gives
//   Jr^T d2u_al = -c (c E_al(u) + G_a(du_l) + G_l(du_a)),
// E_al(u) = dG_a(u)/dx_l (lie's jr_transpose_hessian): H[l](:, a) = d2u/dz_a dz_l, exact, where
// central differences of du had taken 2 N closed-form evaluations. Two uses: u = K(c p)^T M p
// (phi_hessian: z = p) and u = K(x)^T p at fixed p (kt_hessian: z = x, c = 1).
template <int N>
void implicit_second_derivative(const typename FixedLie<N>::Vec& x, const typename FixedLie<N>::Coef& k,
                                const typename FixedLie<N>::Mat& K, const typename FixedLie<N>::Mat D[N],
                                const typename FixedLie<N>::Vec& u, const typename FixedLie<N>::Mat& du, double c,
                                typename FixedLie<N>::Mat H[N]) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  Mat G[N], E[N];  // G[l](:, a) = G_l(du_a) = dJr_l^T du_a, from dJr's matrices D at x
  for (int l = 0; l < N; ++l) G[l].noalias() = D[l].transpose() * du;
  L::jr_transpose_hessian(x, u, k, E);
  const Mat cKt = -c * K.transpose();
  for (int l = 0; l < N; ++l) {
    Mat S;
    for (int a = 0; a < N; ++a) S.col(a) = c * E[l].col(a) + G[a].col(l) + G[l].col(a);
    H[l].noalias() = cKt * S;
  }
}

// H[l] = d/dp_l of phi_jacobian(M, p, c) = d/dp [K(c p)^T M p], exactly (implicit_second_derivative),
// from dJr's matrices D at c p.
template <int N>
void phi_hessian(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p, double c,
                 const typename FixedLie<N>::Mat D[N], typename FixedLie<N>::Mat H[N]) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const Vec x = c * p;
  const typename L::Coef k = L::coefficients(x);
  const Mat K = L::inverse(L::jr(x, k));
  const Vec u = K.transpose() * (M * p);
  implicit_second_derivative<N>(x, k, K, D, u, phi_jacobian_K<N>(M, p, c, K, k), c, H);
}

// variational_step for such a body on fixed-size matrices: the same start and damped Newton
// iteration on R(y) = K(-dt y)^T M y + dt g(q+) - b (D = 0), b = K(dt v)^T M v + dt tau.
template <int N>
void one_body_step(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                   const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const Model& model = *vm.model;
  const double dt = vm.dt;
  w.omega = dt * v;
  pinocchio::integrate(model, q, w.omega, w.qn);
  const Mat M = vm.M_body;  // = M(q) = M(q+)
  const Vec v0 = v;
  const Vec x0 = dt * v0;
  Vec c0 = -(L::inverse(L::jr(x0, L::coefficients(x0))).transpose() * (M * v0)) - dt * Vec(tau);
  if (!vm.gravity_free) c0 += dt * Vec(pinocchio::computeGeneralizedGravity(model, w.data, w.qn));
  // R(y) with K = Jr(-dt y)^-1 and Jr's coefficients at -dt y, which the Newton Jacobian reuses
  typedef typename L::Coef Coef;
  auto residual = [&](const Vec& y, Mat& K, Coef& k) -> Vec {
    const Vec x = -dt * y;
    k = L::coefficients(x);
    K = L::inverse(L::jr(x, k));
    return K.transpose() * (M * y) + c0;
  };
  Mat K, Kt, Kv;
  Coef k, kt, kv;
  Vec y = v0 + dt * Vec(geoddp::aba(model, w.data, w.qn, v, tau));
  Vec r = residual(y, K, k);
  const Vec r0 = residual(v0, Kv, kv);
  if (!r.allFinite() || r0.norm() < r.norm()) {
    y = v0;
    r = r0;
    K = Kv;
    k = kv;
  }
  for (int it = 0; it < NEWTON_MAX_ITER; ++it) {
    const Eigen::PartialPivLU<Mat> lu(phi_jacobian_K<N>(M, y, -dt, K, k));
    const Vec dy = lu.solve(r);
    const double norm_r = r.norm(), tol = NEWTON_TOL * (1.0 + y.norm());
    double alpha = 1.0;
    Vec yt, rt;
    while (true) {
      yt = y - alpha * dy;
      rt = residual(yt, Kt, kt);
      if (rt.norm() < norm_r || alpha < 1e-6 || alpha * dy.norm() <= tol) break;
      alpha *= 0.5;
    }
    y = yt;
    r = rt;
    K = Kt;
    k = kt;
    if (!y.allFinite()) break;
    if (newton_converged(alpha, dy.norm(), y.norm())) {
      q1 = w.qn;
      v1 = y;
      return;
    }
  }
  step_not_converged(v);
}

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
  pinocchio::integrate(*vm.model, q, w.omega, w.qn);
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
    pinocchio::computeGeneralizedGravityDerivatives(*vm.model, w.data, w.qn, w.T);
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

}  // namespace

VariationalModel::VariationalModel(const Model& model_, const double* H_, int m_, double dt_)
    : model(&model_), free_model(model_), groups(joint_groups(model_)), H(H_), m(m_), dt(dt_) {
  free_model.gravity.setZero();
  configuration_free = OneBodySecondOrder::free_of_configuration(free_model);
  gravity_free = model_.gravity.toVector().isZero(0.0);
  const int root_kind = model_.njoints > 1 ? boost::apply_visitor(GroupKindOf(), model_.joints[1].toVariant()) : -1;
  root_dirs = root_kind == SE3 ? 6 : root_kind == SO3 ? 3 : 0;
  flat_dof.assign(model_.nv, 0);
  for (const JointGroup& g : groups)
    if (g.kind == VECTOR || g.kind == SO2)
      for (int d = 0; d < g.nv; ++d) flat_dof[g.idx_v + d] = 1;
  if (configuration_free) {  // M does not depend on q: computed once here, not once per step
    pinocchio::Data data(model_);
    pinocchio::crba(model_, data, pinocchio::neutral(model_));
    M_body = data.M;
    M_body.triangularView<Eigen::StrictlyLower>() = M_body.transpose();
  }
}

VariationalWork::VariationalWork(const VariationalModel& vm) : data(*vm.model), fdata(vm.free_model), kh(vm.free_model) {
  const int nv = vm.model->nv, nq = vm.model->nq;
  for (Eigen::MatrixXd* M : {&M0, &M1, &K0, &K1, &D0, &D1, &A, &Jv, &Jr, &Kt, &S, &N, &Hk, &Hkin, &T, &Sq, &Ry, &Kx, &P1, &P2})
    M->resize(nv, nv);
  J.resize(nv, 3 * nv);
  Jp.resize(nv, 3 * nv);
  for (Eigen::VectorXd* v : {&y, &r, &g1, &b, &tmp, &s, &x, &omega, &r0, &rt, &yt, &dy, &xi, &grad}) v->resize(nv);
  dMdq.assign((size_t)nv * nv * nv, 0.0);
  d2q.assign((size_t)nv * nv * nv, 0.0);
  qn.resize(nq);
  lu = Eigen::PartialPivLU<Eigen::MatrixXd>(nv);
}

void variational_step(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1) {
  if (vm.configuration_free) {  // one body: fixed-size matrices
    if (vm.model->nv == 6) one_body_step<6>(vm, w, q, v, tau, q1, v1);
    else one_body_step<3>(vm, w, q, v, tau, q1, v1);
    return;
  }
  const Model& model = *vm.model;
  const double dt = vm.dt;
  w.omega = dt * v;
  pinocchio::integrate(model, q, w.omega, w.qn);
  // b = K(dt v)^T M(q) v + dt tau: the y-independent part of R
  Kmat(vm, w, w.omega, w.K0);
  mass(vm, w, q, w.M0);
  w.tmp.noalias() = w.M0 * v;
  w.b.noalias() = w.K0.transpose() * w.tmp;
  w.b += dt * tau;
  mass(vm, w, w.qn, w.M1);
  if (vm.gravity_free) w.g1.setZero();  // no gravity: no Pinocchio call
  else w.g1 = pinocchio::computeGeneralizedGravity(model, w.data, w.qn);
  // Start from the better of v and the explicit (symplectic) Euler velocity; damped Newton
  // (backtracking on |R|) keeps stiff light links from throwing the iteration off.
  Eigen::VectorXd& y = w.y;
  y = v + dt * geoddp::aba(model, w.data, w.qn, v, tau);
  residual_at(vm, w, w.qn, y, w.r, w.K1);
  residual_at(vm, w, w.qn, v, w.r0, w.Kx);
  if (!w.r.allFinite() || w.r0.norm() < w.r.norm()) {
    y = v;
    w.r = w.r0;
    w.K1 = w.Kx;
  }
  // D(q+, y) only where a Jacobian is formed: once per Newton iteration, none per trial point
  for (int it = 0; it < NEWTON_MAX_ITER; ++it) {
    Dmat(vm, w, w.qn, y, w.D1);
    velocity_jacobian(vm, w, w.K1, w.D1, y, w.Ry);
    w.lu.compute(w.Ry);
    w.dy = w.lu.solve(w.r);
    const double norm_r = w.r.norm(), tol = NEWTON_TOL * (1.0 + y.norm());
    double alpha = 1.0;
    while (true) {
      w.yt = y - alpha * w.dy;
      residual_at(vm, w, w.qn, w.yt, w.rt, w.Kx);
      if (w.rt.norm() < norm_r || alpha < 1e-6 || alpha * w.dy.norm() <= tol) break;
      alpha *= 0.5;
    }
    y = w.yt;
    w.r = w.rt;
    w.K1 = w.Kx;
    if (!y.allFinite()) break;
    if (newton_converged(alpha, w.dy.norm(), y.norm())) {
      q1 = w.qn;
      v1 = y;
      return;
    }
  }
  step_not_converged(v);
}

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

namespace {

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
// where central differences of the whole Jacobian had taken two residual_jacobian calls per
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

// R_ww after node_first_order (same q, v, y, the same work): nw.T[i](a, j) = d_j J(i, a), J =
// [R_eta, R_dv, R_y] the analytic Jacobian. Two things are central differences of analytic first
// derivatives (no nested differences), both only on articulated models: the kinetic-energy Hessian
// along q+'s joint directions, and the whole Jacobian along the root's pose under gravity. Every
// other term is exact: the product and chain rules on the base call's terms, the tensors dM/dq,
// d/dq D (mass_tensors) and the x-derivative of d/dx[K(x)^T p] on an SO(3) or SE(3) group's block
// (kt_hessian). One body (one_body_columns): every term exact.
void residual_hessians(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y) {
  const Model& model = *vm.model;
  const int nv = model.nv;
  const double dt = vm.dt, h = VARIATIONAL_FD_STEP;
  VariationalWork& w = nw.w;
  // J depends on q+ = q exp(eta) exp(dt (v + dv)) only through Sq = dR/deta+ and R_y (M(q+),
  // D(q+, y), the kinetic-energy Hessian and the gravity terms). Those are taken once along q+'s
  // own nv directions into the first-order model QplusLinear, and each eta or dv column reads them
  // by the chain rule at xi = difference(q+, q+'), which halves the kinetic-energy Hessians (one per
  // joint direction of q+ and sign, instead of one per joint direction of eta and of dv and sign). A free-flyer or spherical root's pose moves the mechanism rigidly (local
  // frames, gravity-free model): along it M, D and the kinetic-energy Hessian do not change, only
  // the gravity terms (nothing at all without gravity: those dSq, dRy are exactly zero, skipped).
  // One body: every direction is the root's.
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
    pinocchio::forwardKinematics(tg.model, tg.data, L.qn);
    const Eigen::Matrix3d W = tg.data.oMi[1].rotation();
    const Eigen::Vector3d g = vm.model->gravity.linear();
    for (int k = 0; k < root; ++k) {
      L.dRy_zero[k] = 1;
      L.dSq_zero[k] = k < rot0;
      if (k < rot0) continue;
      tg.model.gravity.linear() = g.cross(W.col(k - rot0));
      w.T.setZero();
      pinocchio::computeGeneralizedGravityDerivatives(tg.model, tg.data, L.qn, w.T);
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
  // kinetic-energy Hessian (the recursion of kinetic_hessian.hpp) and one gravity derivative per
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
    pinocchio::integrate(model, L.qn, nw.e.head(nv), nw.qp);
    lagrangian_hessian(vm, w, nw.qp, y);
    nw.Hp = w.Hk;
    nw.e[k] = -h;
    pinocchio::integrate(model, L.qn, nw.e.head(nv), nw.qp);
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
    pinocchio::integrate(model, q, nw.e.head(nv), nw.qp);
    nw.vp = v + nw.e.tail(nv);
    residual_jacobian(vm, w, nw.qp, nw.vp, y, w.Jp, keep);
    nw.e = -nw.e;
    pinocchio::integrate(model, q, nw.e.head(nv), nw.qp);
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
  // where central differences had taken two residual_jacobian calls (two mass matrices, two RNEA
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
  // which the central differences below had reproduced to their round-off (~1e-11) at two
  // residual_jacobian calls each. Taken first, while w holds the base call's blocks (the
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

}  // namespace

void variational_node(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, double* F2) {
  const int nv = vm.model->nv, nz = 2 * nv + vm.m;
  node_first_order(vm, nw, q, v, y, F1, F2 != nullptr);
  if (F2 == nullptr) return;
  residual_hessians(vm, nw, q, v, y);
  const Eigen::PartialPivLU<Eigen::MatrixXd>& lu = nw.lu_y;
  // Differentiating the right-trivialised Jacobian along integrate(q, h e_j) adds an
  // antisymmetric bracket term to the eta-eta block: the symmetric part Ts is the (0)-Hessian.
  // R is affine in u, so u enters only through P = dw/dz = [I 0; 0 I; F1]: P^T Ts P on its upper
  // triangle (dynamics.hpp, variational_projection_upper), a third of the two dense (3nv)^2 nz
  // products it replaces.
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
  node_first_order(vm, nw, q, v, y, F1, true);
  residual_hessians(vm, nw, q, v, y);
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
