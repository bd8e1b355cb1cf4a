// RNEA's second derivatives contracted with mu by a spatial-vector recursion (rigid_body/rnea_hessian.hpp).
// Compiled inside dynamics/core_algorithms.cpp.
#include "rigid_body/rnea_hessian.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/spatial.hpp"

#include <pinocchio/algorithm/jacobian.hpp>

#include <algorithm>

namespace geoddp {
namespace dyn {

namespace {

typedef RneaHessianWork::V6 V6;
typedef RneaHessianWork::M6 M6;

// a x b of motions, a x* f of a motion on a force
inline V6 mcross(const V6& a, const V6& b) { return spatial::motion_cross(a, b); }
inline V6 fcross(const V6& a, const V6& f) { return spatial::force_cross(a, f); }

// -((V x)^T I + I (V x)): the symmetric 6 x 6 matrix with <m, N n> = -<V x m, I n> - <m, I (V x n)>
// for the motion V = [v; w], whose cross-product matrix is X = [[w^, v^], [0, w^]]: I X from the
// skew blocks' columns (two axpys each) instead of a 6 x 6 product.
inline M6 bilinear_composite(const M6& I, const V6& V) {
  const double v0 = V[0], v1 = V[1], v2 = V[2], w0 = V[3], w1 = V[4], w2 = V[5];
  const auto L = I.leftCols<3>();
  const auto R = I.rightCols<3>();
  M6 IX;
  IX.col(0) = w2 * L.col(1) - w1 * L.col(2);
  IX.col(1) = w0 * L.col(2) - w2 * L.col(0);
  IX.col(2) = w1 * L.col(0) - w0 * L.col(1);
  IX.col(3) = v2 * L.col(1) - v1 * L.col(2) + w2 * R.col(1) - w1 * R.col(2);
  IX.col(4) = v0 * L.col(2) - v2 * L.col(0) + w0 * R.col(2) - w2 * R.col(0);
  IX.col(5) = v1 * L.col(0) - v0 * L.col(1) + w1 * R.col(0) - w0 * R.col(1);
  return -(IX + IX.transpose());
}

// One node's mu-free terms (rigid_body/rnea_hessian.hpp): per joint j at 132 j, per dof k at 132 nj + 42 k.
struct NodeView {
  double* p;
  int nj;
  Eigen::Map<V6> V(int j) const { return Eigen::Map<V6>(p + 132 * (size_t)j); }
  Eigen::Map<V6> A(int j) const { return Eigen::Map<V6>(p + 132 * (size_t)j + 6); }
  Eigen::Map<M6> I(int j) const { return Eigen::Map<M6>(p + 132 * (size_t)j + 12); }
  Eigen::Map<V6> F(int j) const { return Eigen::Map<V6>(p + 132 * (size_t)j + 48); }
  Eigen::Map<V6> H(int j) const { return Eigen::Map<V6>(p + 132 * (size_t)j + 54); }
  Eigen::Map<M6> Ic(int j) const { return Eigen::Map<M6>(p + 132 * (size_t)j + 60); }
  Eigen::Map<M6> N(int j) const { return Eigen::Map<M6>(p + 132 * (size_t)j + 96); }
  double* dof(int k) const { return p + 132 * (size_t)nj + 42 * (size_t)k; }
  Eigen::Map<V6> xi(int k) const { return Eigen::Map<V6>(dof(k)); }
  Eigen::Map<V6> u(int k) const { return Eigen::Map<V6>(dof(k) + 6); }
  Eigen::Map<V6> sp(int k) const { return Eigen::Map<V6>(dof(k) + 12); }
  Eigen::Map<V6> z(int k) const { return Eigen::Map<V6>(dof(k) + 18); }
  Eigen::Map<V6> Fm(int k) const { return Eigen::Map<V6>(dof(k) + 24); }
  Eigen::Map<V6> dF(int k) const { return Eigen::Map<V6>(dof(k) + 30); }
  Eigen::Map<V6> dFv(int k) const { return Eigen::Map<V6>(dof(k) + 36); }
};

}  // namespace

RneaHessianWork::RneaHessianWork(const pinocchio::Model& model)
    : TreeDofs(model), data(model), W(model.njoints), P(model.njoints), Y(model.njoints), NW(model.njoints),
      node(rnea_hessian_node_size(model)) {
  for (Cols* c : {&t, &dP, &dY, &dYv, &e1, &e12, &Ict, &nw}) c->setZero(6, model.nv);
}

void rnea_hessian_node(const pinocchio::Model& model, RneaHessianWork& w, const double* q_, const double* v_,
                       const double* a_, double* node) {
  const int nj = model.njoints, nv = model.nv;
  const Eigen::Map<const Eigen::VectorXd> q(q_, model.nq), v(v_, nv), a(a_, nv);
  pinocchio::Data& data = w.data;
  libpin::computeJointJacobians(model, data, q);
  const pinocchio::Data::Matrix6x& X = data.J;  // world columns xi
  const NodeView n{node, nj};
  std::fill(node, node + 132, 0.0);  // the universe: V = 0, no inertia, A = -g
  n.A(0) = -model.gravity.toVector();
  // forward: V, A, the world inertia, momentum and force of each body
  for (int j = 1; j < nj; ++j) {
    const int p = model.parents[j], i0 = model.idx_vs[j], m = model.nvs[j];
    const auto Xj = X.middleCols(i0, m);
    const V6 Vp = n.V(p), Vj = Vp + Xj * v.segment(i0, m);
    V6 Aj = n.A(p) + mcross(Vp, Vj - Vp);
    Aj.noalias() += Xj * a.segment(i0, m);
    n.V(j) = Vj;
    n.A(j) = Aj;
    const M6 I = data.oMi[j].act(model.inertias[j]).matrix();
    n.I(j) = I;
    const V6 h = I * Vj;
    n.H(j) = h;
    n.F(j) = I * Aj + fcross(Vj, h);
    n.Ic(j) = I;
    n.N(j) = bilinear_composite(I, Vj);
  }
  // backward: subtree composites
  for (int j = nj - 1; j > 1; --j) {
    const int p = model.parents[j];
    if (p == 0) continue;
    n.F(p) += n.F(j);
    n.H(p) += n.H(j);
    n.Ic(p) += n.Ic(j);
    n.N(p) += n.N(j);
  }
  for (int k = 0; k < nv; ++k) {
    const int J = w.joint[k], p = model.parents[J];
    const V6 xk = X.col(k), Vp = n.V(p), HJ = n.H(J);
    const M6 Ic = n.Ic(J), N = n.N(J);
    const V6 u = mcross(xk, Vp);
    const V6 sp = mcross(xk, n.A(p)) - mcross(u, Vp);
    const V6 z = mcross(xk, n.V(J) + Vp);
    n.xi(k) = xk;
    n.u(k) = u;
    n.sp(k) = sp;
    n.z(k) = z;
    n.Fm(k).noalias() = Ic * xk;
    // the composite force's rates along dof k (rigid turn plus deviation), along q and along v
    V6 dF = fcross(xk, n.F(J)) - fcross(u, HJ);
    dF.noalias() -= Ic * sp;
    dF.noalias() -= N * u;
    n.dF(k) = dF;
    V6 dFv = fcross(xk, HJ);
    dFv.noalias() += N * xk;
    dFv.noalias() -= Ic * z;
    n.dFv(k) = dFv;
  }
}

void rnea_hessian_contract(const pinocchio::Model& model, RneaHessianWork& w, const double* node_, const double* mu_,
                           double* Hqq, double* Hvv, double* Hqv, double* Dm) {
  const int nj = model.njoints, nv = model.nv;
  const size_t nn = (size_t)nv * nv;
  const Eigen::Map<const Eigen::VectorXd> mu(mu_, nv);
  const NodeView n{const_cast<double*>(node_), nj};
  // forward: mu-velocities W and the per-body P = I W, Y = V x* I W - W x* I V + I (W x V), NW
  w.W[0].setZero();
  for (int j = 1; j < nj; ++j) {
    const int p = model.parents[j], i0 = model.idx_vs[j];
    V6 Wj = w.W[p];
    for (int d = 0; d < model.nvs[j]; ++d) Wj += mu[i0 + d] * n.xi(i0 + d);
    w.W[j] = Wj;
    const M6 I = n.I(j);
    const V6 Vj = n.V(j);
    const V6 IW = I * Wj;
    w.P[j] = IW;
    w.Y[j] = fcross(Vj, IW) - fcross(Wj, I * Vj) + I * mcross(Wj, Vj);
    w.NW[j] = bilinear_composite(I, Wj);
  }
  for (int j = nj - 1; j > 1; --j) {
    const int p = model.parents[j];
    if (p == 0) continue;
    w.P[p] += w.P[j];
    w.Y[p] += w.Y[j];
    w.NW[p] += w.NW[j];
  }
  // per dof k (joint J, parent p): the pair terms' vectors that read mu (rigid_body/rnea_hessian.hpp)
  for (int k = 0; k < nv; ++k) {
    const int J = w.joint[k], p = model.parents[J];
    const V6 xk = n.xi(k), u = n.u(k), Vp = n.V(p), HJ = n.H(J), PJ = w.P[J];
    const M6& NW = w.NW[J];
    const V6 t = mcross(xk, w.W[p]);
    const V6 b = fcross(xk, PJ), xY = fcross(xk, w.Y[J]), uP = fcross(u, PJ);
    V6 Ict, nw;
    Ict.noalias() = n.Ic(J) * t;
    nw.noalias() = NW * xk;
    V6 g = fcross(t, HJ);
    g.noalias() -= n.N(J) * t;
    g.noalias() += NW * u;
    w.t.col(k) = t;
    w.Ict.col(k) = Ict;
    w.nw.col(k) = nw;
    w.dP.col(k) = b - Ict;
    w.dYv.col(k) = b - nw;
    w.dY.col(k) = xY - uP + g;
    const V6 e1 = g + uP;
    const V6 e2 = fcross(Vp, b) - fcross(xk, fcross(Vp, PJ)) - uP + xY;
    w.e1.col(k) = e1;
    w.e12.col(k) = e1 + e2;  // cu_k = -(e1_k + e2_k)
  }
  std::fill(Hqq, Hqq + nn, 0.0);
  std::fill(Hvv, Hvv + nn, 0.0);
  std::fill(Hqv, Hqv + nn, 0.0);
  std::fill(Dm, Dm + nn, 0.0);
  // pairs (k, l), entries at k + nv l
  for (int k = 0; k < nv; ++k) {
    const int J = w.joint[k];
    const V6 dFk = n.dF(k), dPk = w.dP.col(k), e12k = w.e12.col(k), Fmk = n.Fm(k);
    // l's joint L strictly supports k's (strict) or is k's own: Hqv = <xi_l, qv_x> + <z_l, qv_z>,
    // Hvv = <xi_l, vv> with, strictly, e1 + e2, Ict - b = -dP and b - nw = dYv, else e1, Ict, -nw
    const V6 e1k = w.e1.col(k), Ictk = w.Ict.col(k), mnwk = -w.nw.col(k), mdPk = -dPk, dYvk = w.dYv.col(k);
    auto upper = [&](int l, const V6& qv_x, const V6& qv_z, const V6& vv) {
      const size_t e = (size_t)k + (size_t)nv * l;
      const double* x = n.dof(l);  // xi, u, sp, z
      const Eigen::Map<const V6> xl(x), ul(x + 6), spl(x + 12), zl(x + 18);
      const V6 tl = w.t.col(l);
      Hqq[e] = -dFk.dot(tl) - dPk.dot(spl) - e12k.dot(ul);  // + <cu_k, u_l>
      Dm[e] = -Fmk.dot(tl);
      Hqv[e] = xl.dot(qv_x) + zl.dot(qv_z);
      Hvv[e] = xl.dot(vv);
    };
    for (const auto& run : w.above[J])
      for (int l = run.first; l < run.second; ++l) upper(l, e12k, mdPk, dYvk);
    for (int l = w.first_dof[J]; l < w.own_end[J]; ++l) upper(l, e1k, Ictk, mnwk);
    // k's joint supports l's strictly: the dofs of J's subtree after its own
    const V6 xk = n.xi(k), tk = w.t.col(k), spk = n.sp(k), uk = n.u(k);
    for (int l = w.own_end[J]; l < w.end_dof[J]; ++l) {
      const size_t e = (size_t)k + (size_t)nv * l;
      const V6 dPl = w.dP.col(l), dYvl = w.dYv.col(l);
      Hqq[e] = -tk.dot(n.dF(l)) - spk.dot(dPl) - uk.dot(w.dY.col(l));
      Dm[e] = xk.dot(dPl);
      Hqv[e] = -tk.dot(n.dFv(l)) - uk.dot(dYvl);
      Hvv[e] = xk.dot(dYvl);
    }
  }
}

void rnea_hessian_point_force(const pinocchio::Model& model, const TreeDofs& tree, const double* node_, int joint,
                              const double* p_, const double* lambda, const double* mu, double* Hqq) {
  const int nv = model.nv;
  const NodeView n{const_cast<double*>(node_), model.njoints};
  const Eigen::Map<const Eigen::Vector3d> p(p_);
  // the point mass's spatial inertia on a motion x = [v; w]: [pv; p x pv], pv = v + w x p
  auto inertia = [&](const V6& x) {
    V6 out;
    const Eigen::Vector3d pv = x.head<3>() + x.tail<3>().cross(p);
    out.head<3>() = pv;
    out.tail<3>() = p.cross(pv);
    return out;
  };
  V6 A0;
  A0 << lambda[0], lambda[1], lambda[2], 0.0, 0.0, 0.0;
  const V6 f = inertia(A0);
  // the chain's dofs, root first (a joint's dofs are consecutive)
  thread_local std::vector<int> chain;
  thread_local Eigen::Matrix<double, 6, Eigen::Dynamic> t, sp, dF, dP;
  chain.clear();
  for (const auto& run : tree.above[joint])
    for (int l = run.first; l < run.second; ++l) chain.push_back(l);
  for (int l = tree.first_dof[joint]; l < tree.own_end[joint]; ++l) chain.push_back(l);
  const int m = (int)chain.size();
  for (auto* c : {&t, &sp, &dF, &dP}) c->resize(6, m);
  // t_k = xi_k x W_p (W_p: the mu-velocity of k's joint's parent), then P = I_p W at the foot's joint
  V6 W = V6::Zero(), Wp = V6::Zero();
  for (int i = 0, cur = -1; i < m; ++i) {
    const int k = chain[(size_t)i];
    if (tree.joint[(size_t)k] != cur) {
      Wp = W;
      cur = tree.joint[(size_t)k];
    }
    W += mu[k] * n.xi(k);
    t.col(i) = mcross(n.xi(k), Wp);
  }
  const V6 P = inertia(W);
  for (int i = 0; i < m; ++i) {
    const V6 xk = n.xi(chain[(size_t)i]);
    sp.col(i) = mcross(xk, A0);
    dF.col(i) = fcross(xk, f) - inertia(sp.col(i));
    dP.col(i) = fcross(xk, P) - inertia(t.col(i));
  }
  // pairs: l's joint supports k's or is it (j < i, or the same joint) as the recursion's first
  // case, k's strictly supports l's as its last
  for (int i = 0; i < m; ++i) {
    const int k = chain[(size_t)i];
    for (int j = 0; j < m; ++j) {
      const int l = chain[(size_t)j];
      const bool above = j < i || tree.joint[(size_t)l] == tree.joint[(size_t)k];
      Hqq[(size_t)k + (size_t)nv * l] += above ? -dF.col(i).dot(t.col(j)) - dP.col(i).dot(sp.col(j))
                                               : -t.col(i).dot(dF.col(j)) - sp.col(i).dot(dP.col(j));
    }
  }
}

void rnea_hessian(const pinocchio::Model& model, RneaHessianWork& w, const double* q, const double* v,
                  const double* a, const double* mu, double* Hqq, double* Hvv, double* Hqv, double* Dm) {
  rnea_hessian_node(model, w, q, v, a, w.node.data());
  rnea_hessian_contract(model, w, w.node.data(), mu, Hqq, Hvv, Hqv, Dm);
}

}  // namespace dyn
}  // namespace geoddp
