// Multibody dynamics kernels over a whole trajectory: arrays in, arrays out.
//
// C++ twins of geoddp.models.multibody.Multibody (rollout, velocity_derivatives, expansion) and
// of the forward pass of geoddp.multibody_problem.MultibodyProblem.rollout_closed_loop, for the
// integrators "euler" (paper eq. disceq: q+ = q exp(dt v)) and "semi_implicit" (q+ = q exp(dt v+)),
// both with v+ = v + dt aba(q, v, H u), and "rk4" (cpp/rkmk4.hpp).
//
// Every array is float64, C-contiguous (row-major), shapes as documented per function. The
// tangent state is zeta = (dq, dv), n = 2 nv, z = (dq, dv, du), nz = n + m. Nothing here imports
// Python: the kernels take a const pinocchio::Model& (see pin_model.hpp for the conversion).
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "joint_groups.hpp"

namespace geoddp {
namespace dyn {

typedef pinocchio::Model Model;

// RK4: the Runge-Kutta-Munthe-Kaas step of cpp/rkmk4.hpp (rollout, forward pass, expansion; not
// velocity_derivatives or the factored second order, which are the Euler schemes' structure).
// VARIATIONAL: the forward variational Euler step of cpp/variational.hpp (rollout, forward pass and
// expansion: its implicit velocity derivatives with the explicit-Euler reconstruction).
enum Integrator { EULER = 0, SEMI_IMPLICIT = 1, RK4 = 2, VARIATIONAL = 3 };

// Inputs shared by every kernel. H: actuation (nv, m) row-major; dt: time step (s).
struct Setup {
  const Model* model;
  const double* H;
  int m;
  double dt;
  Integrator integrator;
};

// Open-loop rollout: q0 (nq), v0 (nv), U (N, m) -> Q (N+1, nq), V (N+1, nv) (caller-allocated).
void rollout(const Setup& s, const double* q0, const double* v0, const double* U, int N, double* Q, double* V);

// Forward pass of Algorithm 1 (eq. dustar): u_k = u_bar_k - gamma k_k - K_k zeta_k, zeta_k =
// (difference(q_bar_k, q_k) with exact SO(2) entries, v_k - v_bar_k). Qbar (N+1, nq), Vbar
// (N+1, nv), Ubar (N, m), kff (N, m), K (N, m, 2 nv); writes Qout, Vout (N+1, .), Uout (N, m).
// Returns false (and stops) as soon as a state is non-finite or, with the variational step, an
// implicit step does not converge (a trial the line search rejects), as the Python path does.
// With control limits lower, upper (N, m) (issue 15; both or neither), u_k is clamped into
// [lower_k, upper_k] after the feedback law, before it is applied and stored (NaN stays NaN).
bool rollout_closed_loop(const Setup& s, const double* q0, const double* v0, const double* Qbar,
                         const double* Vbar, const double* Ubar, const double* kff, const double* K,
                         double gamma, int N, double* Qout, double* Vout, double* Uout,
                         const double* lower = nullptr, const double* upper = nullptr);

// Derivatives of v+ = v + dt aba(q, v, H u) w.r.t. z at N nodes: Q (N, nq), V (N, nv), U (N, m)
// -> F1 (N, nv, nz), and for order 2 F2 (N, nv, nz, nz), the symmetric (0)-Hessian (exact: from
// computeABADerivatives and ComputeRNEASecondOrderDerivatives, no differences).
void velocity_derivatives(const Setup& s, const double* Q, const double* V, const double* U, int N,
                          int order, int threads, double* F1, double* F2);

// Phi (N, n, n), B (N, n, m) and for order 2 Theta (N, n, n, n), Gamma (N, n, n, m),
// Xi (N, n, m, m) at the N nodes of a rollout Q (N+1, nq), V (N+1, nv), U (N, m):
// zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.
// Same meaning and layout as geoddp.models.multibody.Multibody.expansion.
void expansion(const Setup& s, const double* Q, const double* V, const double* U, int N, int order,
               int threads, double* Phi, double* B, double* Theta, double* Gamma, double* Xi);

// Pinocchio's second-order RNEA tensors at (q (nq), v (nv), a (nv)): d2tau_dqdq, d2tau_dvdv,
// d2tau_dqdv, d2tau_dadq, nv^3 each, column-major as Pinocchio stores them ((i, j, k) at
// i + nv (j + nv k)). With one_body, from the one-body shortcut the expansions use (one_body.hpp;
// std::invalid_argument if the model is not one body on a free-flyer or spherical root). For the tests.
void rnea_second_order(const Model& model, const double* q, const double* v, const double* a, bool one_body,
                       double* Iqq, double* Ivv, double* Iqv, double* dM);
// Whether the expansions take RNEA's second-order tensors from the one-body shortcut for `model`.
bool one_body_applies(const Model& model);

// The second-order terms of the expansion kept in factored form, for contraction with V_x' in the
// backward pass (cpp/contracted.hpp) instead of forming Theta, Gamma, Xi (n^3 + n^2 m + n m^2 per
// node). Per node k (blocks of N nodes, each array node-major):
//   Iqq, Ivv, Iqv, dM (nv^3 each): Pinocchio's d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq at
//     (q_k, v_k, a_k), column-major as Pinocchio stores them (see node_derivatives in dynamics.cpp);
//   Minv (nv, nv) full, az (nv, nz) = [ddq_dq ddq_dv Minv H], F1 (nv, nz) the velocity Jacobian,
//   all row-major;
//   for the variational step (`variational`: its velocity update is implicit, v+ = y with
//   R(eta, dv, y, u) = 0, variational.hpp) instead of the four RNEA tensors and az: Ts
//   (variational_upper_size(nv), nv), the upper triangles of the symmetrised residual Hessians R_ww,i
//   (variational_node_factored), and Minv holds R_y^-T; its reconstruction is explicit Euler's;
//   per SO(3)/SE(3) joint group g (offset o, dimension d), in the order of `groups`:
//     Jr (d, d): the reconstruction's right Jacobian block at dt w_bar;
//     Dsym (d, d, d): [p][a][c] = sym_(a,c) dJr[p, a] / d omega_c (the 1/2 dJr[rho] rho term);
//     As (d, d) and JWs (d, nz): the group's blocks of Ad_exp(-dt w_bar) and of Jr W (W the
//     velocity increment's Jacobian), the factors of the 1/2 [A eta, Jr rho] term, whose
//     contraction sum_p lq_p dt/2 As^T C_p JWs (C_p the structure constants) the pass forms as
//     dt/2 As^T (sum_p lq_p C_p) JWs: d^2 + d nz numbers per group instead of d^2 nz.
// An uninitialised float64 buffer: every entry is written before it is read, and zeroing
// megabytes per linearisation (4 nv^3 per node) cost as much as filling them.
// Its memory is recycled (buffer_take / buffer_give, dynamics.cpp): every exact linearisation
// makes a new SecondOrderTerms of the same sizes, and fresh megabytes from the system cost page
// faults and the kernel's zeroing (about 4 ms of Solo12's 15 ms expansion, measured), so a
// released buffer waits in a small pool for the next request of its size.
double* buffer_take(size_t n);
void buffer_give(double* p, size_t n);
struct Buffer {
  double* p = nullptr;
  size_t n = 0;
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer() { buffer_give(p, n); }
  void resize(size_t k) {
    if (k == n) return;
    buffer_give(p, n);
    p = buffer_take(k);
    n = k;
  }
  double* data() { return p; }
  const double* data() const { return p; }
  size_t size() const { return n; }
};

// Entries in the upper triangle of a (3 nv, 3 nv) matrix: the variational step's residual Hessians
// over (eta, dv, y), per row of R.
inline int variational_upper_size(int nv) { return 3 * nv * (3 * nv + 1) / 2; }

// The upper triangle of P^T T P for a symmetric T (3 nv, 3 nv) over (eta, dv | y) and
// P = [I_2nv 0; F1] (3 nv, nz): the variational step's velocity update enters its second order
// only through P (R is affine in u). From T's blocks A (2nv, 2nv), Bm (2nv, nv), C (nv, nv):
//   E^T A E + E^T Bm F1 + (Bm F1)^T E + F1^T C F1,  E = [I_2nv 0] (2nv, nz),
// in coefficient-based loops (Eigen's blocked GEMM packs more than it computes at these sizes).
// sink(a, b, value) receives the entries a <= b in row-major order; G, CF are scratch. Used per row
// of R by the dense expansion (variational.cpp) and once per node by the contracted pass
// (contracted.cpp, on sum_i mu_i Ts_i). separable: Bm = 0 is known (one body,
// SecondOrderTerms::variational_separable), so its product is skipped and T's Bm block not read.
template <class F1Type, class Sink>
inline void variational_projection_upper(const Eigen::MatrixXd& T, const F1Type& F1, Eigen::MatrixXd& G,
                                         Eigen::MatrixXd& CF, Sink&& sink, bool separable = false) {
  const int nv = (int)F1.rows(), nz = (int)F1.cols(), n2 = 2 * nv;
  if (!separable) G.noalias() = T.topRightCorner(n2, nv).lazyProduct(F1);  // Bm F1 (2nv, nz)
  CF.noalias() = T.bottomRightCorner(nv, nv).lazyProduct(F1);                // C F1 (nv, nz)
  for (int a = 0; a < nz; ++a)
    for (int b = a; b < nz; ++b) {
      double s = 0.0;  // (F1^T C F1)(a, b)
      for (int l = 0; l < nv; ++l) s += F1(l, a) * CF(l, b);
      if (!separable) {
        if (a < n2) s += G(a, b);
        if (b < n2) s += G(b, a) + T(a, b);  // b < 2nv implies a < 2nv
      } else if (b < n2) {
        s += T(a, b);  // what G(b, a) + T(a, b) is when G = 0
      }
      sink(a, b, s);
    }
}

struct SecondOrderTerms {
  int N = 0, nv = 0, m = 0;
  double dt = 0.0;
  bool semi = false, variational = false;
  // RNEA's contracted second derivatives come from the recursion of rnea_hessian.hpp inside the pass,
  // from each node's mu-free terms (rnea, N x rnea_hessian_node_size doubles, made by the expansion
  // in parallel), instead of Pinocchio's tensors Iqq, Ivv, Iqv, dM (left empty): every articulated
  // model with an Euler scheme, unless set_rnea_hessian_recursion(false). `model` is the
  // expansion's, `id` new at every resize (the pass's per-thread work is kept per id).
  bool recursion = false;
  const Model* model = nullptr;
  unsigned long long id = 0;
  // One body on a free-flyer or spherical root (one_body.hpp): d2tau_dqdv = d2tau_dadq = 0 and
  // d2tau_dvdv constant, so Iqv and dM are left empty, Ivv holds the one constant tensor (nv^3),
  // and Iqq holds one tensor per node with gravity (one_body_gravity) and is empty without.
  bool one_body = false, one_body_gravity = false;
  // The variational step of one body (VariationalModel::configuration_free): R_y depends on y alone,
  // so the residual Hessians' (eta, dv)-y blocks are exactly zero and the contraction skips them.
  bool variational_separable = false;
  std::vector<JointGroup> groups;  // the SO(3)/SE(3) groups only
  int gJ = 0, gD = 0, gW = 0;      // per-node sizes of the group blocks (Jr and As: gJ each)
  Buffer Iqq, Ivv, Iqv, dM, Minv, az, F1, Jr, Dsym, As, JWs, Ts, rnea;
  int nz() const { return 2 * nv + m; }
  void resize(const Model& model, int m_, int N_, double dt_, bool semi_, bool variational_ = false,
              bool recursion_ = false, bool one_body_ = false, bool one_body_gravity_ = false);
};

// Whether expansion_contracted leaves RNEA's second order to the recursion of rnea_hessian.hpp
// (default) or stores Pinocchio's tensors (ComputeRNEASecondOrderDerivatives per node), for every
// articulated model with an Euler scheme; one-body models keep their shortcut (one_body.hpp). The
// two agree to round-off (tests/test_core_rnea_hessian.py); the switch is for tests and benchmarks.
void set_rnea_hessian_recursion(bool on);
bool rnea_hessian_recursion();

// For the contracted pass (t.recursion): RNEA's second derivatives at node k contracted with mu (nv)
// by the recursion of rnea_hessian.hpp, from the node's stored terms, into r4 (4 nv^2, each
// (nv, nv) column-major: sum_i mu_i X(i, j, l) at j + nv l for X = d2tau_dqdq, d2tau_dvdv,
// d2tau_dqdv, d2tau_dadq). Keeps one work and Data per thread and set of terms (rnea_hessian.cpp).
void rnea_hessian_at_node(const SecondOrderTerms& t, int k, const double* mu, double* r4);

// Phi (N, n, n), B (N, n, m) exactly as expansion(order=1), and the factored second-order terms.
void expansion_contracted(const Setup& s, const double* Q, const double* V, const double* U, int N, int threads,
                          double* Phi, double* B, SecondOrderTerms& terms);

// Reconstruction blocks at omega (nv): Ad_exp(-omega) and Jr(omega), each (nv, nv) row-major
// (geoddp.configuration.block_Ad_Jr), and D (nv, nv, nv) with D[i, j, l] = d Jr[i, j] / d omega_l
// (geoddp.configuration.second_order_tensors' D, exact).
void block_ad_jr(const std::vector<JointGroup>& groups, int nv, const double* omega, double* A, double* Jr,
                 double* D);

// Worker threads of a pass when threads <= 0 ("default"): min(2, cores in the process's affinity
// mask), and at least 16 nodes per worker (workers come from a persistent pool, cpp/pool.hpp).
int default_threads();

// Runs fn(begin, end) on contiguous chunks of [0, N) with `threads` workers (<= 0: the default,
// at least 16 nodes per worker) of the persistent pool; the chunks depend only on N and the worker
// count, so per-node results do not depend on the number of threads.
void parallel_nodes(int N, int threads, const std::function<void(int, int)>& fn);

// How many workers parallel_nodes uses for N nodes (per-worker scratch is sized by it), and
// parallel_nodes with the worker's index 0 .. node_workers(N, threads) - 1 passed to fn.
int node_workers(int N, int threads);
void parallel_nodes_indexed(int N, int threads, const std::function<void(int, int, int)>& fn);

}  // namespace dyn
}  // namespace geoddp
