// Pinocchio's algorithms through the instantiations compiled inside the pin wheel's
// libpinocchio_default.
//
// With PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, Pinocchio's headers declare each algorithm
// `extern template` for one set of argument types (mostly Eigen::Ref<const VectorXd>; plain
// VectorXd / MatrixXd / Matrix6Xd for the Lie-group operations and frame Jacobians). A call whose
// arguments deduce to any other type (a VectorXd where a Ref is declared, a Block, a Map, an
// expression) instantiates the algorithm again in our translation unit, over every joint type of
// the variant: that, more than anything of ours, was what made the core's build slow (about 15
// min for dynamics/core_algorithms.cpp). Each wrapper here names the template arguments of the
// library's instantiation, so the call links against the wheel's copy, which also runs faster
// (benchmarks/pinocchio_calls.py). Same algorithm and arithmetic; only the machine code differs.
// Arguments of another type convert (a Ref binds to any contiguous vector; a Block of a VectorXd
// is copied into the VectorXd parameter), so call sites need no casts.
//
// Every Pinocchio algorithm the core calls goes through here, except three that the wheel does not
// instantiate: the second-order RNEA (rigid_body/pinocchio_second_order.hpp, instantiated once in
// its own file) and the legacy contact-dynamics calls forwardDynamics / impulseDynamics with an
// explicit contact Jacobian (cheap: no joint visitor). tests/test_layering.py checks that no other
// file calls these algorithms on pinocchio:: directly.
#pragma once

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames-derivatives.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics-derivatives.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include <Eigen/Core>

#include <vector>

namespace geoddp {
namespace libpin {

typedef pinocchio::Model Model;
typedef pinocchio::Data Data;
typedef Eigen::Ref<const Eigen::VectorXd> VecRef;
typedef Eigen::Ref<Eigen::MatrixXd> MatRef;
typedef Eigen::Matrix<double, 6, Eigen::Dynamic> Matrix6x;
typedef std::vector<pinocchio::Force> Forces;
#define GEODDP_PIN_LIB double, 0, pinocchio::JointCollectionDefaultTpl

// ---- kinematics --------------------------------------------------------------------------------
inline void forwardKinematics(const Model& m, Data& d, const VecRef& q) {
  pinocchio::forwardKinematics<GEODDP_PIN_LIB, VecRef>(m, d, q);
}
inline void forwardKinematics(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& a) {
  pinocchio::forwardKinematics<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, a);
}
inline void computeForwardKinematicsDerivatives(const Model& m, Data& d, const VecRef& q, const VecRef& v,
                                                const VecRef& a) {
  pinocchio::computeForwardKinematicsDerivatives<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, a);
}
// data.J (6, nv), world frame; also the forward kinematics (placements).
inline const Matrix6x& computeJointJacobians(const Model& m, Data& d, const VecRef& q) {
  return pinocchio::computeJointJacobians<GEODDP_PIN_LIB, VecRef>(m, d, q);
}
inline void computeAllTerms(const Model& m, Data& d, const VecRef& q, const VecRef& v) {
  pinocchio::computeAllTerms<GEODDP_PIN_LIB, VecRef, VecRef>(m, d, q, v);
}
// oMf of every frame from data.oMi.
inline void updateFramePlacements(const Model& m, Data& d) { pinocchio::updateFramePlacements<GEODDP_PIN_LIB>(m, d); }
// J (6, nv): frame f's Jacobian in `rf` from data.J (after computeJointJacobians or computeAllTerms).
inline void getFrameJacobian(const Model& m, Data& d, pinocchio::FrameIndex f, pinocchio::ReferenceFrame rf,
                             Matrix6x& J) {
  pinocchio::getFrameJacobian<GEODDP_PIN_LIB, Matrix6x>(m, d, f, rf, J);
}
inline pinocchio::Motion getFrameVelocity(const Model& m, const Data& d, pinocchio::FrameIndex f,
                                          pinocchio::ReferenceFrame rf) {
  return pinocchio::getFrameVelocity<GEODDP_PIN_LIB>(m, d, f, rf);
}
inline pinocchio::Motion getFrameClassicalAcceleration(const Model& m, const Data& d, pinocchio::FrameIndex f,
                                                       pinocchio::ReferenceFrame rf) {
  return pinocchio::getFrameClassicalAcceleration<GEODDP_PIN_LIB>(m, d, f, rf);
}
// After computeForwardKinematicsDerivatives: frame f's velocity and spatial-acceleration
// derivatives (6, nv) each, added into the outputs' support columns.
inline void getFrameAccelerationDerivatives(const Model& m, Data& d, pinocchio::FrameIndex f,
                                            pinocchio::ReferenceFrame rf, Matrix6x& v_dq, Matrix6x& a_dq,
                                            Matrix6x& a_dv, Matrix6x& a_da) {
  pinocchio::getFrameAccelerationDerivatives<GEODDP_PIN_LIB, Matrix6x, Matrix6x, Matrix6x, Matrix6x>(
      m, d, f, rf, v_dq, a_dq, a_dv, a_da);
}
inline void getFrameVelocityDerivatives(const Model& m, Data& d, pinocchio::FrameIndex f,
                                        pinocchio::ReferenceFrame rf, Matrix6x& v_dq, Matrix6x& v_dv) {
  pinocchio::getFrameVelocityDerivatives<GEODDP_PIN_LIB, Matrix6x, Matrix6x>(m, d, f, rf, v_dq, v_dv);
}
// After computeJointJacobians: every joint's kinematic Hessian (data.kinematic_hessians).
inline void computeJointKinematicHessians(const Model& m, Data& d) {
  pinocchio::computeJointKinematicHessians<GEODDP_PIN_LIB>(m, d);
}
// H (6, nv, nv): frame f's kinematic Hessian in `rf` (after computeJointKinematicHessians).
inline void getFrameKinematicHessian(const Model& m, const Data& d, pinocchio::FrameIndex f,
                                     pinocchio::ReferenceFrame rf, pinocchio::Tensor<double, 3>& H) {
  pinocchio::getFrameKinematicHessian<GEODDP_PIN_LIB>(m, d, f, rf, H);
}
// J (6, nv) += the frame's Jacobian in `rf` (Pinocchio sets the columns of the frame's support).
inline void computeFrameJacobian(const Model& m, Data& d, const Eigen::VectorXd& q, pinocchio::FrameIndex f,
                                 pinocchio::ReferenceFrame rf, Matrix6x& J) {
  pinocchio::computeFrameJacobian<GEODDP_PIN_LIB, Eigen::VectorXd, Matrix6x>(m, d, q, f, rf, J);
}

