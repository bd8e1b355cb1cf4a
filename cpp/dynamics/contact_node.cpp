// Contact and impulse node dynamics with first derivatives (see contact.hpp); the twin of
// geoddp.models.contact.ContactDynamics.contact / impulse, call for call. Compiled inside
// dynamics/contact_algorithms.cpp.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/compute-all-terms.hpp>
#include <pinocchio/algorithm/contact-dynamics.hpp>
#include <pinocchio/algorithm/frames-derivatives.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics-derivatives.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>

#include <Eigen/LU>

#include "dynamics/contact.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {

namespace {

typedef Eigen::Matrix<double, 6, Eigen::Dynamic> Mat6x;
typedef pinocchio::container::aligned_vector<pinocchio::Force> ForceVector;

inline Eigen::Matrix3d skew3(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0;
  return S;
}

// The contact forces (foot frame) as external forces on their parent joints.
ForceVector foot_forces(const pinocchio::Model& m, const std::vector<int>& feet,
                        const std::vector<Eigen::Vector3d>& local) {
  ForceVector fext((size_t)m.njoints, pinocchio::Force::Zero());
  for (size_t i = 0; i < feet.size(); ++i) {
    const pinocchio::Frame& fr = m.frames[(size_t)feet[i]];
    fext[fr.parentJoint] += fr.placement.act(pinocchio::Force(local[i], Eigen::Vector3d::Zero()));
  }
  return fext;
}

// -(K^-1 rhs), K = [[M, -Jl^T], [Jl, 0]] with M from Pinocchio's upper triangle.
RowMat kkt_solve(const Eigen::MatrixXd& Mupper, const Eigen::MatrixXd& Jl, const RowMat& rhs) {
  const int nv = (int)Mupper.rows(), nc = (int)Jl.rows();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nv + nc, nv + nc);
  K.topLeftCorner(nv, nv) = Mupper.selfadjointView<Eigen::Upper>();
  if (nc > 0) {
    K.topRightCorner(nv, nc) = -Jl.transpose();
    K.bottomLeftCorner(nc, nv) = Jl;
  }
  const Eigen::MatrixXd Kinv = K.partialPivLu().inverse();
  return -(Kinv * rhs);
}

}  // namespace

