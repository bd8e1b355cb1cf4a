// A contact schedule's rollouts, node costs and first-order expansion over the whole horizon (see
// contact.hpp): the twin of geoddp.problem.legged.ContactProblem's trajectory, rollout_policy,
// node_costs and linearise(order=1). Compiled inside dynamics/contact_algorithms.cpp.
#include <pinocchio/algorithm/joint-configuration.hpp>

#include <memory>
#include <vector>

#include "dynamics/contact.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

double contact_step(const ContactSetup& s, ContactWork& w, int k, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                    const Eigen::VectorXd& u, bool derivatives, ContactEval& ev, Eigen::VectorXd& g, RowMat& Hs) {
  const ContactNode& node = s.nodes[(size_t)k];
  if (node.impulse) impulse_node(s, w, node, q, v, derivatives, ev);
  else contact_node(s, w, node, q, v, u, derivatives, ev);
  return contact_node_cost(s, w, k, q, v, u, &ev, derivatives, g, Hs);
}

void contact_rollout(const ContactSetup& s, const double* U, double* Q, double* V, double* costs) {
  const pinocchio::Model& m = *s.model;
  const int H = s.horizon(), nq = m.nq, nv = m.nv, nu = s.nu();
  ContactWork w(m);
  ContactEval ev;
  Eigen::VectorXd g;
  RowMat Hs;
  CMatMap Um(U, H, nu);
  MatMap Qm(Q, H + 1, nq), Vm(V, H + 1, nv);
  Qm.row(0) = s.q0.transpose();
  Vm.row(0) = s.v0.transpose();
  Eigen::VectorXd q(nq), v(nv), u(nu);
  for (int k = 0; k < H; ++k) {
    q = Qm.row(k).transpose();
    v = Vm.row(k).transpose();
    if (s.nodes[(size_t)k].impulse) u.setZero();
    else u = Um.row(k).transpose();
    costs[k] = contact_step(s, w, k, q, v, u, false, ev, g, Hs);
    Qm.row(k + 1) = ev.q_next.transpose();
    Vm.row(k + 1) = ev.v_next.transpose();
  }
  q = Qm.row(H).transpose();
  v = Vm.row(H).transpose();
  costs[H] = contact_node_cost(s, w, H, q, v, Eigen::VectorXd::Zero(nu), nullptr, false, g, Hs);
}

bool contact_rollout_closed_loop(const ContactSetup& s, const double* Qbar, const double* Vbar, const double* Ubar,
                                 const double* kff, const double* K, double gamma, double* Qout, double* Vout,
                                 double* Uout, double* costs) {
  const pinocchio::Model& m = *s.model;
  const int H = s.horizon(), nq = m.nq, nv = m.nv, nu = s.nu(), n = 2 * nv;
  ContactWork w(m);
  ContactEval ev;
  Eigen::VectorXd g;
  RowMat Hs;
  CMatMap Qb(Qbar, H + 1, nq), Vb(Vbar, H + 1, nv), Ub(Ubar, H, nu), kf(kff, H, nu);
  MatMap Qo(Qout, H + 1, nq), Vo(Vout, H + 1, nv), Uo(Uout, H, nu);
  Qo.row(0) = s.q0.transpose();
  Vo.row(0) = s.v0.transpose();
  Eigen::VectorXd q(nq), v(nv), u(nu), zeta(n), dq(nv), qb(nq);
  for (int k = 0; k < H; ++k) {
    q = Qo.row(k).transpose();
    v = Vo.row(k).transpose();
    if (s.nodes[(size_t)k].impulse) {
      u.setZero();
    } else {
      qb = Qb.row(k).transpose();
      libpin::difference(m, qb, q, dq);
      zeta.head(nv) = dq;
      zeta.tail(nv) = v - Vb.row(k).transpose();
      CMatMap Kk(K + (size_t)k * nu * n, nu, n);
      u = Ub.row(k).transpose() - gamma * kf.row(k).transpose() - Kk * zeta;
    }
    Uo.row(k) = u.transpose();
    costs[k] = contact_step(s, w, k, q, v, u, false, ev, g, Hs);
    if (!ev.q_next.allFinite() || !ev.v_next.allFinite()) return false;
    Qo.row(k + 1) = ev.q_next.transpose();
    Vo.row(k + 1) = ev.v_next.transpose();
  }
  q = Qo.row(H).transpose();
  v = Vo.row(H).transpose();
  costs[H] = contact_node_cost(s, w, H, q, v, Eigen::VectorXd::Zero(nu), nullptr, false, g, Hs);
  return true;
}

namespace {
// The first-order kernels' per-worker work: the node's own (kept between calls, WorkCache).
struct NoExtra {
  ContactWork node;
  explicit NoExtra(const ContactSetup& s) : node(*s.model) {}
  ContactWork& node_work() { return node; }
};
}  // namespace

void contact_costs(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                   double* costs) {
  for_each_node<NoExtra>(
      s, Q, V, U, threads, false, costs, [](int, const Eigen::VectorXd&, const Eigen::VectorXd&, const ContactEval&,
                                           const Eigen::VectorXd&, RowMat&, NoExtra&) {},
      [](const Eigen::VectorXd&, const Eigen::VectorXd&, const Eigen::VectorXd&, RowMat&, NoExtra&) {});
}

void store_node_expansion(int k, int n, int nu, const ContactEval& ev, const Eigen::VectorXd& g, const RowMat& Hs,
                          double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu) {
  MatMap(Phi + (size_t)k * n * n, n, n) = ev.Fz.leftCols(n);
  MatMap(B + (size_t)k * n * nu, n, nu) = ev.Fz.rightCols(nu);
  VecMap(lx + (size_t)k * n, n) = g.head(n);
  VecMap(lu + (size_t)k * nu, nu) = g.tail(nu);
  MatMap(lxx + (size_t)k * n * n, n, n) = Hs.topLeftCorner(n, n);
  MatMap(lux + (size_t)k * nu * n, nu, n) = Hs.bottomLeftCorner(nu, n);
  MatMap(luu + (size_t)k * nu * nu, nu, nu) = Hs.bottomRightCorner(nu, nu);
}

void store_terminal_expansion(int n, const Eigen::VectorXd& g, const RowMat& Hs, double* lfx, double* lfxx) {
  VecMap(lfx, n) = g.head(n);
  MatMap(lfxx, n, n) = Hs.topLeftCorner(n, n);
}

void contact_linearise(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                       double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu,
                       double* lfx, double* lfxx, double* costs) {
  const int n = 2 * s.model->nv, nu = s.nu();
  for_each_node<NoExtra>(
      s, Q, V, U, threads, true, costs,
      [&](int k, const Eigen::VectorXd&, const Eigen::VectorXd&, const ContactEval& ev, const Eigen::VectorXd& g,
          RowMat& Hs, NoExtra&) { store_node_expansion(k, n, nu, ev, g, Hs, Phi, B, lx, lu, lxx, lux, luu); },
      [&](const Eigen::VectorXd&, const Eigen::VectorXd&, const Eigen::VectorXd& g, RowMat& Hs, NoExtra&) {
        store_terminal_expansion(n, g, Hs, lfx, lfxx);
      });
}

}  // namespace dyn
}  // namespace geoddp
