// Multibody dynamics kernels (see dynamics.hpp). Compiled in one translation unit with rkmk4.cpp
// and variational.cpp (core_algorithms.cpp), which holds every Pinocchio template instantiation
// the core needs, to keep the compile time small.
#include "dynamics.hpp"
#include "aba_compiled.hpp"
#include "small_gemm.hpp"

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea-second-order-derivatives.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/spatial.hpp>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "lie.hpp"
#include "one_body.hpp"
#include "rnea_hessian.hpp"
#include "pool.hpp"
#include "rkmk4.hpp"
#include "variational.hpp"

#ifdef __linux__
#include <sched.h>
#endif

namespace geoddp {
namespace dyn {

int default_threads() {
  // One worker per core, at most two: measured on 2 cores (benchmarks/core_dynamics.py), two
  // workers cut the second-order expansion by 1.3-1.9x on the built-in scenes. Read once:
  // glibc's hardware_concurrency reads /sys/devices/system/cpu/online on every call (5 us, paid
  // by every kernel call with threads <= 0).
  // Cores this process may run on: its affinity mask (taskset, a container's cpuset), not the
  // machine's count (hardware_concurrency): two workers on one allowed core time-slice, and the
  // two-worker backward pass (contracted.cpp) then waits a scheduler slice per node.
  static const int workers = []() {
    int n = 0;
#ifdef __linux__
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof(set), &set) == 0) n = CPU_COUNT(&set);
#endif
    if (n <= 0) n = (int)std::thread::hardware_concurrency();
    return n <= 0 ? 1 : std::min(n, 2);
  }();
  return workers;
}

// The default for a pass: default_threads() workers of the persistent pool (cpp/pool.hpp), but at
// least MIN_NODES_PER_WORKER nodes each (a first-order node costs 1.5-5 us; waking a pooled worker
// costs about as much as one node, starting a std::thread ~10 nodes, which is why first-order
// passes ran on one thread before the pool).
static const int MIN_NODES_PER_WORKER = 16;

// Runs fn(begin, end, worker) on contiguous chunks of [0, N) with `threads` workers (<= 0: the
// default above). The
// chunks depend only on N and the worker count, and each node's arithmetic is the same on any
// worker, so results do not depend on the number of threads (tested).
int node_workers(int N, int threads) {
  const int T = threads > 0 ? threads : std::min(default_threads(), std::max(1, N / MIN_NODES_PER_WORKER));
  return std::max(1, std::min(T, N));
}

template <typename Fn>
static void parallel_for(int N, int threads, Fn fn) {
  const int T = node_workers(N, threads);
  if (T == 1) {
    fn(0, N, 0);
    return;
  }
  const std::function<void(int)> task = [&](int t) {
    const int b = (int)((long)N * t / T), e = (int)((long)N * (t + 1) / T);
    fn(b, e, t);
  };
  WorkerPool::get().run(T, task);
}

void parallel_nodes(int N, int threads, const std::function<void(int, int)>& fn) {
  parallel_for(N, threads, [&](int b, int e, int) { fn(b, e); });
}

void parallel_nodes_indexed(int N, int threads, const std::function<void(int, int, int)>& fn) {
  parallel_for(N, threads, fn);
}

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

// One explicit / semi-implicit Euler step (geoddp.models.multibody.Multibody._step).
// RK4: cpp/rkmk4.hpp.
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
  geoddp::aba(model, data, q, v, tau);
  v1 = v + s.dt * data.ddq;
  const Eigen::VectorXd w = s.dt * (s.integrator == SEMI_IMPLICIT ? v1 : v);
  pinocchio::integrate(model, q, w, q1);
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

