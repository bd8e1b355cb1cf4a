// The variational step's internals shared by its files (variational_step.cpp,
// variational_residual.cpp, variational_hessian.cpp, variational_derivatives.cpp): the residual
// R(q, v, y, u) = 0 that defines y = v+, its Jacobian's building blocks and the second order's
// columns (namespace dyn::var). Not for use outside the variational step. mass and Dmat are
// defined here, inline: every file's callers inline them.
#pragma once

#include <pinocchio/algorithm/crba.hpp>

#include <Eigen/Core>

#include "dynamics/variational.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {
namespace var {

// M(q), full (both triangles).
inline void mass(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q, Eigen::MatrixXd& M) {
  libpin::crba(*vm.model, w.data, q);
  M = w.data.M;
  M.triangularView<Eigen::StrictlyLower>() = M.transpose();
}

// D(q, x) = d(M(q) x)/dq, right-trivialised as RNEA's dtau/dq at (q, 0, x) without gravity (zero
// for one body, whose M is constant in its own frame), from the kinetic-energy recursion
// (rigid_body/kinetic_hessian.hpp's mass_velocity_derivative: O(nv depth) dot products where Pinocchio's RNEA
// derivatives also formed dtau/dv and M).
inline void Dmat(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q, const Eigen::VectorXd& x,
                 Eigen::MatrixXd& D) {
  if (vm.configuration_free) {
    D.setZero(vm.model->nv, vm.model->nv);
    return;
  }
  mass_velocity_derivative(vm.free_model, w.fdata, w.kh, q, x, D);
}

// Jr(x)^-1 into K (block-diagonal).
void Kmat(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, Eigen::MatrixXd& K);

// out = d/dx [K(x)^T p] for fixed p = -K^T dJr[.]^T (K^T p).
void dKT(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, const Eigen::MatrixXd& K,
         const Eigen::VectorXd& p, Eigen::MatrixXd& out);


// d/deta [dL/dq(q exp(eta), v)] at eta = 0 into w.Hk: the kinetic part exact, 1/2 d/dq_j of
// D(q, v)^T v = 1/2 sum_p v_p d2tau_p/dq_i dq_j (the (i, j) order is that of differentiating the
// trivialised D along q exp(h e_j), as the Python oracle's differences do), minus the generalised
// gravity's derivative. The kinetic part comes from the spatial-vector recursion of
// rigid_body/kinetic_hessian.hpp: O(nv depth) dot products, instead of contracting the nv^3
// entries of Pinocchio's second-order RNEA at (q, 0, v) with v, which costs many times more.
// save_tensors (the second order's base point): the same recursion's tensors dM/dq and
// d/dq D(q, v) (mass_tensors: Pinocchio's d2tau_dadq and d2tau_dqdq at (q, 0, v), for a fraction
// of that call's cost) go to w.dMdq, w.d2q, which
// residual_hessians reads (VariationalWork); the first order (F1, Phi, B) does not read them.
void lagrangian_hessian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                        const Eigen::VectorXd& v, bool save_tensors = false);

// R_y = K1^T M1 - dt d/dx[K(x)^T M1 y]|_(x = -dt y) - dt D1^T, into out.
void velocity_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::MatrixXd& K1,
                       const Eigen::MatrixXd& D1, const Eigen::VectorXd& y, Eigen::MatrixXd& out);

// What a residual_jacobian call may keep from the previous call on the same work (residual_hessians
// orders its calls so that these hold). Each kept value is the one the call would compute, up to
// round-off where it rests on the root's invariance (VariationalModel::root_dirs).
//   v_terms: v is the previous call's: Ad_exp(-dt v), Jr(dt v), K(dt v) and d/dx[K^T M0 v] (its
//      dual-number dJr), when M0 is kept as well;
//   M0: q differs at most along the root's pose: M0 = M(q);
//   D0: and v is the previous call's: D0 = D(q, v);
//   lin: y is the base call's, and Sq and R_y come from q+'s first-order model (QplusLinear,
//      dynamics/variational.hpp) instead of M(q+), D(q+, y), the kinetic-energy Hessian and the gravity
//      terms at q+.
struct Keep {
  bool v_terms = false, M0 = false, D0 = false;
  bool tensors = true;  // the base call: keep dM/dq and d/dq D at q+ (lagrangian_hessian)
  const QplusLinear* lin = nullptr;
};

// [R_eta, R_dv, R_y] at any (q, v, y), into J (nv, 3 nv), keeping what `keep` allows.
void residual_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y, Eigen::MatrixXd& J,
                       const Keep& keep = Keep());

// R_ww after node_first_order (same q, v, y, the same work): nw.T[i](a, j) = d_j J(i, a), J =
// [R_eta, R_dv, R_y] the analytic Jacobian. Two things are central differences of analytic first
// derivatives (no nested differences), both only on articulated models: the kinetic-energy Hessian
// along q+'s joint directions, and the whole Jacobian along the root's pose under gravity. Every
// other term is exact: the product and chain rules on the base call's terms, the tensors dM/dq,
// d/dq D (mass_tensors) and the x-derivative of d/dx[K(x)^T p] on an SO(3) or SE(3) group's block
// (kt_hessian). One body (one_body_columns): every term exact.
void residual_hessians(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y);

}  // namespace var
}  // namespace dyn
}  // namespace geoddp
