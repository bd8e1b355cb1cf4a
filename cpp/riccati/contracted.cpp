// Contraction of the factored second-order terms with V_x' and the backward pass using it (see
// riccati/contracted.hpp). Eigen only: no Pinocchio algorithm is instantiated here.
#include "riccati/contracted.hpp"
#include "riccati/ladder.hpp"
#include "riccati/riccati_blocks.hpp"
#include "riccati/riccati.hpp"

#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <type_traits>
#include <thread>
#include <vector>

#include "lie/right_jacobians.hpp"
#include "runtime/pool.hpp"

namespace geoddp {
namespace ctr {

// The structure constants C_p of so(3) and se(3), made once.
static const lie::GroupStructure STRUCTURE;

// X = As^T (sum_p l_p C_p) for a group of dimension D (3: SO(3), 6: SE(3)); As row-major.
template <int D>
static void bracket_factor(const double* as, const double* l, const Eigen::Matrix<double, D, D>* C, double* X) {
  Eigen::Matrix<double, D, D> Cl = l[0] * C[0];
  for (int p = 1; p < D; ++p) Cl += l[p] * C[p];
  Eigen::Map<Eigen::Matrix<double, D, D, Eigen::RowMajor>>(X).noalias() =
      Eigen::Map<const Eigen::Matrix<double, D, D, Eigen::RowMajor>>(as).transpose() * Cl;
}

// The reconstruction rows of the SO(3)/SE(3) groups (upper triangle of S), contracted with lq.
static void reconstruction_upper(const dyn::SecondOrderTerms& t, int k, const CVecMap& lq, RowMat& S) {
  const int nv = t.nv, nz = t.nz();
  const double dt = t.dt;
  thread_local std::vector<double> ml, dl, DW, X;
  const double* dsym = t.Dsym.data() + (size_t)k * t.gD;
  const double* as = t.As.data() + (size_t)k * t.gJ;
  const double* jw = t.JWs.data() + (size_t)k * t.gW;
  const double* F1 = t.F1.data() + (size_t)k * nv * nz;
  for (const JointGroup& g : t.groups) {
    const int o = g.idx_v, d = g.nv, dd = d * d, dn = d * nz;
    dl.assign(dd, 0.0);
    for (int p = 0; p < d; ++p) {
      const double l = lq[o + p];
      const double* Dp = dsym + (size_t)p * dd;
      for (int e = 0; e < dd; ++e) dl[e] += l * Dp[e];
    }
    // Ml = dt/2 As^T (sum_p lq_p C_p) JWs: a d x d factor, then one (d, d) x (d, nz) product
    X.resize(dd);
    if (g.kind == SO3) bracket_factor<3>(as, lq.data() + o, STRUCTURE.C3, X.data());
    else bracket_factor<6>(as, lq.data() + o, STRUCTURE.C6, X.data());
    ml.resize(dn);
    gemm::gemm(false, d, nz, d, 0.5 * dt, X.data(), d, jw, nz, false, ml.data(), nz);
    if (t.semi) {  // S += dt^2 Ws^T Dl Ws with Ws = F1's rows of the group: upper triangle only
      const double* Ws = F1 + (size_t)o * nz;
      DW.resize(dn);
      gemm::gemm(false, d, nz, d, 1.0, dl.data(), d, Ws, nz, false, DW.data(), nz);
      gemm::gemm_upper(true, nz, d, dt * dt, Ws, nz, DW.data(), nz, true, S.data(), nz);
    } else {  // W_s selects the group's v directions
      for (int a = 0; a < d; ++a)
        for (int b = a; b < d; ++b) S(nv + o + a, nv + o + b) += (dt * dt) * dl[(size_t)a * d + b];
    }
    // Ml on the group's q rows and Ml^T on its q columns, upper entries only
    for (int p = 0; p < d; ++p) {
      const int row = o + p;
      double* Srow = S.data() + (size_t)row * nz;
      const double* Mp = ml.data() + (size_t)p * nz;
      for (int b = row; b < nz; ++b) Srow[b] += Mp[b];
      for (int a = 0; a <= row; ++a) S(a, row) += Mp[a];
    }
    dsym += d * dd;
    as += dd;
    jw += dn;
  }
}

// The variational step's velocity rows (t.variational), upper triangle of S: v+ = y with R(w, y) = 0
// over w = (eta, dv) and y, so sum_p lv_p F2_p = P^T T P with T = sum_i mu_i Ts_i, mu = -R_y^-T lv
// and P = [I_2nv 0; F1] (dynamics/variational.hpp, variational_node_factored; the projection is
// dyn::variational_projection_upper, which the dense expansion applies per row i, nv times).
static void variational_upper(const dyn::SecondOrderTerms& t, int k, const double* lv, RowMat& S) {
  const int nv = t.nv, nz = t.nz(), w = 3 * nv, nt = dyn::variational_upper_size(nv);
  thread_local Eigen::VectorXd mu;
  thread_local Eigen::MatrixXd T, G, CF;
  mu.noalias() = -(CMatMap(t.Minv.data() + (size_t)k * nv * nv, nv, nv) * CVecMap(lv, nv));
  T.resize(w, w);
  const double* ts = t.Ts.data() + (size_t)k * nt * nv;
  const double* u = mu.data();
  // one body (t.variational_separable): the (eta, dv)-y entries are zero, neither formed nor read
  const bool sep = t.variational_separable;
  const int n2 = 2 * nv;
  for (int a = 0, c = 0; a < w; ++a)
    for (int b = a; b < w; ++b, ++c) {
      if (sep && a < n2 && b >= n2) continue;
      const double* x = ts + (size_t)c * nv;
      double s = 0.0;
      for (int i = 0; i < nv; ++i) s += x[i] * u[i];
      T(a, b) = s;
      T(b, a) = s;
    }
  const CMatMap F1(t.F1.data() + (size_t)k * nv * nz, nv, nz);
  dyn::variational_projection_upper(T, F1, G, CF, [&](int a, int b, double s) { S(a, b) += s; }, sep);
}

// c = lv + dt Jr^T lq at node k (Jr the reconstruction's right Jacobian: the identity outside the
// SO(3)/SE(3) groups, their stored blocks on them): the weight with which the velocity update's second
// order enters S under the semi-implicit step (v+'' in the v rows, dt Jr v+'' in the q rows).
static void semi_implicit_weight(const dyn::SecondOrderTerms& t, int k, const CVecMap& lq, const CVecMap& lv,
                                 Eigen::VectorXd& c) {
  const double dt = t.dt;
  c = lv;
  c.noalias() += dt * lq;
  const double* jr = t.Jr.data() + (size_t)k * t.gJ;
  for (const JointGroup& g : t.groups) {
    const int o = g.idx_v, d = g.nv;
    c.segment(o, d) = lv.segment(o, d);
    c.segment(o, d).noalias() += dt * (CMatMap(jr, d, d).transpose() * lq.segment(o, d));
    jr += d * d;
  }
}

// A contact schedule's node (t.contact; dynamics/contact_second.cpp, contact_linearise_contracted),
// upper triangle of S: v+'' is the velocity rows of y'' = Kinv rhs (times dt at a contact node, whose
// semi-implicit reconstruction also adds dt Jr v+'' to the q rows; an impulse node keeps q), so
// both contract with w = dt c (c as for `semi` in contract_upper) or w = lv (impulse), and
// sum_i w_i y''_i = sum_r mu_r rhs_r with mu = Kt^T w (Kt: Kinv's first nv rows), which
// dyn::contact_kkt_upper forms from the factors.
static void contact_upper(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S) {
  const int nv = t.nv, ny = t.ny[(size_t)k], nyx = t.ny_max;
  const bool impulse = t.impulse[(size_t)k] != 0;
  const double dt = t.dt;
  thread_local Eigen::VectorXd c, mu;
  CVecMap lq(Vx, nv), lv(Vx + nv, nv);
  if (impulse) {
    c = lv;
  } else {
    semi_implicit_weight(t, k, lq, lv, c);
    c *= dt;
  }
  const double* kt = t.Kt.data() + (size_t)k * nv * nyx;
  mu.setZero(ny);
  for (int i = 0; i < nv; ++i) {
    const double ci = c[i];
    const double* row = kt + (size_t)i * nyx;
    for (int r = 0; r < ny; ++r) mu[r] += ci * row[r];
  }
  dyn::contact_kkt_upper(t, k, mu.data(), S.data());
  if (!impulse) reconstruction_upper(t, k, lq, S);
}

// S's upper triangle (the top-right n x m block is S_ux^T); the lower triangle is left as junk.
// With lq = Vx[:nv], lv = Vx[nv:]:
// * velocity rows (v+ = v + dt a): G2 = dt a_zz with a_zz = -Minv T, T_i = ID_zz,i + P_i + P_i^T,
//   P_i(j, b) = sum_l dM(i, l, j) a_z(l, b) on the q rows j (dynamics/euler.cpp, node_derivatives). The
//   semi-implicit reconstruction adds dt Jr F2 to the q rows, so both contract with
//   c = lv + [semi] dt Jr^T lq, and sum_p c_p F2_p = sum_i mu_i T_i with mu = -dt Minv c;
//   sum_i mu_i ID_zz,i and sum_i mu_i dM(i, ., .) come from the recursion of rigid_body/rnea_hessian.hpp
//   (t.recursion: articulated models) or are mu^T times Pinocchio's column-major tensors (one body,
//   or set_rnea_hessian_recursion(false));
//   for the variational step (t.variational) v+ is implicit instead: variational_upper;
// * reconstruction rows of each SO(3)/SE(3) group s (reconstruction_upper): dt^2 W_s^T (sum_p lq_p Dsym_p) W_s and
//   Ml = dt/2 As^T (sum_p lq_p C_p) JWs on the group's q rows plus its transpose (the dense
//   expansion in dynamics/expansion.cpp adds each dt/2 As^T C_p JWs, bracket_block; here the sum over p is
//   taken before the products).
// Why upper only: every consumer completes Qxx and Quu from their upper triangles, so the lower
// half (and the symmetric half of each product) would be work thrown away.
static void contract_upper(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S) {
  const int nv = t.nv, nz = t.nz(), nn = nv * nv;
  const double dt = t.dt;
  const size_t n3 = (size_t)nv * nn;
  // per-thread scratch: contract runs once per node in the sequential pass
  thread_local Eigen::VectorXd c, mu;
  thread_local std::vector<double> r4, R;
  CVecMap lq(Vx, nv), lv(Vx + nv, nv);
  S.setZero(nz, nz);
  if (t.contact) {
    contact_upper(t, k, Vx, S);
    return;
  }
  if (t.variational) {
    variational_upper(t, k, Vx + nv, S);
    reconstruction_upper(t, k, lq, S);
    return;
  }
  if (t.semi) semi_implicit_weight(t, k, lq, lv, c);
  else c = lv;
  mu.noalias() = (-dt) * (CMatMap(t.Minv.data() + (size_t)k * nn, nv, nv) * c);
  // rX[j + nv l] = sum_i mu_i X(i, j, l) for the four column-major tensors X (nv, nv, nv), in one
  // sweep (four independent sums per column; Eigen's four gemv calls cost more than their flops)
  r4.resize(4 * (size_t)nn);
  double *rqq = r4.data(), *rvv = rqq + nn, *rqv = rvv + nn, *rdm = rqv + nn;
  if (t.recursion) {  // the same four contractions by the recursion, from node k's stored terms
    dyn::rnea_hessian_at_node(t, k, mu.data(), r4.data());
  } else if (t.one_body) {  // one body: Ivv constant, Iqq only under gravity, Iqv = dM = 0
    const double *Xqq = t.one_body_gravity ? t.Iqq.data() + k * n3 : nullptr, *Xvv = t.Ivv.data();
    const double* w = mu.data();
    for (int col = 0; col < nn; ++col) {
      const size_t o = (size_t)col * nv;
      double a = 0.0, b = 0.0;
      for (int i = 0; i < nv; ++i) b += Xvv[o + i] * w[i];
      if (Xqq)
        for (int i = 0; i < nv; ++i) a += Xqq[o + i] * w[i];
      rqq[col] = a;
      rvv[col] = b;
      rqv[col] = 0.0;
      rdm[col] = 0.0;
    }
  } else {
    const double *Xqq = t.Iqq.data() + k * n3, *Xvv = t.Ivv.data() + k * n3, *Xqv = t.Iqv.data() + k * n3,
                 *Xdm = t.dM.data() + k * n3;
    const double* w = mu.data();
    for (int col = 0; col < nn; ++col) {
      const size_t o = (size_t)col * nv;
      double a = 0.0, b = 0.0, e = 0.0, f = 0.0;
      for (int i = 0; i < nv; ++i) {
        a += Xqq[o + i] * w[i];
        b += Xvv[o + i] * w[i];
        e += Xqv[o + i] * w[i];
        f += Xdm[o + i] * w[i];
      }
      rqq[col] = a;
      rvv[col] = b;
      rqv[col] = e;
      rdm[col] = f;
    }
  }
  for (int j = 0; j < nv; ++j) {
    double* Sj = S.data() + (size_t)j * nz;
    double* Svj = S.data() + (size_t)(nv + j) * nz + nv;
    for (int l = j; l < nv; ++l) {
      Sj[l] = 0.5 * (rqq[j + nv * l] + rqq[l + nv * j]);
      Svj[l] = 0.5 * (rvv[j + nv * l] + rvv[l + nv * j]);
    }
    for (int l = 0; l < nv; ++l) Sj[nv + l] = rqv[j + nv * l];
  }
  // Y(l, j) = sum_i mu_i dM(i, l, j); R = Y^T a_z (nv, nz) on the q rows, and its transpose on the
  // q columns: upper entries S(j, b) += R(j, b) (b >= j) + R(b, j) (b < nv). rdm read row-major is Y^T.
  if (t.one_body) {  // dM = 0: no (q, z) terms
    reconstruction_upper(t, k, lq, S);
    return;
  }
  R.resize((size_t)nv * nz);
  gemm::gemm(false, nv, nz, nv, 1.0, rdm, nv, t.az.data() + (size_t)k * nv * nz, nz, false, R.data(), nz);
  for (int j = 0; j < nv; ++j) {
    double* Sj = S.data() + (size_t)j * nz;
    const double* Rj = R.data() + (size_t)j * nz;
    for (int b = j; b < nz; ++b) Sj[b] += Rj[b];
    for (int b = j; b < nv; ++b) Sj[b] += R[(size_t)b * nz + j];
  }
  reconstruction_upper(t, k, lq, S);
}

void contract(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S) {
  contract_upper(t, k, Vx, S);
  for (Eigen::Index i = 1; i < S.rows(); ++i)
    for (Eigen::Index j = 0; j < i; ++j) S(i, j) = S(j, i);
}

// Qxx, Qux, Quu += S's blocks, reading S's upper triangle only (S from contract_upper): the passes
// complete Qxx and Quu from their upper triangles, so their lower halves need no sum. In the
// two-worker pass S is written on the other core, and every cache line of it read here crosses
// between cores; the lower half would be almost half of those lines.
static void add_upper(const RowMat& S, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
  const int n = (int)Qxx.rows(), m = (int)Quu.rows(), nz = n + m;
  for (int j = 0; j < n; ++j) {
    const double* Sj = S.data() + (size_t)j * nz;
    double* q = Qxx.data() + (size_t)j * n;
    for (int l = j; l < n; ++l) q[l] += Sj[l];
    for (int a = 0; a < m; ++a) Qux(a, j) += Sj[n + a];
  }
  for (int a = 0; a < m; ++a) {
    const double* Sa = S.data() + (size_t)(n + a) * nz + n;
    double* q = Quu.data() + (size_t)a * m;
    for (int b = a; b < m; ++b) q[b] += Sa[b];
  }
}

// Node k's second-order terms for a one-worker pass: Qxx (n, n) += S_xx, Qux (m, n) += S_ux, Quu
// (m, m) += S_uu with S = contract(t, k, Vx) (S the caller's scratch).
static void add_contracted(const dyn::SecondOrderTerms& t, int k, const Eigen::VectorXd& Vx, RowMat& S, RowMat& Qxx,
                           RowMat& Qux, RowMat& Quu) {
  contract_upper(t, k, Vx.data(), S);
  add_upper(S, Qxx, Qux, Quu);
}

// A short wait for the other worker of a two-worker pass: it hands over within microseconds, so
// spin (with the CPU's pause hint), and after a few microseconds yield the core at every check:
// if both workers share one core (a CPU quota, an oversubscribed machine), the other one runs
// then instead of after a scheduler slice (a slice per node makes the pass many times slower).
static inline void wait_a_little(int& spins) {
  if (++spins < 256) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  } else {
    std::this_thread::yield();
  }
}

// A pass on two workers. Node k's contraction needs only V_x' (the Vx of node k + 1), not Vxx,
// so worker 1 contracts node k while worker 0 finishes node k + 1 (feedback gains, Vxx) and forms
// node k's first-order blocks (q_blocks); worker 0 then adds S and factors. The arithmetic is the
// one-worker pass's, operation for operation: the results are bitwise equal (tested); only where
// contract_upper runs differs. One S and the pass's own Vx are shared without copies: worker 1
// reads Vx and writes S only between node k's hand-over and its S being ready, and worker 0 reads
// S and rewrites Vx only after that. run_pass(add, hand_over) runs the pass itself (unconstrained
// or box) on worker 0 with those two hooks and returns its failed node.
template <typename RunPass>
static int on_two_workers(int H, const dyn::SecondOrderTerms& t, RunPass&& run_pass) {
  RowMat S;
  const double* vx = nullptr;
  std::atomic<int> vx_ready{H}, s_ready{H};  // the node whose Vx is handed over / whose S is ready
  std::atomic<bool> done{false}, helper_failed{false};
  int failed = -1;
  const std::function<void(int)> task = [&](int worker) {
    if (worker == 1) {
      try {
        for (int k = H - 1; k >= 0; --k) {
          int spins = 0;
          while (vx_ready.load(std::memory_order_acquire) != k) {
            if (done.load(std::memory_order_acquire)) return;  // the pass stopped at a failed node
            wait_a_little(spins);
          }
          contract_upper(t, k, vx, S);
          s_ready.store(k, std::memory_order_release);
        }
      } catch (...) {
        helper_failed.store(true, std::memory_order_release);
        throw;  // the pool rethrows it to the caller
      }
      return;
    }
    const auto hand_over = [&](int k, const Eigen::VectorXd& Vx) {
      vx = Vx.data();
      vx_ready.store(k, std::memory_order_release);
    };
    const auto add = [&](int k, const Eigen::VectorXd&, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
      int spins = 0;
      while (s_ready.load(std::memory_order_acquire) != k) {
        if (helper_failed.load(std::memory_order_acquire)) throw std::runtime_error("contraction failed");
        wait_a_little(spins);
      }
      add_upper(S, Qxx, Qux, Quu);
    };
    try {
      failed = run_pass(add, hand_over);
    } catch (...) {
      done.store(true, std::memory_order_release);
      throw;
    }
    done.store(true, std::memory_order_release);
  };
  WorkerPool::get().run(2, task);
  return failed;
}

// workers = 0 ("auto"): which way a pass of this shape runs faster here, learnt from the passes
// themselves. The two-worker pass hands data between the cores once per node, and on a shared
// virtual machine that round trip varies several-fold over a day: when it is slow the two-worker
// pass takes as long as the one-worker pass or longer. Both ways give bitwise the same results, so
// choosing by time changes nothing else.
// Per problem shape (n, m, H, the size of the reconstruction's group blocks and whether the terms
// are the variational step's): a moving average of each way's time per node over whole passes (a
// pass that fails after a few nodes mostly measures the hand-over's start); the faster runs, and
// every 16th pass runs the other to follow the machine's changes.
namespace {
class WorkersChoice {
 public:
  // The process's (a forked child makes its own: the parent's mutex may have been held at the
  // fork, as runtime/pool.hpp does for the pool); never destroyed (passes may run at exit).
  static WorkersChoice& get() {
    static std::mutex guard;
    static WorkersChoice* c = nullptr;
    std::lock_guard<std::mutex> lk(guard);
    if (c == nullptr || c->pid_ != getpid()) c = new WorkersChoice;  // the parent's is abandoned
    return *c;
  }
  typedef std::array<int, 5> Shape;  // n, m, H, group block size, kind (1 variational, 2 contact: contractions differ)
  int choose(const Shape& shape) {
    std::lock_guard<std::mutex> lk(mutex_);
    Entry& e = entries_[shape];
    ++e.passes;
    if (e.ns_per_node[1] == 0.0) return 2;  // measure each way once first
    if (e.ns_per_node[0] == 0.0) return 1;
    const int faster = e.ns_per_node[1] <= e.ns_per_node[0] ? 2 : 1;
    return e.passes % 16 == 0 ? 3 - faster : faster;
  }
  void record(const Shape& shape, int workers, double ns_per_node) {
    std::lock_guard<std::mutex> lk(mutex_);
    double& x = entries_[shape].ns_per_node[workers - 1];
    x = x == 0.0 ? ns_per_node : 0.5 * (x + ns_per_node);
  }