// difference(q0, q1) with exact SO(2) entries (geoddp.configuration.difference).
static void difference(const Model& model, const std::vector<JointGroup>& groups, const Eigen::VectorXd& q0,
                       const Eigen::VectorXd& q1, Eigen::VectorXd& d) {
  pinocchio::difference(model, q0, q1, d);
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

// Each of `rows` rows of X (rows, nz*nz) is an (nz, nz) matrix: make it exactly symmetric (the
// products forming it round differently in (a, b) and (b, a)).
static void symmetrise_rows(double* X, int rows, int nz) {
  for (int r = 0; r < rows; ++r) {
    double* x = X + (size_t)r * nz * nz;
    for (int a = 0; a < nz; ++a)
      for (int b = a + 1; b < nz; ++b) {
        const double v = 0.5 * (x[(size_t)a * nz + b] + x[(size_t)b * nz + a]);
        x[(size_t)a * nz + b] = v;
        x[(size_t)b * nz + a] = v;
      }
  }
}

// ------------------------------------------------------------------ velocity update derivatives
// The second derivatives of the velocity update are symmetric in (a, b) and exactly zero in the
// (v, u) and (u, u) blocks (a is affine in tau with slope Minv(q), which does not depend on v). So
// they are computed only on the "active" upper pairs (a <= b): a a q direction (b any), or a and b
// both v directions: nv nz + nv pairs instead of nz^2 (2.2x fewer on the manipulator), stored
// packed, one column per pair.
struct PairIndex {
  std::vector<int> a, b;  // pair c = (a[c], b[c]), a[c] <= b[c]
  int count() const { return (int)a.size(); }
};
static PairIndex active_pairs(int nv, int nz) {
  PairIndex P;
  for (int a = 0; a < nv; ++a)
    for (int b = a; b < nz; ++b) P.a.push_back(a), P.b.push_back(b);
  for (int a = nv; a < 2 * nv; ++a)
    for (int b = a; b < 2 * nv; ++b) P.a.push_back(a), P.b.push_back(b);
  return P;
}

// Per-worker scratch: Pinocchio data and the node's buffers.
struct NodeWork {
  pinocchio::Data data;
  Eigen::MatrixXd Minv, aq, av, au, az, Pj, Tu, F2u;
  Eigen::VectorXd q, v, tau, a;
  PairIndex pairs;
  std::vector<int> pair_of;  // (a, b) -> packed column or -1 (inactive), both orders
  // RNEA's second-order tensors without Pinocchio's per-node call, for a one-body model (one_body.hpp)
  const OneBodySecondOrder* one_body = nullptr;
  explicit NodeWork(const Model& model, int m)
      : data(model), Minv(model.nv, model.nv), aq(model.nv, model.nv), av(model.nv, model.nv),
        au(model.nv, m), az(model.nv, 2 * model.nv + m), Pj(model.nv, 2 * model.nv + m), q(model.nq),
        v(model.nv), tau(model.nv), a(model.nv) {
    const int nv = model.nv, nz = 2 * nv + m;
    pairs = active_pairs(nv, nz);
    pair_of.assign((size_t)nz * nz, -1);
    for (int c = 0; c < pairs.count(); ++c) {
      pair_of[(size_t)pairs.a[c] * nz + pairs.b[c]] = c;
      pair_of[(size_t)pairs.b[c] * nz + pairs.a[c]] = c;
    }
    Tu.resize(nv, pairs.count());
    F2u.resize(nv, pairs.count());
  }
};

// F1 (nv, nz) and, if second, F2u (nv, active pairs) in w.F2u (column-major, packed as
// w.pairs) at one node.
//
// a(q, v, u) solves ID(q, v, a) = H u with ID RNEA (affine in a, slope M(q)). Differentiating
// twice along z = (dq, dv, du) (dq through integrate, right-trivialised):
//   ID_z + M a_z = [0 0 H]
//   ID_zz + ID_za a_z + a_z^T ID_az + M a_zz = 0      (ID_aa = 0)
// so a_zz = -Minv (ID_zz + ID_za a_z + (ID_za a_z)^T), where ID_za is only the (q, a) block
// dM/dq (M does not depend on v) and ID_zz has the (q, q), (q, v), (v, v) blocks of RNEA's
// second derivatives. The q-q block of RNEA is a derivative on the group (not symmetric in a
// free flyer's rotation block): its symmetric part is the (0)-Hessian geoddp uses, as in the
// Python path. Pinocchio's tensors (checked against differences of its analytic first
// derivatives in tests/test_core_dynamics.py): d2tau_dqdq(i, j, k), d2tau_dvdv(i, j, k),
// d2tau_dqdv(i, q_j, v_k), d2tau_dadq(i, a_j, q_k) = d M(i, j) / d q_k.
static void node_derivatives(const Setup& s, NodeWork& w, double* F1, bool second) {
  const Model& model = *s.model;
  const int nv = model.nv, m = s.m, nz = 2 * nv + m;
  const double dt = s.dt;
  CMatMap Hm(s.H, nv, m);
  pinocchio::Data& data = w.data;
  pinocchio::computeABADerivatives(model, data, w.q, w.v, w.tau);
  w.Minv = data.Minv;
  w.Minv.triangularView<Eigen::StrictlyLower>() = w.Minv.transpose();
  w.aq = data.ddq_dq;
  w.av = data.ddq_dv;
  w.au.noalias() = w.Minv * Hm;
  w.a = data.ddq;
  MatMap F1m(F1, nv, nz);
  F1m.leftCols(nv) = dt * w.aq;
  F1m.middleCols(nv, nv) = dt * w.av;
  F1m.middleCols(nv, nv).diagonal().array() += 1.0;
  F1m.rightCols(m) = dt * w.au;
  if (!second) return;

  if (w.one_body)
    w.one_body->at(w.q.data(), data.d2tau_dqdq.data(), data.d2tau_dvdv.data(), data.d2tau_dqdv.data(),
                   data.d2tau_dadq.data());
  else
    pinocchio::ComputeRNEASecondOrderDerivatives(model, data, w.q, w.v, w.a);
  const auto& Iqq = data.d2tau_dqdq;
  const auto& Ivv = data.d2tau_dvdv;
  const auto& Iqv = data.d2tau_dqdv;
  w.az.leftCols(nv) = w.aq;
  w.az.middleCols(nv, nv) = w.av;
  w.az.rightCols(m) = w.au;
  // Tu(i, (a, b)) = T_i(a, b) of ID_zz + ID_za a_z + (ID_za a_z)^T on the active pairs.
  w.Tu.setZero();
  double* Tu = w.Tu.data();
  const int* pa = w.pairs.a.data();
  for (int j = 0; j < nv; ++j) {
    // Pj(i, :) = sum_l dM(i, l, j) a_z(l, :): row i, q_j entries of ID_za a_z. dM is a
    // column-major tensor, so its slice at q_j is a column-major (nv, nv) matrix.
    Eigen::Map<const Eigen::MatrixXd> dMj(data.d2tau_dadq.data() + (size_t)nv * nv * j, nv, nv);
    if (nv <= 16)  // small: coefficient-based (Eigen's blocked GEMM packs more than it multiplies)
      w.Pj.noalias() = dMj.lazyProduct(w.az);
    else
      w.Pj.noalias() = dMj * w.az;
    for (int b = 0; b < nz; ++b) {
      // (q_j, z_b) and (z_b, q_j): the same upper pair; the diagonal gets both
      const int c = w.pair_of[(size_t)j * nz + b];
      double* t = Tu + (size_t)nv * c;
      const double* pcol = w.Pj.data() + (size_t)nv * b;
      if (b == j)
        for (int i = 0; i < nv; ++i) t[i] += 2.0 * pcol[i];
      else
        for (int i = 0; i < nv; ++i) t[i] += pcol[i];
    }
  }
  (void)pa;
  for (int j = 0; j < nv; ++j)
    for (int k = 0; k < nv; ++k) {
      if (k >= j) {
        double* tqq = Tu + (size_t)nv * w.pair_of[(size_t)j * nz + k];
        double* tvv = Tu + (size_t)nv * w.pair_of[(size_t)(nv + j) * nz + nv + k];
        for (int i = 0; i < nv; ++i) {
          tqq[i] += 0.5 * (Iqq(i, j, k) + Iqq(i, k, j));
          tvv[i] += 0.5 * (Ivv(i, j, k) + Ivv(i, k, j));
        }
      }
      double* tqv = Tu + (size_t)nv * w.pair_of[(size_t)j * nz + nv + k];
      for (int i = 0; i < nv; ++i) tqv[i] += Iqv(i, j, k);
    }
  w.F2u.noalias() = (-dt) * (w.Minv * w.Tu);
}

// The dense symmetric (nv, nz, nz) F2 (row-major [p][a*nz + b]) from the packed pairs.
static void unpack_pairs(const NodeWork& w, int rows, const Eigen::MatrixXd& Xu, int nz, double* X) {
  std::fill(X, X + (size_t)rows * nz * nz, 0.0);
  for (int c = 0; c < w.pairs.count(); ++c) {
    const int a = w.pairs.a[c], b = w.pairs.b[c];
    const double* x = Xu.data() + (size_t)rows * c;
    for (int p = 0; p < rows; ++p) {
      X[(size_t)p * nz * nz + (size_t)a * nz + b] = x[p];
      X[(size_t)p * nz * nz + (size_t)b * nz + a] = x[p];
    }
  }
}

// The one-body shortcut for RNEA's second-order tensors when `model` is one body on a free-flyer or
// spherical root and the second order is wanted, else null.
static std::unique_ptr<OneBodySecondOrder> one_body_for(const Model& model, bool second) {
  return second && OneBodySecondOrder::applies(model) ? std::make_unique<OneBodySecondOrder>(model) : nullptr;
}

bool one_body_applies(const Model& model) { return OneBodySecondOrder::applies(model); }

// Pinocchio's second-order RNEA tensors at (q, v, a), written straight into Iqq, Ivv, Iqv, dM
// (nv^3 each, its column-major layout): Pinocchio's overload with output tensors, here maps of
// the caller's buffers, zeroed first as its own overload zeroes data's (the recursion writes only
// the entries the kinematic tree couples). The copy out of data it replaces moved 4 nv^3 doubles
// per node (23 kB at nv = 9: 7 % of the space manipulator's second-order expansion).
static void pinocchio_second_order(const Model& model, pinocchio::Data& data, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& v, const Eigen::VectorXd& a, double* Iqq, double* Ivv,
                                   double* Iqv, double* dM) {
  typedef Eigen::TensorMap<Eigen::Tensor<double, 3>> TensorMap;
  const Eigen::Index nv = model.nv;
  const size_t n3 = (size_t)nv * nv * nv;
  for (double* X : {Iqq, Ivv, Iqv, dM}) std::fill(X, X + n3, 0.0);
  TensorMap tqq(Iqq, nv, nv, nv), tvv(Ivv, nv, nv, nv), tqv(Iqv, nv, nv, nv), tdm(dM, nv, nv, nv);
  pinocchio::ComputeRNEASecondOrderDerivatives(model, data, q, v, a, tqq, tvv, tqv, tdm);
}

void rnea_second_order(const Model& model, const double* q, const double* v, const double* a, bool one_body,
                       double* Iqq, double* Ivv, double* Iqv, double* dM) {
  if (one_body) {
    if (!OneBodySecondOrder::applies(model))
      throw std::invalid_argument("model: the one-body shortcut needs one free-flyer or spherical joint");
    OneBodySecondOrder(model).at(q, Iqq, Ivv, Iqv, dM);
    return;
  }
  pinocchio::Data data(model);
  pinocchio_second_order(model, data, CVecMap(q, model.nq), CVecMap(v, model.nv), CVecMap(a, model.nv), Iqq, Ivv,
                         Iqv, dM);
}

static void node_velocity_derivatives(const Setup& s, NodeWork& w, double* F1, double* F2) {
  node_derivatives(s, w, F1, F2 != nullptr);
  if (F2 != nullptr) unpack_pairs(w, s.model->nv, w.F2u, 2 * s.model->nv + s.m, F2);
}

void velocity_derivatives(const Setup& s, const double* Q, const double* V, const double* U, int N, int order,
                          int threads, double* F1, double* F2) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, nz = 2 * nv + m;
  CMatMap Hm(s.H, nv, m);
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, order >= 2);
  parallel_for(N, threads, [&](int b, int e, int) {
    NodeWork w(model, m);
    w.one_body = one_body.get();
    for (int k = b; k < e; ++k) {
      w.q = CVecMap(Q + (size_t)k * nq, nq);
      w.v = CVecMap(V + (size_t)k * nv, nv);
      w.tau = Hm * CVecMap(U + (size_t)k * m, m);
      node_velocity_derivatives(s, w, F1 + (size_t)k * nv * nz,
                                order >= 2 ? F2 + (size_t)k * nv * nz * nz : nullptr);
    }
  });
}

