// The kinetic energy's configuration Hessian by spatial-vector recursions (kinetic_hessian.hpp).
// Included by core_algorithms.cpp (the translation unit of Pinocchio's algorithm instantiations).
#include "kinetic_hessian.hpp"

#include <pinocchio/algorithm/jacobian.hpp>

#include <algorithm>

namespace geoddp {
namespace dyn {

KineticHessianWork::KineticHessianWork(const pinocchio::Model& model)
    : V(model.njoints), h(model.njoints), Ic(model.njoints), xi(model.nv), u(model.nv), A(model.nv), A0(model.nv),
      B(model.nv), w(model.nv), joint(model.nv),
      last(model.njoints) {
  for (int j = 0; j < model.njoints; ++j) {
    last[j] = j;
    for (const auto s : model.subtrees[j]) last[j] = std::max(last[j], (int)s);
  }
  for (int j = 1; j < model.njoints; ++j)
    for (int d = 0; d < model.nvs[j]; ++d) joint[model.idx_vs[j] + d] = j;
}

namespace {

// The world-frame terms both functions start from: data.oMi and the columns data.J, the body
// velocities w.V, and the subtrees' momenta w.h and composite inertias w.Ic.
void subtree_terms(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                   const Eigen::VectorXd& q, const Eigen::VectorXd& y) {
  const int nj = model.njoints;
  pinocchio::computeJointJacobians(model, data, q);
  // forward: world body velocities V_j = V_parent + sum of the joint's columns times y
  w.V[0].setZero();
  for (int j = 1; j < nj; ++j) {
    const int i0 = model.idx_vs[j], n = model.nvs[j];
    w.V[j] = w.V[model.parents[j]];
    w.V[j].toVector().noalias() += data.J.middleCols(i0, n) * y.segment(i0, n);
  }
  // backward: subtree momenta and composite inertias (world frame)
  for (int j = 1; j < nj; ++j) {
    w.Ic[j] = data.oMi[j].act(model.inertias[j]);
    w.h[j] = w.Ic[j] * w.V[j];
  }
  for (int j = nj - 1; j > 1; --j) {
    const int p = model.parents[j];
    if (p == 0) continue;
    w.Ic[p] += w.Ic[j];
    w.h[p] += w.h[j];
  }
}

}  // namespace

void kinetic_gradient(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                      const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::VectorXd& g) {
  subtree_terms(model, data, w, q, y);
  for (int k = 0; k < model.nv; ++k) {
    const int jk = w.joint[k];
    const pinocchio::Motion u = pinocchio::Motion(data.J.col(k)).cross(w.V[model.parents[jk]]);
    g[k] = -u.dot(w.h[jk]);
  }
}

void kinetic_hessian(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::MatrixXd& H) {
  using pinocchio::Force;
  using pinocchio::Motion;
  const int nv = model.nv;
  subtree_terms(model, data, w, q, y);
  // per dof: the pair terms' factors (kinetic_hessian.hpp)
  for (int k = 0; k < nv; ++k) {
    const int jk = w.joint[k];
    const Motion xi(data.J.col(k));
    const Motion& Vp = w.V[model.parents[jk]];
    const Force& h = w.h[jk];
    const Motion u = xi.cross(Vp);
    const Force Q = xi.cross(h), S = u.cross(h), R = Vp.cross(Q), P = xi.cross(Vp.cross(h));
    const Force wk = w.Ic[jk] * u;
    w.xi[k] = xi.toVector();
    w.u[k] = u.toVector();
    w.A0[k] = P.toVector() - S.toVector();
    w.A[k] = w.A0[k] - R.toVector();
    w.B[k] = Q.toVector() - wk.toVector();
    w.w[k] = wk.toVector();
  }
  // pairs: H(k, l) = 1/2 d_l d_k phi
  for (int k = 0; k < nv; ++k) {
    const int jk = w.joint[k];
    for (int l = 0; l < nv; ++l) {
      const int jl = w.joint[l];
      double d;
      // a joint on the universe moves its whole tree rigidly with its velocities (V_p(l) = 0):
      // phi's gradient does not change along it, exactly (the terms below cancel to round-off only,
      // and the variational step skips such directions on exact zeros)
      if (model.parents[jl] == 0) d = 0.0;
      else if (jl == jk) d = w.xi[l].dot(w.A0[k]) - w.u[l].dot(w.w[k]);
      else if (jl < jk && jk <= w.last[jl]) d = w.xi[l].dot(w.A[k]) + w.u[l].dot(w.B[k]);  // l's joint supports k's
      else if (jk < jl && jl <= w.last[jk]) d = w.u[k].dot(w.B[l]);                      // k's joint supports l's
      else d = 0.0;
      H(k, l) = -d;
    }
  }
}

}  // namespace dyn
}  // namespace geoddp