 private:
  struct Entry {
    double ns_per_node[2] = {0.0, 0.0};  // one worker, two workers (0: not yet measured)
    unsigned passes = 0;
  };
  WorkersChoice() : pid_(getpid()) {}
  pid_t pid_;
  std::mutex mutex_;
  std::map<Shape, Entry> entries_;
};

// run(workers) with workers 1 or 2; for 0 the choice above, timed and, if the pass went through
// all H nodes, recorded.
template <typename Run>
int with_workers(int workers, int H, int n, int m, const dyn::SecondOrderTerms& t, Run&& run) {
  if (workers == 1 || workers == 2 || H <= 0) return run(workers == 2 && H > 0 ? 2 : 1);
  const WorkersChoice::Shape shape{n, m, H, t.gD, t.variational ? 1 : t.contact ? 2 : 0};
  WorkersChoice& choice = WorkersChoice::get();
  const int w = choice.choose(shape);
  const auto t0 = std::chrono::steady_clock::now();
  const int failed = run(w);
  const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
  if (failed < 0) choice.record(shape, w, ns / H);
  return failed;
}
}  // namespace

// A contracted pass with `workers` (0: with_workers's choice). run_pass(add, hand_over) runs the pass
// itself (unconstrained or box) with node k's second-order hook and the V_x' hand-over: on two
// workers those of on_two_workers, on one add_contracted and no hand-over (ric::NoHandOver).
template <typename RunPass>
static int contracted_pass(int workers, int H, int n, int m, const dyn::SecondOrderTerms& t, RunPass&& run_pass) {
  return with_workers(workers, H, n, m, t, [&](int w) {
    if (w == 2) return on_two_workers(H, t, run_pass);
    RowMat S;
    // sum_i V_x'_i Theta_i, Gamma_i^T, Xi_i (Remark rem:theta), contracted from the factors
    const auto add = [&](int k, const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu) {
      add_contracted(t, k, Vx, S, Qxx, Qux, Quu);
    };
    return run_pass(add, ric::NoHandOver());
  });
}

int backward_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                             const double* lu, const double* lxx, const double* lux, const double* luu,
                             const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                             double reg, int workers, double* k_ff, double* K_fb, double* quu_eig, double* d1,
                             double* d2) {
  return contracted_pass(workers, H, n, m, t, [&](const auto& add, const auto& hand_over) {
    return ric::unconstrained_pass(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, add, reg, k_ff, K_fb,
                                   quu_eig, d1, d2, hand_over);
  });
}