// ------------------------------------------------------------------ reconstruction
void block_ad_jr(const std::vector<JointGroup>& groups, int nv, const double* omega, double* A, double* Jr,
                 double* D) {
  MatMap Am(A, nv, nv), Jm(Jr, nv, nv);
  Am.setIdentity();
  Jm.setIdentity();
  if (D != nullptr) std::fill(D, D + (size_t)nv * nv * nv, 0.0);
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3) {
      const lie::Vec3 w = CVecMap(omega + o, 3);
      Am.block<3, 3>(o, o) = pinocchio::exp3(w).transpose();
      Jm.block<3, 3>(o, o) = lie::so3_jr(w);
      if (D != nullptr) {
        lie::Mat3 Dl[3];
        lie::so3_djr(w, Dl);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            for (int l = 0; l < 3; ++l) D[((size_t)(o + i) * nv + (o + j)) * nv + (o + l)] = Dl[l](i, j);
      }
    } else if (g.kind == SE3) {
      const Eigen::Matrix<double, 6, 1> w = CVecMap(omega + o, 6);
      Am.block<6, 6>(o, o) = pinocchio::exp6(pinocchio::Motion(-w)).toActionMatrix();
      Jm.block<6, 6>(o, o) = lie::se3_jr(w);
      if (D != nullptr) {
        lie::Mat6 Dl[6];
        lie::se3_djr(w, Dl);
        for (int i = 0; i < 6; ++i)
          for (int j = 0; j < 6; ++j)
            for (int l = 0; l < 6; ++l) D[((size_t)(o + i) * nv + (o + j)) * nv + (o + l)] = Dl[l](i, j);
      }
    }
  }
}

