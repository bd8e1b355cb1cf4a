// The variational step itself: the model and its scratch, and the damped Newton iteration on
// R(y) = 0 (see dynamics/variational.hpp; twin of tests/oracle_variational.py's step). Compiled inside
// dynamics/variational_algorithms.cpp.
#include "dynamics/variational.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/LU>
#include <cmath>
#include <cstdio>

#include "dynamics/variational_fixed.hpp"
#include "dynamics/variational_residual.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/one_body.hpp"

namespace geoddp {
namespace dyn {
namespace var {

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

// R at y (into r) with K1 = K(-dt y); M1 = M(q+), g1 = g(q+), b fixed. R needs no D(q+, y), only
// 1/2 D(q+, y)^T y, the kinetic energy's gradient (rigid_body/kinetic_hessian.hpp: O(nv), where Pinocchio's
// RNEA derivatives would form all of D at every trial point of the step's line search).
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
  libpin::integrate(model, q, w.omega, w.qn);
  const Mat M = vm.M_body;  // = M(q) = M(q+)
  const Vec v0 = v;
  const Vec x0 = dt * v0;
  Vec c0 = -(L::inverse(L::jr(x0, L::coefficients(x0))).transpose() * (M * v0)) - dt * Vec(tau);
  if (!vm.gravity_free) c0 += dt * Vec(libpin::computeGeneralizedGravity(model, w.data, w.qn));
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
  Vec y = v0 + dt * Vec(libpin::aba(model, w.data, w.qn, v, tau));
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

}  // namespace
}  // namespace var

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
    libpin::crba(model_, data, libpin::neutral(model_));
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
  using namespace var;
  if (vm.configuration_free) {  // one body: fixed-size matrices
    if (vm.model->nv == 6) one_body_step<6>(vm, w, q, v, tau, q1, v1);
    else one_body_step<3>(vm, w, q, v, tau, q1, v1);
    return;
  }
  const Model& model = *vm.model;
  const double dt = vm.dt;
  w.omega = dt * v;
  libpin::integrate(model, q, w.omega, w.qn);
  // b = K(dt v)^T M(q) v + dt tau: the y-independent part of R
  Kmat(vm, w, w.omega, w.K0);
  mass(vm, w, q, w.M0);
  w.tmp.noalias() = w.M0 * v;
  w.b.noalias() = w.K0.transpose() * w.tmp;
  w.b += dt * tau;
  mass(vm, w, w.qn, w.M1);
  if (vm.gravity_free) w.g1.setZero();  // no gravity: no Pinocchio call
  else w.g1 = libpin::computeGeneralizedGravity(model, w.data, w.qn);
  // Start from the better of v and the explicit (symplectic) Euler velocity; damped Newton
  // (backtracking on |R|) keeps stiff light links from throwing the iteration off.
  Eigen::VectorXd& y = w.y;
  y = v + dt * libpin::aba(model, w.data, w.qn, v, tau);
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

}  // namespace dyn
}  // namespace geoddp
