// Crocoddyl's gait costs of a contact schedule's node (see contact.hpp): the twin of
// geoddp.problem.legged.ContactProblem._cost, term for term. Compiled inside
// dynamics/contact_algorithms.cpp.
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>

#include <algorithm>

#include "dynamics/contact.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {

namespace {

// Crocoddyl's quadratic barrier: the excess of r beyond [lb, ub] (0 inside) and its active mask.
void barrier(const Eigen::VectorXd& r, const Eigen::VectorXd& lb, const Eigen::VectorXd& ub, Eigen::VectorXd& ex,
             Eigen::VectorXd& mask) {
  ex.resize(r.size());
  mask.resize(r.size());
  for (Eigen::Index i = 0; i < r.size(); ++i) {
    ex[i] = std::min(r[i] - lb[i], 0.0) + std::max(r[i] - ub[i], 0.0);
    mask[i] = ex[i] != 0.0 ? 1.0 : 0.0;
  }
}

}  // namespace

double contact_node_cost(const ContactSetup& s, ContactWork& w, int k, const Eigen::VectorXd& q,
                         const Eigen::VectorXd& v, const Eigen::VectorXd& u, const ContactEval* ev,
                         bool derivatives, Eigen::VectorXd& g, RowMat& Hs) {
  const pinocchio::Model& m = *s.model;
  pinocchio::Data& d = w.data;
  const int nv = m.nv, nu = nv - 6, nz = 2 * nv + nu;
  const ContactNode& node = s.nodes[(size_t)k];
  const bool terminal = k == s.horizon();
  const GaitWeights& c = s.w;
  double val = 0.0;
  if (derivatives) {
    g = Eigen::VectorXd::Zero(nz);
    Hs = RowMat::Zero(nz, nz);
  }
  Eigen::VectorXd dq(nv);
  Eigen::MatrixXd D(nv, nv);

  // weight, act * residual, act (or null: ones), Jacobian (or null: identity), first column
  auto deriv = [&](double wt, const Eigen::VectorXd& ar, const Eigen::VectorXd* a, const Eigen::MatrixXd* Jr,
                   int col) {
    const int n = (int)(Jr ? Jr->cols() : ar.size());
    if (Jr == nullptr) {
      g.segment(col, n) += wt * ar;
      if (a == nullptr) Hs.block(col, col, n, n).diagonal().array() += wt;
      else Hs.block(col, col, n, n).diagonal() += wt * *a;
    } else {
      g.segment(col, n) += wt * (Jr->transpose() * ar);
      if (a == nullptr) Hs.block(col, col, n, n) += wt * (Jr->transpose() * *Jr);
      else Hs.block(col, col, n, n) += wt * (Jr->transpose() * (a->asDiagonal() * *Jr));
    }
  };
  // weight, residual, its Jacobian (rows, the q columns) or null
  auto add = [&](double wt, const Eigen::VectorXd& r, const Eigen::MatrixXd* Jr, int col) {
    val += 0.5 * wt * r.dot(r);
    if (derivatives) deriv(wt, r, nullptr, Jr, col);
  };
  auto add_state = [&](double wt, const Eigen::VectorXd& act) {
    libpin::difference(m, s.q_ref, q, dq);
    Eigen::VectorXd rs(2 * nv);
    rs.head(nv) = dq;
    rs.tail(nv) = v - s.v_ref;
    const Eigen::VectorXd ar = act.cwiseProduct(rs);
    val += 0.5 * wt * rs.dot(ar);
    if (derivatives) {
      D.setZero();
      libpin::dDifference(m, s.q_ref, q, D, pinocchio::ARG1);
      const Eigen::VectorXd aq = act.head(nv), av = act.tail(nv);
      deriv(wt, ar.head(nv), &aq, &D, 0);
      deriv(wt, ar.tail(nv), &av, nullptr, nv);
    }
  };
  libpin::Matrix6x Jf(6, nv);
  Eigen::MatrixXd Jw(3, nv);
  auto foot_jacobian = [&](int f) {
    Jf.setZero();
    libpin::computeFrameJacobian(m, d, q, (pinocchio::FrameIndex)f, pinocchio::LOCAL, Jf);
    Jw = d.oMf[(size_t)f].rotation() * Jf.topRows(3);
  };
  auto feet = [&](double wt) {
    for (size_t i = 0; i < node.swing.size(); ++i) {
      const int f = node.swing[i];
      const Eigen::VectorXd r = d.oMf[(size_t)f].translation() - node.swing_target[i];
      if (derivatives) foot_jacobian(f);
      add(wt, r, derivatives ? &Jw : nullptr, 0);
    }
  };

  libpin::forwardKinematics(m, d, q);
  libpin::updateFramePlacements(m, d);
  if (node.impulse && !terminal) {
    add_state(c.impulse_state, s.w_impulse);
    feet(c.impulse_foot);
    add(c.impulse_control, u, nullptr, 2 * nv);
    return val;
  }
  add_state(c.state, s.w_state);
  {
    Eigen::VectorXd rb(2 * nv), ex, mask;
    libpin::difference(m, s.q_neutral, q, dq);
    rb.head(nv) = dq;
    rb.tail(nv) = v;
    barrier(rb, s.lb, s.ub, ex, mask);
    val += 0.5 * c.bounds * ex.dot(ex);
    if (derivatives) {
      D.setZero();
      libpin::dDifference(m, s.q_neutral, q, D, pinocchio::ARG1);
      const Eigen::VectorXd eq = ex.head(nv), mq = mask.head(nv), evv = ex.tail(nv), mv = mask.tail(nv);
      deriv(c.bounds, eq, &mq, &D, 0);
      deriv(c.bounds, evv, &mv, nullptr, nv);
    }
  }
  if (node.has_com) {
    const Eigen::VectorXd r = libpin::centerOfMass(m, d, q) - node.com;
    if (derivatives) {
      const Eigen::MatrixXd Jcom = libpin::jacobianCenterOfMass(m, d, q);
      add(c.com, r, &Jcom, 0);
    } else {
      add(c.com, r, nullptr, 0);
    }
  }
  feet(c.foot);
  if (terminal) return val;
  add(c.control, u, nullptr, 2 * nv);
  const int nf = (int)node.feet.size();
  if (nf > 0) {
    Eigen::VectorXd ex, mask;
    for (int i = 0; i < nf; ++i) {
      const Eigen::VectorXd r = s.cone_A * ev->forces.segment(3 * i, 3);
      barrier(r, s.cone_lb, s.cone_ub, ex, mask);
      val += 0.5 * c.friction_cone * ex.dot(ex);
      if (derivatives && mask.any()) {
        const RowMat Jr = s.cone_A * ev->Lz.middleRows(3 * i, 3);
        g += c.friction_cone * (Jr.transpose() * ex);
        Hs += c.friction_cone * (Jr.transpose() * (mask.asDiagonal() * Jr));
      }
    }
  }
  val *= s.dt;
  if (derivatives) {
    g *= s.dt;
    Hs *= s.dt;
  }
  return val;
}

}  // namespace dyn
}  // namespace geoddp