using lie::GroupStructure;  // the reconstruction's structure constants C3[p], C6[p]

// out = alpha Jr X for the block-diagonal right Jacobian Jr (nv, nv) of the reconstruction, X and
// out (nv, c), out not aliasing X. Jr is the identity off the SO(3)/SE(3) groups, so only those
// groups' rows are multiplied; the others are copied, scaled.
template <typename XMat, typename OutMat>
static void jr_times(const std::vector<JointGroup>& groups, const RowMat& Jr, double alpha, const XMat& X,
                     OutMat& out) {
  out = alpha * X;
  for (const JointGroup& g : groups)
    if (g.kind == SO3 || g.kind == SE3)
      out.middleRows(g.idx_v, g.nv).noalias() =
          alpha * Jr.block(g.idx_v, g.idx_v, g.nv, g.nv).lazyProduct(X.middleRows(g.idx_v, g.nv));
}

// The first-order blocks of node k (eta+ = A eta + Jr rho, rho = dt delta w; v+'s rows F1
// (nv, nz)): W1 = d(delta w)/dz (F1 semi-implicit, the dv selector explicit), JW = Jr W1, and
// Phi_k (n, n), B_k (n, m) from G1 = [A 0 + dt JW; F1] (G1 (n, nz) scratch).
static void first_order_blocks(const std::vector<JointGroup>& groups, bool semi, double dt, const RowMat& F1,
                               const RowMat& A, const RowMat& Jr, RowMat& W1, RowMat& JW, RowMat& G1, double* Phi_k,
                               double* B_k) {
  const int nv = (int)F1.rows(), n = 2 * nv, m = (int)F1.cols() - n;
  if (semi) {
    W1 = F1;
  } else {
    W1.setZero();
    W1.middleCols(nv, nv).setIdentity();
  }
  jr_times(groups, Jr, 1.0, W1, JW);
  G1.topRows(nv) = dt * JW;
  G1.topLeftCorner(nv, nv) += A;
  G1.bottomRows(nv) = F1;
  MatMap(Phi_k, n, n) = G1.leftCols(n);
  MatMap(B_k, n, m) = G1.rightCols(m);
}

// sym D[o+p, o+a, o+c] over (a, c) for the group at tangent offset o (Dt (nv, nv, nv) row-major,
// the derivative of Jr from block_ad_jr): 1/2 dJr[rho] rho = rho^T Dsym_p rho.
static inline double dsym_entry(const std::vector<double>& Dt, int nv, int o, int p, int a, int c) {
  return 0.5 * (Dt[((size_t)(o + p) * nv + (o + a)) * nv + (o + c)] + Dt[((size_t)(o + p) * nv + (o + c)) * nv + (o + a)]);
}