void contact_node(const ContactSetup& s, ContactWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, const Eigen::VectorXd& u, bool derivatives, ContactEval& ev) {
  const pinocchio::Model& m = *s.model;
  pinocchio::Data& d = w.data;
  const int nv = m.nv, nu = nv - 6, nz = 2 * nv + nu;
  const int nf = (int)node.feet.size(), nc = 3 * nf;
  const double dt = s.dt, Kp = s.Kp, Kd = s.Kd;
  libpin::computeAllTerms(m, d, q, v);
  libpin::updateFramePlacements(m, d);
  std::vector<Mat6x> J((size_t)nf);
  std::vector<Eigen::Matrix3d> R((size_t)nf);
  std::vector<pinocchio::Motion> vf((size_t)nf);
  std::vector<Eigen::Vector3d> dp((size_t)nf);
  Eigen::MatrixXd Jc(nc, nv);
  Eigen::VectorXd a0w(nc);
  for (int i = 0; i < nf; ++i) {
    const pinocchio::FrameIndex f = (pinocchio::FrameIndex)node.feet[(size_t)i];
    J[i] = Mat6x::Zero(6, nv);
    libpin::getFrameJacobian(m, d, f, pinocchio::LOCAL, J[i]);
    R[i] = d.oMf[f].rotation();
    vf[i] = libpin::getFrameVelocity(m, d, f, pinocchio::LOCAL);
    Eigen::Vector3d a0 = libpin::getFrameClassicalAcceleration(m, d, f, pinocchio::LOCAL).linear();
    if (Kp != 0.0) {
      dp[i] = R[i].transpose() * d.oMf[f].translation();
      a0 += Kp * dp[i];
    }
    if (Kd != 0.0) a0 += Kd * vf[i].linear();
    Jc.middleRows(3 * i, 3) = R[i] * J[i].topRows(3);
    a0w.segment(3 * i, 3) = R[i] * a0;
  }
  Eigen::VectorXd tau = Eigen::VectorXd::Zero(nv);
  tau.tail(nu) = u;
  Eigen::VectorXd a;
  if (nf > 0) {
    pinocchio::forwardDynamics(m, d, tau, Jc, a0w, 0.0);
    a = d.ddq;
    ev.forces = d.lambda_c;
  } else {
    a = libpin::aba(m, d, q, v, tau);
    ev.forces.resize(0);
  }
  ev.acc = a;
  ev.v_next = v + a * dt;
  const Eigen::VectorXd step = v * dt + a * (dt * dt);
  ev.q_next.resize(m.nq);
  libpin::integrate(m, q, step, ev.q_next);
  if (!derivatives) return;

  std::vector<Eigen::Vector3d> lam_local((size_t)nf);
  for (int i = 0; i < nf; ++i) lam_local[i] = R[i].transpose() * ev.forces.segment(3 * i, 3);
  const ForceVector fext = foot_forces(m, node.feet, lam_local);
  libpin::computeRNEADerivatives(m, d, q, v, a, fext);
  const Eigen::MatrixXd M = d.M;  // upper triangle
  RowMat rhs = RowMat::Zero(nv + nc, nz);
  rhs.block(0, 0, nv, nv) = d.dtau_dq;
  rhs.block(0, nv, nv, nv) = d.dtau_dv;
  rhs.block(6, 2 * nv, nu, nu) = -Eigen::MatrixXd::Identity(nu, nu);
  Eigen::MatrixXd Jl(nc, nv);
  if (nf > 0) {
    libpin::computeForwardKinematicsDerivatives(m, d, q, v, a);
    Mat6x V_dq(6, nv), A_dq(6, nv), A_dv(6, nv), A_da(6, nv);
    for (int i = 0; i < nf; ++i) {
      V_dq.setZero();
      A_dq.setZero();
      A_dv.setZero();
      A_da.setZero();
      libpin::getFrameAccelerationDerivatives(m, d, (pinocchio::FrameIndex)node.feet[(size_t)i], pinocchio::LOCAL,
                                                 V_dq, A_dq, A_dv, A_da);
      const Eigen::Matrix3d Wx = skew3(vf[i].angular()), Vx = skew3(vf[i].linear());
      Eigen::MatrixXd h_q = A_dq.topRows(3) + Wx * V_dq.topRows(3) - Vx * V_dq.bottomRows(3);
      Eigen::MatrixXd h_v = A_dv.topRows(3) + Wx * J[i].topRows(3) - Vx * J[i].bottomRows(3);
      if (Kp != 0.0) h_q += Kp * (skew3(dp[i]) * J[i].bottomRows(3) + J[i].topRows(3));
      if (Kd != 0.0) {
        h_q += Kd * V_dq.topRows(3);
        h_v += Kd * J[i].topRows(3);
      }
      Jl.middleRows(3 * i, 3) = J[i].topRows(3);
      rhs.block(nv + 3 * i, 0, 3, nv) = h_q;
      rhs.block(nv + 3 * i, nv, 3, nv) = h_v;
    }
  }
  const RowMat sol = kkt_solve(M, Jl, rhs);
  ev.Lz.resize(nc, nz);
  for (int i = 0; i < nf; ++i) {
    ev.Lz.middleRows(3 * i, 3) = R[i] * sol.middleRows(nv + 3 * i, 3);
    ev.Lz.block(3 * i, 0, 3, nv) -= R[i] * skew3(lam_local[i]) * J[i].bottomRows(3);
  }
  RowMat dvn = dt * sol.topRows(nv);
  dvn.block(0, nv, nv, nv).diagonal().array() += 1.0;
  Eigen::MatrixXd Dq = Eigen::MatrixXd::Zero(nv, nv), Dw = Eigen::MatrixXd::Zero(nv, nv);
  libpin::dIntegrate(m, q, step, Dq, pinocchio::ARG0);
  libpin::dIntegrate(m, q, step, Dw, pinocchio::ARG1);
  ev.Fz.resize(2 * nv, nz);
  ev.Fz.topRows(nv) = dt * (Dw * dvn);
  ev.Fz.block(0, 0, nv, nv) += Dq;
  ev.Fz.bottomRows(nv) = dvn;
  ev.Az = sol.topRows(nv);
}

