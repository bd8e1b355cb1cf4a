// RNEA's second-order tensors for a model of one rigid body on a free-flyer or spherical root
// (the spacecraft, the quadrotors, the satellite): Pinocchio's own tensors, computed once per
// expansion instead of once per node.
//
// Why they are cheap: such a body's inverse dynamics, in its own frame, is
//   tau = I (a - g_b) + v x* (I v),   g_b = R^T g (gravity seen from the body, R = R_plc R(q)),
// with I the body's spatial inertia about the joint (constant in the body frame) and the armature a
// constant diagonal. So
//   d2tau/dv2 is a constant tensor (v x* I v is bilinear), d2tau/dqdv = 0 and dM/dq = 0 (no term
//   couples q with v or a), and
//   d2tau/dq2 (Pinocchio's derivative on the group, not symmetric in the rotation block) depends on
//   q only through g_b, linearly: d2tau/dq2 (q) = sum_c g_b,c T_c, where T_c is the tensor of the
//   same body at the identity under unit gravity e_c.
// Pinocchio's ComputeRNEASecondOrderDerivatives costs several times its computeABADerivatives, and
// an exact expansion of such a body would call it at every node. Here Pinocchio computes T_c (three
// calls) and d2tau/dv2 (one of them) once per expansion; each node then costs three axpys of nv^3
// numbers.
// tests/test_core_dynamics.py checks every tensor against Pinocchio's at random states (near the
// identity and near pi, gravity on and off, free flyer and spherical, a rotated root placement).
#pragma once

#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/multibody.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <vector>

#include "lie/joint_groups.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/pinocchio_second_order.hpp"

namespace geoddp {
namespace dyn {

class OneBodySecondOrder {
 public:
  // True for a model of one joint, free flyer or spherical, whose gravity has no angular part
  // (Pinocchio's gravity is a spatial acceleration; an angular one would make tau depend on q
  // otherwise). Fixed joints merged into the body do not count: Pinocchio folds them in.
  static bool applies(const pinocchio::Model& model) {
    if (model.njoints != 2 || !model.gravity.angular().isZero(0.0)) return false;
    const int kind = boost::apply_visitor(GroupKindOf(), model.joints[1].toVariant());
    return kind == SO3 || kind == SE3;
  }

  // True when, moreover, gravity is zero: then tau does not depend on q at all and d2tau_dqdq is
  // zero at every state (the variational step's kinetic-energy Hessian, dynamics/variational_residual.cpp).
  static bool free_of_configuration(const pinocchio::Model& model) {
    return applies(model) && model.gravity.linear().isZero(0.0);
  }

  explicit OneBodySecondOrder(const pinocchio::Model& model)
      : nv_(model.nv), quat_at_(model.joints[1].idx_q() + (model.joints[1].nv() == 6 ? 3 : 0)) {
    const size_t n3 = (size_t)nv_ * nv_ * nv_;
    // gravity in the joint's parent frame: g_b = R(q)^T (R_plc^T g)
    g_parent_ = model.jointPlacements[1].rotation().transpose() * model.gravity.linear();
    with_gravity_ = !g_parent_.isZero(0.0);
    pinocchio::Model unit = model;
    unit.jointPlacements[1] = pinocchio::SE3::Identity();
    pinocchio::Data data(unit);
    const Eigen::VectorXd q0 = libpin::neutral(unit), zero = Eigen::VectorXd::Zero(nv_);
    Ivv_.resize(n3);
    for (int c = 0; c < 3; ++c) {
      unit.gravity.setZero();
      unit.gravity.linear()[c] = 1.0;
      libpin::rnea_second_order_tensors(unit, data, q0, zero, zero);
      if (c == 0) std::copy(data.d2tau_dvdv.data(), data.d2tau_dvdv.data() + n3, Ivv_.data());
      if (!with_gravity_) break;
      T_[c].assign(data.d2tau_dqdq.data(), data.d2tau_dqdq.data() + n3);
    }
  }

  // Pinocchio's d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq (nv^3 each, column-major as
  // Pinocchio stores them) at configuration q (nq), for any v and a.
  void at(const double* q, double* Iqq, double* Ivv, double* Iqv, double* dM) const {
    const size_t n3 = (size_t)nv_ * nv_ * nv_;
    std::copy(Ivv_.begin(), Ivv_.end(), Ivv);
    std::fill(Iqv, Iqv + n3, 0.0);
    std::fill(dM, dM + n3, 0.0);
    dqdq_at(q, Iqq);
  }

  // Whether d2tau_dqdq is nonzero (gravity on); d2tau_dqdv and d2tau_dadq are always zero.
  bool with_gravity() const { return with_gravity_; }
  // The constant d2tau_dvdv (nv^3, column-major).
  const std::vector<double>& d2tau_dvdv() const { return Ivv_; }
  // d2tau_dqdq alone at configuration q (what at() writes into Iqq); zero without gravity.
  void dqdq_at(const double* q, double* Iqq) const {
    const size_t n3 = (size_t)nv_ * nv_ * nv_;
    if (!with_gravity_) {
      std::fill(Iqq, Iqq + n3, 0.0);
      return;
    }
    // R(q) as Pinocchio's joints form it: the (x, y, z, w) quaternion's matrix
    const Eigen::Map<const Eigen::Quaterniond> quat(q + quat_at_);
    const Eigen::Vector3d gb = quat.matrix().transpose() * g_parent_;
    const double *t0 = T_[0].data(), *t1 = T_[1].data(), *t2 = T_[2].data();
    for (size_t i = 0; i < n3; ++i) Iqq[i] = gb[0] * t0[i] + gb[1] * t1[i] + gb[2] * t2[i];
  }

 private:
  int nv_, quat_at_;
  Eigen::Vector3d g_parent_;
  bool with_gravity_ = false;
  std::vector<double> Ivv_;
  std::array<std::vector<double>, 3> T_;
};

}  // namespace dyn
}  // namespace geoddp