// 1/2 [A eta, Jr rho]_p = z^T Mz z on the (eta in the group, z) block: Mz = dt/2 As^T C_p JWs
// (As the group's block of A, JWs its rows of JW, row-major; Ds scratch). As^T C_p is a fixed-size
// 3x3 or 6x6 product, and Ds JWs runs on small_gemm.hpp: Eigen's dynamic lazy product of these
// d x nz blocks cost 5 % of a quadrotor's second-order solve.
template <typename ABlock, typename JWBlock>
static void bracket_block(const GroupStructure& gs, const JointGroup& g, int p, double dt, const ABlock& As,
                          const JWBlock& JWs, RowMat& Ds, RowMat& Mz) {
  const int d = g.nv;
  if (g.kind == SO3) Ds = lie::Mat3(As).transpose() * gs.C3[p];
  else Ds = lie::Mat6(As).transpose() * gs.C6[p];
  const int nz = (int)JWs.cols();
  Mz.resize(d, nz);
  gemm::gemm(false, d, nz, d, 0.5 * dt, Ds.data(), d, JWs.data(), (int)JWs.outerStride(), false, Mz.data(), nz);
}

void expansion(const Setup& s, const double* Q, const double* V, const double* U, int N, int order, int threads,
               double* Phi, double* B, double* Theta, double* Gamma, double* Xi) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, n = 2 * nv, nz = n + m;
  const double dt = s.dt;
  const bool semi = s.integrator == SEMI_IMPLICIT;
  const std::vector<JointGroup> groups = joint_groups(model);
  if (s.integrator == RK4) {
    parallel_for(N, threads, [&](int b, int e, int) {
      Rk4Work w(model, m);
      Eigen::VectorXd q(nq), v(nv), u(m);
      for (int k = b; k < e; ++k) {
        q = CVecMap(Q + (size_t)k * nq, nq);
        v = CVecMap(V + (size_t)k * nv, nv);
        u = CVecMap(U + (size_t)k * m, m);
        const bool second = order >= 2;
        rk4_node_expansion(s, groups, w, q, v, u, Phi + (size_t)k * n * n, B + (size_t)k * n * m,
                           second ? Theta + (size_t)k * n * n * n : nullptr,
                           second ? Gamma + (size_t)k * n * n * m : nullptr, second ? Xi + (size_t)k * n * m * m : nullptr);
      }
    });
    return;
  }
  const GroupStructure gs;
  CMatMap Hm(s.H, nv, m);
  // the variational step: its own velocity derivatives (dense F2), the explicit-Euler reconstruction
  const std::unique_ptr<VariationalModel> vmod =
      s.integrator == VARIATIONAL ? std::make_unique<VariationalModel>(model, s.H, m, dt) : nullptr;
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, order >= 2 && !vmod);
  parallel_for(N, threads, [&](int b0, int e0, int) {
    // each worker builds the scratch of its integrator only (a Pinocchio Data and pair tables, or
    // the variational step's)
    const std::unique_ptr<NodeWork> ew = vmod ? nullptr : std::make_unique<NodeWork>(model, m);
    if (ew) ew->one_body = one_body.get();
    const std::unique_ptr<VariationalNodeWork> vw = vmod ? std::make_unique<VariationalNodeWork>(*vmod) : nullptr;
    Eigen::VectorXd q(nq), v(nv);
    RowMat F2d(vw && order >= 2 ? nv : 0, (Eigen::Index)nz * nz);
    Eigen::VectorXd ynext(vw ? nv : 0);
    RowMat F1(nv, nz), W1(nv, nz), JW(nv, nz), G1(n, nz);
    RowMat A(nv, nv), Jr(nv, nv), G2(order >= 2 ? n : 0, (Eigen::Index)nz * nz);
    RowMat Ds, Mz, WDW;  // per-group scratch (reused: no allocation per node)
    Eigen::MatrixXd JF2u;    // dt Jr F2 on the active pairs (semi-implicit top rows)
    std::vector<double> Dt(order >= 2 ? (size_t)nv * nv * nv : 0);
    Eigen::VectorXd omega(nv);
    for (int k = b0; k < e0; ++k) {
      q = CVecMap(Q + (size_t)k * nq, nq);
      v = CVecMap(V + (size_t)k * nv, nv);
      if (vw) {
        ynext = CVecMap(V + (size_t)(k + 1) * nv, nv);
        variational_node(*vmod, *vw, q, v, ynext, F1.data(), order >= 2 ? F2d.data() : nullptr);
      } else {
        ew->q = q;
        ew->v = v;
        ew->tau = Hm * CVecMap(U + (size_t)k * m, m);
        node_derivatives(s, *ew, F1.data(), order >= 2);
      }
      // reconstruction velocity w_bar: v_k (euler) or v_{k+1} (semi-implicit)
      omega = dt * CVecMap(V + (size_t)(semi ? k + 1 : k) * nv, nv);
      block_ad_jr(groups, nv, omega.data(), A.data(), Jr.data(), order >= 2 ? Dt.data() : nullptr);
      first_order_blocks(groups, semi, dt, F1, A, Jr, W1, JW, G1, Phi + (size_t)k * n * n, B + (size_t)k * n * m);
      if (order < 2) continue;
      // eta+ = A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [A eta, Jr rho], rho = dt delta w
      // (geoddp.integrators' module docstring; per non-commutative joint group).
      G2.setZero();
      for (const JointGroup& g : groups) {
        if (g.kind != SO3 && g.kind != SE3) continue;
        const int o = g.idx_v, d = g.nv;
        const auto Ws = W1.middleRows(o, d);
        const auto JWs = JW.middleRows(o, d);
        const auto As = A.block(o, o, d, d);
        Ds.resize(d, d);
        for (int p = 0; p < d; ++p) {
          // 1/2 dJr[rho] rho: dt^2 Ws^T Dsym_p Ws, Dsym_p(a, b) = sym D[p, a, b]
          for (int a = 0; a < d; ++a)
            for (int c = 0; c < d; ++c) Ds(a, c) = dsym_entry(Dt, nv, o, p, a, c);
          Eigen::Map<RowMat> G2p(G2.row(o + p).data(), nz, nz);
          // coefficient-based products: these are (nz, d) x (d, d) x (d, nz) with d <= 6, where
          // Eigen's blocked GEMM spends more on packing than on arithmetic
          Mz.noalias() = Ds.lazyProduct(Ws);
          WDW.noalias() = Ws.transpose().lazyProduct(Mz);
          G2p += (dt * dt) * WDW;
          // 1/2 [A eta, Jr rho]_p = z^T Mz_p z, Mz_p = dt/2 A^T C_p JW on the (eta in s, z) block
          bracket_block(gs, g, p, dt, As, JWs, Ds, Mz);
          G2p.middleRows(o, d) += Mz;
          G2p.middleCols(o, d) += Mz.transpose();
        }
      }
      // velocity update: F2 (symmetric, zero off the active pairs) in the bottom rows and, for
      // the semi-implicit reconstruction, dt Jr F2 in the top rows (Jr is the identity outside
      // the SO(3)/SE(3) blocks, so only those blocks multiply)
      if (vw) {  // the variational step's dense F2; its reconstruction is explicit Euler's
        for (int p = 0; p < nv; ++p) G2.row(nv + p) = F2d.row(p);
      }
      const int np = vw ? 0 : ew->pairs.count();
      if (semi) jr_times(groups, Jr, dt, ew->F2u, JF2u);
      for (int c = 0; c < np; ++c) {
        const size_t ab = (size_t)ew->pairs.a[c] * nz + ew->pairs.b[c], ba = (size_t)ew->pairs.b[c] * nz + ew->pairs.a[c];
        const double* f = ew->F2u.data() + (size_t)nv * c;
        for (int p = 0; p < nv; ++p) {
          double* row = G2.row(nv + p).data();
          row[ab] = f[p];
          row[ba] = f[p];
        }
        if (semi) {
          const double* jf = JF2u.data() + (size_t)nv * c;
          for (int p = 0; p < nv; ++p) {
            double* row = G2.row(p).data();
            row[ab] += jf[p];
            if (ba != ab) row[ba] += jf[p];
          }
        }
      }
      symmetrise_rows(G2.data(), nv, nz);  // the reconstruction's rows (the velocity rows are exactly symmetric)
      double* Th = Theta + (size_t)k * n * n * n;
      double* Ga = Gamma + (size_t)k * n * n * m;
      double* X = Xi + (size_t)k * n * m * m;
      for (int i = 0; i < n; ++i) {
        const double* g2 = G2.row(i).data();
        for (int a = 0; a < n; ++a) {
          for (int c = 0; c < n; ++c) Th[((size_t)i * n + a) * n + c] = g2[(size_t)a * nz + c];
          for (int c = 0; c < m; ++c) Ga[((size_t)i * n + a) * m + c] = g2[(size_t)a * nz + n + c];
        }
        for (int a = 0; a < m; ++a)
          for (int c = 0; c < m; ++c) X[((size_t)i * m + a) * m + c] = g2[(size_t)(n + a) * nz + n + c];
      }
    }
  });
}

}  // namespace dyn
}  // namespace geoddp

