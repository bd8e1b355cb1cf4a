// The kinetic energy's configuration Hessian, its gradient and the tensors dM/dq and d/dq D(q, y) by
// spatial-vector recursions (rigid_body/kinetic_hessian.hpp).
// Compiled inside dynamics/core_algorithms.cpp.
#include "rigid_body/kinetic_hessian.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/spatial.hpp"

#include <pinocchio/algorithm/jacobian.hpp>

#include <algorithm>

namespace geoddp {
namespace dyn {

KineticHessianWork::KineticHessianWork(const pinocchio::Model& model)
    : TreeDofs(model), V(model.njoints), h(model.njoints), Ic(model.njoints), xi(model.nv), u(model.nv),
      A(model.nv), A0(model.nv), B(model.nv), w(model.nv), U(6, model.nv), Fm(6, model.nv), Bm(6, model.nv),
      Icm(model.njoints), Iw(model.njoints) {}

namespace {

// The world-frame terms every function here starts from: data.oMi and the columns data.J, the body
// velocities w.V, and the subtrees' momenta w.h and composite inertias w.Ic. The configuration's
// part (kinematics, w.Iw, w.Ic) is kept from the previous call at the same q and Data
// (KineticHessianWork::q_kin).
void subtree_terms(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                   const Eigen::VectorXd& q, const Eigen::VectorXd& y) {
  const int nj = model.njoints;
  if (!(w.data_kin == &data && w.q_kin.size() == q.size() && w.q_kin == q)) {
    libpin::computeJointJacobians(model, data, q);
    // world inertias, and the subtrees' composites (backward)
    for (int j = 1; j < nj; ++j) {
      w.Iw[j] = data.oMi[j].act(model.inertias[j]);
      w.Ic[j] = w.Iw[j];
    }
    for (int j = nj - 1; j > 1; --j) {
      const int p = model.parents[j];
      if (p != 0) w.Ic[p] += w.Ic[j];
    }
    w.q_kin = q;
    w.data_kin = &data;
  }
  // forward: world body velocities V_j = V_parent + sum of the joint's columns times y
  w.V[0].setZero();
  for (int j = 1; j < nj; ++j) {
    const int i0 = model.idx_vs[j], n = model.nvs[j];
    w.V[j] = w.V[model.parents[j]];
    w.V[j].toVector().noalias() += data.J.middleCols(i0, n) * y.segment(i0, n);
  }
  // backward: subtree momenta (world frame)
  for (int j = 1; j < nj; ++j) w.h[j] = w.Iw[j] * w.V[j];
  for (int j = nj - 1; j > 1; --j) {
    const int p = model.parents[j];
    if (p != 0) w.h[p] += w.h[j];
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
  // per dof: the pair terms' factors (rigid_body/kinetic_hessian.hpp)
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

namespace {

typedef spatial::V6 V6;
using spatial::force_cross;
using spatial::motion_cross;

// out[i * stride] = scale cols(i) . f (6 x nv `cols`) for the dofs i of `runs` within [lo, hi):
// fixed-size 6-vector dot products (a dynamic-size product per run would dispatch and allocate
// more than it multiplies).
template <class Runs>
inline void dots(const Eigen::Matrix<double, 6, Eigen::Dynamic>& cols, const Runs& runs, int lo, int hi, const V6& f,
                 double scale, double* out, int stride) {
  for (const auto& r : runs) {
    const int b = std::max(r.first, lo), e = std::min(r.second, hi);
    for (int i = b; i < e; ++i) out[(size_t)i * stride] = scale * cols.col(i).dot(f);
  }
}

// out[i] = cols(i) . f for the dofs i in [b, e).
inline void dots(const Eigen::Matrix<double, 6, Eigen::Dynamic>& cols, int b, int e, const V6& f, double* out) {
  for (int i = b; i < e; ++i) out[i] = cols.col(i).dot(f);
}

// After subtree_terms: per joint Ic as a 6 x 6 matrix (w.Icm), and per dof, as the columns of
// w.U, w.Fm, w.Bm: u_k = xi_k x V_p(k), F_k = Ic_k xi_k and B_k = xi_k x* h_k - Ic_k u_k (what
// mass_velocity_derivative and mass_tensors read).
void dof_terms(const pinocchio::Model& model, const pinocchio::Data& data, KineticHessianWork& w) {
  for (int j = 1; j < model.njoints; ++j) w.Icm[j] = w.Ic[j].matrix();
  const pinocchio::Data::Matrix6x& X = data.J;
  for (int k = 0; k < model.nv; ++k) {
    const int jk = w.joint[k];
    const V6 xi = X.col(k);
    w.U.col(k) = motion_cross(xi, w.V[model.parents[jk]].toVector());
    w.Fm.col(k).noalias() = w.Icm[jk] * xi;
    w.Bm.col(k) = force_cross(xi, w.h[jk].toVector());
    w.Bm.col(k).noalias() -= w.Icm[jk] * w.U.col(k);
  }
}

}  // namespace

void mass_velocity_derivative(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                              const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::MatrixXd& D) {
  const int nv = model.nv;
  subtree_terms(model, data, w, q, y);
  dof_terms(model, data, w);
  const pinocchio::Data::Matrix6x& X = data.J;  // the world columns xi (subtree_terms)
  D.setZero(nv, nv);
  for (int k = 0; k < nv; ++k) {
    const int jk = w.joint[k];
    // J_k <= J_i (k's subtree, its own joint included): -F_i . u_k; zero on a joint on the universe
    if (model.parents[jk] != 0) {
      const V6 uk = w.U.col(k);
      for (int i = w.first_dof[jk]; i < w.end_dof[jk]; ++i) D(i, k) = -w.Fm.col(i).dot(uk);
    }
    // J_i < J_k (the joints strictly above k's): xi_i . B_k
    const V6 Bk = w.Bm.col(k);
    for (const auto& run : w.above[jk])
      for (int i = run.first; i < run.second; ++i) D(i, k) = X.col(i).dot(Bk);
  }
}

void mass_tensors(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                  const Eigen::VectorXd& q, const Eigen::VectorXd& y, double* dM, double* T) {
  const int nv = model.nv;
  const size_t nn = (size_t)nv * nv;
  subtree_terms(model, data, w, q, y);
  dof_terms(model, data, w);
  const pinocchio::Data::Matrix6x& X = data.J;  // the world columns xi (subtree_terms)
  std::fill(dM, dM + nn * nv, 0.0);
  std::fill(T, T + nn * nv, 0.0);
  // page k: the header comment's cases, by where j (or b) sits: in k's subtree, or strictly above
  // k (`up`, runs of dofs root first, in which a dof's index orders its joint)
  for (int k = 0; k < nv; ++k) {
    const int jk = w.joint[k], k0 = w.first_dof[jk], k1 = w.end_dof[jk];
    // A joint on the universe turns the whole tree (u_k = 0, nothing above it): its pages are zero.
    if (model.parents[jk] == 0) continue;
    double* dMk = dM + k * nn;
    double* Tk = T + k * nn;
    const V6 xk = X.col(k), uk = w.U.col(k);
    const Eigen::Matrix<double, 6, 6>& Ick = w.Icm[jk];
    const auto& up = w.above[jk];
    for (int j = k0; j < k1; ++j) {  // J_k <= J_j
      const int jj = w.joint[j];
      const V6 xj = X.col(j);
      const V6 fj = force_cross(xk, w.Fm.col(j));
      dots(X, up, 0, nv, fj, 1.0, dMk + nv * j, 1);  // dM: J_a < J_k <= J_j, and its mirror
      dots(X, up, 0, nv, fj, 1.0, dMk + j, nv);
      const V6 m = motion_cross(xj, uk);
      const int i0 = w.first_dof[jj], i1 = w.end_dof[jj];  // J_j <= J_i
      dots(w.Fm, i0, i1, m, Tk + nv * j);
      const auto& above_j = w.above[jj];
      if (above_j.empty()) continue;  // a guard: J_k, hence J_j, has a joint above it here
      const Eigen::Matrix<double, 6, 6>& Icj = w.Icm[jj];
      V6 C = Icj * m;
      C -= force_cross(xj, Icj * uk);
      dots(X, above_j, k0, nv, C, 1.0, Tk + nv * j, 1);  // J_i < J_j, J_k <= J_i
      if (above_j.front().first >= k0) continue;
      const V6 C2 = force_cross(xk, w.Bm.col(j)) + C;
      dots(X, above_j, 0, k0, C2, 1.0, Tk + nv * j, 1);  // J_i < J_k
    }
    for (const auto& run : up) {
      for (int j = run.first; j < run.second; ++j) {  // J_j < J_k
        const int jj = w.joint[j], j0 = w.first_dof[jj];
        const V6 xj = X.col(j), uj = w.U.col(j);
        V6 fM = force_cross(xk, Ick * xj);
        fM.noalias() -= Ick * motion_cross(xk, xj);
        dots(X, up, 0, j + 1, fM, 1.0, dMk + nv * j, 1);  // dM: J_a <= J_j < J_k (a <= j within a joint)
        dots(X, up, 0, j + 1, fM, 1.0, dMk + j, nv);
        // j on a joint on the universe: u_j = 0 and nothing is above it, so its T entries are zero
        if (model.parents[jj] == 0) continue;
        const V6 m = motion_cross(xk, uj);
        dots(w.Fm, k0, k1, m, Tk + nv * j);  // J_k <= J_i
        V6 E = force_cross(xk, Ick * uj);
        E.noalias() -= Ick * m;
        dots(X, up, j0, nv, E, -1.0, Tk + nv * j, 1);  // J_j <= J_i < J_k
        const V6 f2 = force_cross(xj, w.Bm.col(k)) - E;
        dots(X, w.above[jj], 0, nv, f2, 1.0, Tk + nv * j, 1);  // J_i < J_j
      }
    }
  }
}

}  // namespace dyn
}  // namespace geoddp