int box_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                        const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                        const double* Vxx_final, const dyn::SecondOrderTerms& t, double reg, const double* u_bar,
                        const double* lower, const double* upper, int workers, double* k_ff, double* K_fb,
                        double* quu_eig, signed char* active, double* Vx0, double* Vxx0, double* d1, double* d2) {
  return contracted_pass(workers, H, n, m, t, [&](const auto& add, const auto& hand_over) {
    // the box pass takes its hooks as std::function pointers; no hand-over on one worker
    const ric::SecondOrderHook second = add;
    const ric::HandOverHook h = hand_over;
    constexpr bool none = std::is_same_v<std::decay_t<decltype(hand_over)>, ric::NoHandOver>;
    return ric::backward_pass_box_hook(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, &second, reg,
                                       u_bar, lower, upper, k_ff, K_fb, quu_eig, active, Vx0, Vxx0, d1, d2,
                                       none ? nullptr : &h);
  });
}

int regularised_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                           const double* lu, const double* lxx, const double* lux, const double* luu,
                           const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                           double reg_increase, double reg_min, double reg_max, bool speculate, double* k_ff,
                           double* K_fb, double* quu_eig, double* spare_k, double* spare_K, double* spare_eig,
                           double* lam, double* d1, double* d2, int* restarts) {
  // a pass alone may use both workers (with `speculate`, the permission to use two; whether it does
  // is workers = 0's choice); two passes side by side get one each
  const int alone = speculate ? 0 : 1;
  const auto pass = [&](double reg, int workers, double* k, double* K, double* e, double* a, double* b) {
    return backward_pass_contracted(H, n, m, Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final, t, reg, workers, k,
                                    K, e, a, b);
  };
  *restarts = 0;
  int failed = pass(*lam, alone, k_ff, K_fb, quu_eig, d1, d2);
  if (failed < 0) return failed;
  // the ladder, one product at a time (the one-rung loop's values bit for bit), to the first rung
  // above reg_max
  std::vector<double> rungs{*lam};
  do rungs.push_back(std::max(rungs.back() * reg_increase, reg_min));
  while (rungs.back() <= reg_max);
  const int top = (int)rungs.size() - 1;

  struct Buffers {
    double *k, *K, *e;
  };
  const Buffers ws{k_ff, K_fb, quu_eig}, spare{spare_k, spare_K, spare_eig};
  std::vector<double> own;  // the lower probe's buffers once ws holds a factorised pass
  const auto take = [&](const Buffers& from, int f) {  // Workspace.take
    const size_t lo = (size_t)(f + 1);
    std::copy(from.k + lo * m, from.k + (size_t)H * m, k_ff + lo * m);
    std::copy(from.K + lo * m * n, from.K + (size_t)H * m * n, K_fb + lo * m * n);
    std::copy(from.e + lo, from.e + H, quu_eig + lo);
  };
  LadderSearch search(top, speculate);
  int probe[2];
  while (const int count = search.probes(probe)) {
    Buffers buf[2];
    if (!search.found) {
      buf[0] = ws;
      buf[1] = spare;
    } else {
      if (count == 2 && own.empty()) own.resize((size_t)H * m * (n + 1) + H);
      const Buffers mine{own.data(), own.data() + (size_t)H * m, own.data() + (size_t)H * m * (n + 1)};
      buf[0] = count == 2 ? mine : spare;
      buf[1] = spare;
    }
    int f[2] = {-1, -1};
    double a[2] = {0.0, 0.0}, b[2] = {0.0, 0.0};
    if (count == 2) {
      const std::function<void(int)> both = [&](int w) {
        f[w] = pass(rungs[probe[w]], 1, buf[w].k, buf[w].K, buf[w].e, &a[w], &b[w]);
      };
      WorkerPool::get().run(2, both);
    } else {
      f[0] = pass(rungs[probe[0]], alone, buf[0].k, buf[0].K, buf[0].e, &a[0], &b[0]);
    }
    const bool ok[2] = {f[0] < 0, f[1] < 0};
    const int i = search.record(probe, ok, count);
    if (i >= 0) {
      failed = -1;
      *d1 = a[i];
      *d2 = b[i];
      if (buf[i].k != k_ff) take(buf[i], -1);
    } else if (!search.found) {
      failed = f[count - 1];
      *d1 = a[count - 1];
      *d2 = b[count - 1];
      if (buf[count - 1].k != k_ff) take(buf[count - 1], failed);
    }
  }
  *restarts = search.found ? search.hi : top;
  *lam = rungs[*restarts];
  return failed;
}

}  // namespace ctr
}  // namespace geoddp