namespace geoddp {
namespace dyn {

// ------------------------------------------------------------------ factored second order
// The pool behind Buffer: at most POOL_BUFFERS released buffers and POOL_BYTES in all (the four
// tensors and six blocks of one SecondOrderTerms, a second set for a linearisation still alive),
// taken back by exact size; anything beyond is freed. Never destroyed: Python may release its last
// SecondOrderTerms after static destructors have run.
namespace {
constexpr size_t POOL_BUFFERS = 20;
constexpr size_t POOL_BYTES = size_t(512) << 20;
struct Pool {
  std::mutex mutex;
  std::vector<std::pair<size_t, double*>> free;  // (doubles, memory), oldest first
  size_t doubles = 0;
};
Pool& pool() {
  static Pool* p = new Pool;
  return *p;
}
}  // namespace

double* buffer_take(size_t n) {
  if (n == 0) return nullptr;
  Pool& P = pool();
  {
    std::lock_guard<std::mutex> lock(P.mutex);
    for (size_t i = P.free.size(); i-- > 0;)
      if (P.free[i].first == n) {
        double* p = P.free[i].second;
        P.free.erase(P.free.begin() + i);
        P.doubles -= n;
        return p;
      }
  }
  return new double[n];
}

void buffer_give(double* p, size_t n) {
  if (!p) return;
  Pool& P = pool();
  std::vector<double*> drop;
  {
    std::lock_guard<std::mutex> lock(P.mutex);
    P.free.emplace_back(n, p);
    P.doubles += n;
    while (!P.free.empty() && (P.free.size() > POOL_BUFFERS || P.doubles * sizeof(double) > POOL_BYTES)) {
      drop.push_back(P.free.front().second);  // the oldest go first
      P.doubles -= P.free.front().first;
      P.free.erase(P.free.begin());
    }
  }
  for (double* d : drop) delete[] d;
}

namespace {
std::atomic<bool> RECURSION{true};
std::atomic<unsigned long long> TERMS_ID{0};
}  // namespace

void set_rnea_hessian_recursion(bool on) { RECURSION = on; }
bool rnea_hessian_recursion() { return RECURSION; }

void SecondOrderTerms::resize(const Model& model_, int m_, int N_, double dt_, bool semi_, bool variational_,
                              bool recursion_, bool one_body_, bool one_body_gravity_) {
  const Model& model = model_;
  this->model = &model_;
  id = ++TERMS_ID;
  recursion = recursion_ && !variational_;
  one_body = one_body_ && !variational_ && !recursion;
  one_body_gravity = one_body && one_body_gravity_;
  N = N_;
  nv = model.nv;
  m = m_;
  dt = dt_;
  semi = semi_;
  variational = variational_;
  groups.clear();
  for (const JointGroup& g : joint_groups(model))
    if (g.kind == SO3 || g.kind == SE3) groups.push_back(g);
  const int nz = 2 * nv + m;
  gJ = gD = gW = 0;
  for (const JointGroup& g : groups) {
    gJ += g.nv * g.nv;
    gD += g.nv * g.nv * g.nv;
    gW += g.nv * nz;
  }
  const size_t n3 = variational || recursion ? 0 : (size_t)N * nv * nv * nv;
  rnea.resize(recursion ? (size_t)N * rnea_hessian_node_size(model) : 0);
  if (one_body) {
    Iqq.resize(one_body_gravity ? n3 : 0);
    Ivv.resize((size_t)nv * nv * nv);
    Iqv.resize(0);
    dM.resize(0);
  } else {
    for (auto* x : {&Iqq, &Ivv, &Iqv, &dM}) x->resize(n3);
  }
  Minv.resize((size_t)N * nv * nv);
  az.resize(variational || one_body ? 0 : (size_t)N * nv * nz);  // one body: read only with dM = 0
  Ts.resize(variational ? (size_t)N * variational_upper_size(nv) * nv : 0);
  F1.resize((size_t)N * nv * nz);
  Jr.resize((size_t)N * gJ);
  Dsym.resize((size_t)N * gD);
  As.resize((size_t)N * gJ);
  JWs.resize((size_t)N * gW);
}

// What a Data and RneaHessianWork depend on: the tree's shape and its joints' kinds.
static std::vector<int> model_structure(const Model& model) {
  std::vector<int> x{model.njoints, model.nq, model.nv};
  for (int j = 0; j < model.njoints; ++j) {
    x.push_back((int)model.parents[j]);
    x.push_back(model.nvs[j]);
    x.push_back(model.nqs[j]);
    x.push_back(model.joints[j].toVariant().which());
  }
  return x;
}

void rnea_hessian_at_node(const SecondOrderTerms& t, int k, const double* mu, double* r4) {
  // One work (and Data) per thread: the pass may contract on the pool's second worker, and two
  // passes may run side by side (ladder.hpp's speculation). Every linearisation makes new terms
  // (a new id); a work is rebuilt only if their model is another (a Data costs more than a node).
  struct Cache {
    std::unique_ptr<RneaHessianWork> work;
    const Model* model = nullptr;
    std::vector<int> structure;
    unsigned long long served = 0;
  };
  thread_local Cache c;
  const Model& model = *t.model;
  if (c.served != t.id) {
    std::vector<int> structure = model_structure(model);
    if (!c.work || c.model != &model || c.structure != structure) {
      c.work = std::make_unique<RneaHessianWork>(model);
      c.model = &model;
      c.structure = std::move(structure);
    }
    c.served = t.id;
  }
  const size_t nn = (size_t)model.nv * model.nv;
  rnea_hessian_contract(model, *c.work, t.rnea.data() + (size_t)k * rnea_hessian_node_size(model), mu, r4, r4 + nn,
                        r4 + 2 * nn, r4 + 3 * nn);
}

// Node k's reconstruction group blocks (Jr, As, JWs, Dsym) into t, from block_ad_jr's A, Jr, D
// and first_order_blocks' JW.
static void store_group_blocks(const std::vector<JointGroup>& groups, SecondOrderTerms& t, int k, const RowMat& Jr,
                               const RowMat& A, const RowMat& JW, const std::vector<double>& Dt, int nv, int nz) {
  double* jr = t.Jr.data() + (size_t)k * t.gJ;
  double* as = t.As.data() + (size_t)k * t.gJ;
  double* dsym = t.Dsym.data() + (size_t)k * t.gD;
  double* jw = t.JWs.data() + (size_t)k * t.gW;
  for (const JointGroup& g : groups) {
    if (g.kind != SO3 && g.kind != SE3) continue;
    const int o = g.idx_v, d = g.nv;
    MatMap(jr, d, d) = Jr.block(o, o, d, d);
    MatMap(as, d, d) = A.block(o, o, d, d);
    MatMap(jw, d, nz) = JW.middleRows(o, d);
    jr += d * d;
    as += d * d;
    jw += d * nz;
    for (int p = 0; p < d; ++p)
      for (int a = 0; a < d; ++a)
        for (int c = 0; c < d; ++c) dsym[(size_t)(p * d + a) * d + c] = dsym_entry(Dt, nv, o, p, a, c);
    dsym += d * d * d;
  }
}

// Per node: the first-order part exactly as expansion() computes it (same expressions, so Phi and
// B are bitwise those of order 1), then RNEA's second-order tensors and the reconstruction's group
// blocks copied into `t` instead of being assembled into Theta, Gamma, Xi.
void expansion_contracted(const Setup& s, const double* Q, const double* V, const double* U, int N, int threads,
                          double* Phi, double* B, SecondOrderTerms& t) {
  if (s.integrator == RK4)
    throw std::invalid_argument("integrator: the factored second order is for euler, semi_implicit and variational");
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, n = 2 * nv, nz = n + m;
  const double dt = s.dt;
  const bool semi = s.integrator == SEMI_IMPLICIT;
  // the variational step: its residual Hessians and R_y^-T (variational_node_factored); its
  // reconstruction is explicit Euler's, so the group blocks below are those of euler
  const std::unique_ptr<VariationalModel> vmod =
      s.integrator == VARIATIONAL ? std::make_unique<VariationalModel>(model, s.H, m, dt) : nullptr;
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, !vmod);
  t.resize(model, m, N, dt, semi, vmod != nullptr, !vmod && !one_body && rnea_hessian_recursion(), one_body != nullptr,
           one_body && one_body->with_gravity());
  if (t.one_body) std::copy(one_body->d2tau_dvdv().begin(), one_body->d2tau_dvdv().end(), t.Ivv.data());
  t.variational_separable = vmod && vmod->configuration_free;
  const std::vector<JointGroup> groups = joint_groups(model);
  CMatMap Hm(s.H, nv, m);
  const size_t n3 = (size_t)nv * nv * nv, nts = (size_t)variational_upper_size(nv) * nv;
  parallel_for(N, threads, [&](int b0, int e0, int) {
    const std::unique_ptr<NodeWork> ew = vmod ? nullptr : std::make_unique<NodeWork>(model, m);
    const std::unique_ptr<VariationalNodeWork> vw = vmod ? std::make_unique<VariationalNodeWork>(*vmod) : nullptr;
    const std::unique_ptr<RneaHessianWork> rw = t.recursion ? std::make_unique<RneaHessianWork>(model) : nullptr;
    RowMat F1(nv, nz), W1(nv, nz), JW(nv, nz), G1(n, nz);
    RowMat A(nv, nv), Jr(nv, nv);
    std::vector<double> Dt((size_t)nv * nv * nv);
    Eigen::VectorXd omega(nv), q(nq), v(nv), ynext(nv);
    for (int k = b0; k < e0; ++k) {
      if (vw) {
        q = CVecMap(Q + (size_t)k * nq, nq);
        v = CVecMap(V + (size_t)k * nv, nv);
        ynext = CVecMap(V + (size_t)(k + 1) * nv, nv);
        variational_node_factored(*vmod, *vw, q, v, ynext, F1.data(), t.Minv.data() + (size_t)k * nv * nv,
                                  t.Ts.data() + k * nts);
      } else {
        ew->q = CVecMap(Q + (size_t)k * nq, nq);
        ew->v = CVecMap(V + (size_t)k * nv, nv);
        ew->tau = Hm * CVecMap(U + (size_t)k * m, m);
        node_derivatives(s, *ew, F1.data(), false);
      }
      omega = dt * CVecMap(V + (size_t)(semi ? k + 1 : k) * nv, nv);
      block_ad_jr(groups, nv, omega.data(), A.data(), Jr.data(), Dt.data());
      first_order_blocks(groups, semi, dt, F1, A, Jr, W1, JW, G1, Phi + (size_t)k * n * n, B + (size_t)k * n * m);
      if (ew) {
        NodeWork& w = *ew;
        // the velocity update's second order: RNEA's tensors at (q, v, a), as node_derivatives uses
        // them (the one-body shortcut writes them in place); the variational step's are written above
        if (one_body) {  // d2tau_dqdq only (the rest is zero or constant, stored once above)
          if (t.one_body_gravity) one_body->dqdq_at(w.q.data(), t.Iqq.data() + k * n3);
        } else if (t.recursion) {  // contracted in the pass (rnea_hessian.hpp): its mu-free terms
          rnea_hessian_node(model, *rw, w.q.data(), w.v.data(), w.a.data(),
                            t.rnea.data() + (size_t)k * rnea_hessian_node_size(model));
        } else {
          pinocchio_second_order(model, w.data, w.q, w.v, w.a, t.Iqq.data() + k * n3, t.Ivv.data() + k * n3,
                                 t.Iqv.data() + k * n3, t.dM.data() + k * n3);
        }
        MatMap(t.Minv.data() + (size_t)k * nv * nv, nv, nv) = w.Minv;
        if (!t.one_body) {
          MatMap azk(t.az.data() + (size_t)k * nv * nz, nv, nz);
          azk.leftCols(nv) = w.aq;
          azk.middleCols(nv, nv) = w.av;
          azk.rightCols(m) = w.au;
        }
      }
      MatMap(t.F1.data() + (size_t)k * nv * nz, nv, nz) = F1;
      store_group_blocks(groups, t, k, Jr, A, JW, Dt, nv, nz);
    }
  });
}

}  // namespace dyn
}  // namespace geoddp