// ---- centre of mass ----------------------------------------------------------------------------
inline const Eigen::Vector3d& centerOfMass(const Model& m, Data& d, const VecRef& q) {
  return pinocchio::centerOfMass<GEODDP_PIN_LIB, VecRef>(m, d, q, true);
}
inline double computeTotalMass(const Model& m) { return pinocchio::computeTotalMass<GEODDP_PIN_LIB>(m); }
// data.Jcom (3, nv), world frame.
inline const Eigen::Matrix<double, 3, Eigen::Dynamic>& jacobianCenterOfMass(const Model& m, Data& d,
                                                                              const VecRef& q) {
  return pinocchio::jacobianCenterOfMass<GEODDP_PIN_LIB, VecRef>(m, d, q, true);
}

// ---- dynamics ----------------------------------------------------------------------------------
// data.ddq = ABA(q, v, tau), local convention (pinocchio::aba's default); returns data.ddq.
inline const Eigen::VectorXd& aba(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& tau) {
  return pinocchio::aba<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, tau, pinocchio::Convention::LOCAL);
}
// data.M's upper triangle (local convention).
inline const Eigen::MatrixXd& crba(const Model& m, Data& d, const VecRef& q) {
  return pinocchio::crba<GEODDP_PIN_LIB, VecRef>(m, d, q, pinocchio::Convention::LOCAL);
}
inline const Eigen::VectorXd& rnea(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& a) {
  return pinocchio::rnea<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, a);
}
inline const Eigen::VectorXd& computeGeneralizedGravity(const Model& m, Data& d, const VecRef& q) {
  return pinocchio::computeGeneralizedGravity<GEODDP_PIN_LIB, VecRef>(m, d, q);
}

// ---- first derivatives -------------------------------------------------------------------------
// data.ddq_dq, ddq_dv, Minv (upper triangle).
inline void computeABADerivatives(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& tau) {
  pinocchio::computeABADerivatives<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, tau);
}
// data.dtau_dq, dtau_dv, M (upper triangle).
inline void computeRNEADerivatives(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& a) {
  pinocchio::computeRNEADerivatives<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, a);
}
// The same with external forces fext (one per joint, in the joint's frame).
inline void computeRNEADerivatives(const Model& m, Data& d, const VecRef& q, const VecRef& v, const VecRef& a,
                                   const Forces& fext) {
  pinocchio::computeRNEADerivatives<GEODDP_PIN_LIB, VecRef, VecRef, VecRef>(m, d, q, v, a, fext);
}
// g_partial_dq (nv, nv) = d g(q) / dq (overwritten).
inline void computeGeneralizedGravityDerivatives(const Model& m, Data& d, const VecRef& q, MatRef g_partial_dq) {
  pinocchio::computeGeneralizedGravityDerivatives<GEODDP_PIN_LIB, VecRef, MatRef>(m, d, q, g_partial_dq);
}

// ---- configuration space (Lie group of the joints) ---------------------------------------------
// out (nq) = q (+) v.
inline void integrate(const Model& m, const Eigen::VectorXd& q, const Eigen::VectorXd& v, Eigen::VectorXd& out) {
  pinocchio::integrate<GEODDP_PIN_LIB, Eigen::VectorXd, Eigen::VectorXd, Eigen::VectorXd>(m, q, v, out);
}
// out (nv) = q1 (-) q0.
inline void difference(const Model& m, const Eigen::VectorXd& q0, const Eigen::VectorXd& q1, Eigen::VectorXd& out) {
  pinocchio::difference<GEODDP_PIN_LIB, Eigen::VectorXd, Eigen::VectorXd, Eigen::VectorXd>(m, q0, q1, out);
}
inline Eigen::VectorXd neutral(const Model& m) { return pinocchio::neutral<GEODDP_PIN_LIB>(m); }
// J (nv, nv) = d integrate(q, v) / d arg.
inline void dIntegrate(const Model& m, const Eigen::VectorXd& q, const Eigen::VectorXd& v, Eigen::MatrixXd& J,
                       pinocchio::ArgumentPosition arg) {
  pinocchio::dIntegrate<GEODDP_PIN_LIB, Eigen::VectorXd, Eigen::VectorXd, Eigen::MatrixXd>(m, q, v, J, arg);
}
// J (nv, nv) = d difference(q0, q1) / d arg.
inline void dDifference(const Model& m, const Eigen::VectorXd& q0, const Eigen::VectorXd& q1, Eigen::MatrixXd& J,
                        pinocchio::ArgumentPosition arg) {
  pinocchio::dDifference<GEODDP_PIN_LIB, Eigen::VectorXd, Eigen::VectorXd, Eigen::MatrixXd>(m, q0, q1, J, arg);
}

#undef GEODDP_PIN_LIB

}  // namespace libpin
}  // namespace geoddp
