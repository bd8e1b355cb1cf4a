// The rollouts of a multibody model (see trajectory.hpp): open loop and the forward pass under the feedback
// law, each step by the Setup's integrator (euler.hpp, dynamics/rkmk4.hpp, dynamics/variational.hpp).
// Compiled inside dynamics/core_algorithms.cpp.
#include "dynamics/trajectory.hpp"

#include <pinocchio/algorithm/joint-configuration.hpp>

#include <cmath>
#include <memory>
#include <vector>

#include "dynamics/euler.hpp"
#include "dynamics/rkmk4.hpp"
#include "dynamics/variational.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {

// The variational step's model and scratch, for a sequential pass (rollout, forward pass).
struct SequentialVariational {
  VariationalModel vm;
  VariationalWork w;
  explicit SequentialVariational(const Setup& s) : vm(*s.model, s.H, s.m, s.dt), w(vm) {}
};
static std::unique_ptr<SequentialVariational> variational_for(const Setup& s) {
  return s.integrator == VARIATIONAL ? std::make_unique<SequentialVariational>(s) : nullptr;
}

static inline bool all_finite(const Eigen::VectorXd& x) { return x.allFinite(); }

// One step of the Setup's integrator (the oracle's OracleMultibody._step, tests/oracle_multibody.py).
static void step(const Setup& s, pinocchio::Data& data, const std::vector<JointGroup>& groups,
                 SequentialVariational* var, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                 const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1) {
  const Model& model = *s.model;
  if (s.integrator == RK4) {
    rk4_step(model, data, groups, q, v, tau, s.dt, q1, v1);
    return;
  }
  if (var != nullptr) {
    variational_step(var->vm, var->w, q, v, tau, q1, v1);
    return;
  }
  euler_step(s, data, q, v, tau, q1, v1);
}

void rollout(const Setup& s, const double* q0, const double* v0, const double* U, int N, double* Q, double* V) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m;
  const std::vector<JointGroup> groups = joint_groups(model);
  const std::unique_ptr<SequentialVariational> var = variational_for(s);
  pinocchio::Data data(model);
  CMatMap Hm(s.H, nv, m);
  MatMap Qm(Q, N + 1, nq), Vm(V, N + 1, nv);
  CMatMap Um(U, N, m);
  Qm.row(0) = CVecMap(q0, nq).transpose();
  Vm.row(0) = CVecMap(v0, nv).transpose();
  Eigen::VectorXd q(nq), v(nv), q1(nq), v1(nv), tau(nv);
  for (int k = 0; k < N; ++k) {
    q = Qm.row(k).transpose();
    v = Vm.row(k).transpose();
    tau = Hm * Um.row(k).transpose();
    step(s, data, groups, var.get(), q, v, tau, q1, v1);
    Qm.row(k + 1) = q1.transpose();
    Vm.row(k + 1) = v1.transpose();
  }
}

// difference(q0, q1) with exact SO(2) entries (geoddp.lie.product.difference).
static void difference(const Model& model, const std::vector<JointGroup>& groups, const Eigen::VectorXd& q0,
                       const Eigen::VectorXd& q1, Eigen::VectorXd& d) {
  libpin::difference(model, q0, q1, d);
  for (const JointGroup& g : groups) {
    if (g.kind != SO2) continue;
    const double c0 = q0[g.idx_q], s0 = q0[g.idx_q + 1], c1 = q1[g.idx_q], s1 = q1[g.idx_q + 1];
    d[g.idx_v] = std::atan2(c0 * s1 - s0 * c1, c0 * c1 + s0 * s1);
  }
}

bool rollout_closed_loop(const Setup& s, const double* q0, const double* v0, const double* Qbar,
                         const double* Vbar, const double* Ubar, const double* kff, const double* K,
                         double gamma, int N, double* Qout, double* Vout, double* Uout,
                         const double* lower, const double* upper) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, n = 2 * nv;
  const std::vector<JointGroup> groups = joint_groups(model);
  const std::unique_ptr<SequentialVariational> var = variational_for(s);
  pinocchio::Data data(model);
  CMatMap Hm(s.H, nv, m);
  CMatMap Qb(Qbar, N + 1, nq), Vb(Vbar, N + 1, nv), Ub(Ubar, N, m), kf(kff, N, m);
  MatMap Qo(Qout, N + 1, nq), Vo(Vout, N + 1, nv), Uo(Uout, N, m);
  Qo.row(0) = CVecMap(q0, nq).transpose();
  Vo.row(0) = CVecMap(v0, nv).transpose();
  Eigen::VectorXd q(nq), v(nv), q1(nq), v1(nv), tau(nv), zeta(n), dq(nv), u(m), qb(nq);
  for (int k = 0; k < N; ++k) {
    q = Qo.row(k).transpose();
    v = Vo.row(k).transpose();
    qb = Qb.row(k).transpose();
    difference(model, groups, qb, q, dq);
    zeta.head(nv) = dq;
    zeta.tail(nv) = v - Vb.row(k).transpose();
    CMatMap Kk(K + (size_t)k * m * n, m, n);
    u = Ub.row(k).transpose() - gamma * kf.row(k).transpose() - Kk * zeta;
    if (lower != nullptr) {
      for (int a = 0; a < m; ++a) {  // explicit comparisons: a NaN input stays NaN
        const double lo = lower[(size_t)k * m + a], hi = upper[(size_t)k * m + a];
        if (u[a] < lo) u[a] = lo;
        else if (u[a] > hi) u[a] = hi;
      }
    }
    Uo.row(k) = u.transpose();
    tau = Hm * u;
    try {
      step(s, data, groups, var.get(), q, v, tau, q1, v1);
    } catch (const StepNotConverged&) {
      return false;  // a trial whose implicit step has no solution: rejected like a non-finite one
    }
    if (!all_finite(q1) || !all_finite(v1)) return false;
    Qo.row(k + 1) = q1.transpose();
    Vo.row(k + 1) = v1.transpose();
  }
  return true;
}

}  // namespace dyn
}  // namespace geoddp