void impulse_node(const ContactSetup& s, ContactWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, bool derivatives, ContactEval& ev) {
  const pinocchio::Model& m = *s.model;
  pinocchio::Data& d = w.data;
  const int nv = m.nv, nu = nv - 6, nz = 2 * nv + nu;
  const int nf = (int)node.feet.size(), nc = 3 * nf;
  libpin::computeAllTerms(m, d, q, v);
  libpin::updateFramePlacements(m, d);
  std::vector<Mat6x> J((size_t)nf);
  std::vector<Eigen::Matrix3d> R((size_t)nf);
  Eigen::MatrixXd Jc(nc, nv);
  for (int i = 0; i < nf; ++i) {
    const pinocchio::FrameIndex f = (pinocchio::FrameIndex)node.feet[(size_t)i];
    J[i] = Mat6x::Zero(6, nv);
    libpin::getFrameJacobian(m, d, f, pinocchio::LOCAL, J[i]);
    R[i] = d.oMf[f].rotation();
    Jc.middleRows(3 * i, 3) = R[i] * J[i].topRows(3);
  }
  pinocchio::impulseDynamics(m, d, v, Jc, 0.0, s.impulse_damping);  // M from computeAllTerms
  ev.v_next = d.dq_after;
  ev.forces = d.impulse_c;
  ev.q_next = q;
  ev.acc.resize(0);
  if (!derivatives) return;

  std::vector<Eigen::Vector3d> imp_local((size_t)nf);
  for (int i = 0; i < nf; ++i) imp_local[i] = R[i].transpose() * ev.forces.segment(3 * i, 3);
  const ForceVector fext = foot_forces(m, node.feet, imp_local);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(nv);
  const Eigen::VectorXd jump = ev.v_next - v;
  libpin::computeRNEADerivatives(m, d, q, zero, jump, fext);
  const Eigen::MatrixXd dtau_dq = d.dtau_dq;
  const Eigen::MatrixXd M = d.M;  // upper triangle
  Eigen::MatrixXd dg_dq = Eigen::MatrixXd::Zero(nv, nv);
  libpin::computeGeneralizedGravityDerivatives(m, d, q, dg_dq);
  RowMat rhs = RowMat::Zero(nv + nc, nz);
  rhs.block(0, 0, nv, nv) = dtau_dq - dg_dq;
  rhs.block(0, nv, nv, nv) = -Eigen::MatrixXd(M.selfadjointView<Eigen::Upper>());
  libpin::computeForwardKinematicsDerivatives(m, d, q, ev.v_next, zero);
  Eigen::MatrixXd Jl(nc, nv);
  Mat6x v_dq(6, nv), v_dv(6, nv);
  for (int i = 0; i < nf; ++i) {
    v_dq.setZero();
    v_dv.setZero();
    libpin::getFrameVelocityDerivatives(m, d, (pinocchio::FrameIndex)node.feet[(size_t)i], pinocchio::LOCAL, v_dq,
                                           v_dv);
    Jl.middleRows(3 * i, 3) = J[i].topRows(3);
    rhs.block(nv + 3 * i, 0, 3, nv) = v_dq.topRows(3);
  }
  const RowMat sol = kkt_solve(M, Jl, rhs);
  ev.Lz.resize(nc, nz);
  for (int i = 0; i < nf; ++i) {
    ev.Lz.middleRows(3 * i, 3) = R[i] * sol.middleRows(nv + 3 * i, 3);
    ev.Lz.block(3 * i, 0, 3, nv) -= R[i] * skew3(imp_local[i]) * J[i].bottomRows(3);
  }
  ev.Fz = RowMat::Zero(2 * nv, nz);
  ev.Fz.block(0, 0, nv, nv).diagonal().setOnes();
  ev.Fz.bottomRows(nv) = sol.topRows(nv);
  ev.Az = sol.topRows(nv);
}

}  // namespace dyn
}  // namespace geoddp
