// The second order of a multibody expansion in factored form (SecondOrderTerms): what the
// expansion (dynamics/expansion.cpp) writes per node and the contracted backward pass
// (riccati/contracted.hpp) contracts with V_x', instead of the dense tensors Theta, Gamma, Xi.
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <vector>

#include "lie/joint_groups.hpp"
#include "runtime/buffers.hpp"

namespace geoddp {
namespace dyn {

typedef pinocchio::Model Model;

// Entries in the upper triangle of a (3 nv, 3 nv) matrix: the variational step's residual Hessians
// over (eta, dv, y), per row of R.
inline int variational_upper_size(int nv) { return 3 * nv * (3 * nv + 1) / 2; }

// The upper triangle of P^T T P for a symmetric T (3 nv, 3 nv) over (eta, dv | y) and
// P = [I_2nv 0; F1] (3 nv, nz): the variational step's velocity update enters its second order
// only through P (R is affine in u). From T's blocks A (2nv, 2nv), Bm (2nv, nv), C (nv, nv):
//   E^T A E + E^T Bm F1 + (Bm F1)^T E + F1^T C F1,  E = [I_2nv 0] (2nv, nz),
// in coefficient-based loops (Eigen's blocked GEMM packs more than it computes at these sizes).
// sink(a, b, value) receives the entries a <= b in row-major order; G, CF are scratch. Used per row
// of R by the dense expansion (variational_node) and once per node by the contracted pass
// (riccati/contracted.cpp, on sum_i mu_i Ts_i). separable: Bm = 0 is known (one body,
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

// The second-order terms of the expansion kept in factored form, for contraction with V_x' in the
// backward pass (riccati/contracted.hpp) instead of forming Theta, Gamma, Xi (n^3 + n^2 m + n m^2 per
// node). Per node k (blocks of N nodes, each array node-major):
//   Iqq, Ivv, Iqv, dM (nv^3 each): Pinocchio's d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq at
//     (q_k, v_k, a_k), column-major as Pinocchio stores them (see node_derivatives, dynamics/euler.cpp);
//   Minv (nv, nv) full, az (nv, nz) = [ddq_dq ddq_dv Minv H], F1 (nv, nz) the velocity Jacobian,
//   all row-major;
//   for the variational step (`variational`: its velocity update is implicit, v+ = y with
//   R(eta, dv, y, u) = 0, dynamics/variational.hpp) instead of the four RNEA tensors and az: Ts
//   (variational_upper_size(nv), nv), the upper triangles of the symmetrised residual Hessians R_ww,i
//   (variational_node_factored), and Minv holds R_y^-T; its reconstruction is explicit Euler's;
//   per SO(3)/SE(3) joint group g (offset o, dimension d), in the order of `groups`:
//     Jr (d, d): the reconstruction's right Jacobian block at dt w_bar;
//     Dsym (d, d, d): [p][a][c] = sym_(a,c) dJr[p, a] / d omega_c (the 1/2 dJr[rho] rho term);
//     As (d, d) and JWs (d, nz): the group's blocks of Ad_exp(-dt w_bar) and of Jr W (W the
//     velocity increment's Jacobian), the factors of the 1/2 [A eta, Jr rho] term, whose
//     contraction sum_p lq_p dt/2 As^T C_p JWs (C_p the structure constants) the pass forms as
//     dt/2 As^T (sum_p lq_p C_p) JWs: d^2 + d nz numbers per group instead of d^2 nz.
// Each array is a Buffer (runtime/buffers.hpp): recycled between linearisations, uninitialised.
struct SecondOrderTerms {
  int N = 0, nv = 0, m = 0;
  double dt = 0.0;
  bool semi = false, variational = false;
  // RNEA's contracted second derivatives come from the recursion of rigid_body/rnea_hessian.hpp inside the
  // pass, from each node's mu-free terms (rnea, N x rnea_hessian_node_size doubles, made by the expansion in
  // parallel), instead of Pinocchio's tensors Iqq, Ivv, Iqv, dM (left empty): every articulated model with an
  // Euler scheme, unless set_rnea_hessian_recursion(false). `model` is the expansion's, `id` new at every
  // resize (the pass's per-thread work is kept per id).
  bool recursion = false;
  const Model* model = nullptr;
  unsigned long long id = 0;
  // One body on a free-flyer or spherical root (rigid_body/one_body.hpp): d2tau_dqdv = d2tau_dadq = 0 and
  // d2tau_dvdv constant, so Iqv and dM are left empty, Ivv holds the one constant tensor (nv^3),
  // and Iqq holds one tensor per node with gravity (one_body_gravity) and is empty without.
  bool one_body = false, one_body_gravity = false;
  // The variational step of one body (VariationalModel::configuration_free): R_y depends on y alone,
  // so the residual Hessians' (eta, dv)-y blocks are exactly zero and the contraction skips them.
  bool variational_separable = false;
  // A contact schedule's nodes (dynamics/contact_second.cpp, contact_linearise_contracted) instead of
  // free multibody steps. Node k's KKT system E(s, y) = 0 (ny[k] = nv + 3 nf rows for its nf feet,
  // y = (a, lambda) or (v+, Lambda)) has y'' = Kinv rhs, rhs_r = E_ss,r + P_r + P_r^T on the (s, s)
  // block and P_r on the (s, u) block, P_r = E_sy,r Y1. The pass needs them only as sum_r mu_r rhs_r
  // with mu = Kt^T w, so they are kept as factors, each node's block sized for nf_max feet
  // (ny_max = nv + 3 nf_max rows):
  //   Kt (nv, ny_max): Kinv's first nv rows (the velocity update's); Yz (ny, nz) = dy/dz;
  //   the RNEA rows (the first nv) as the recursion's mu-free terms of rigid_body/rnea_hessian.hpp
  //   (`rnea`, N x rnea_hessian_node_size): the robot's at (q, v, a), or at an impulse node the
  //   robot's without gravity at (q, 0, v+ - v) (its M(q) (v+ - v)); per foot i, its force's
  //   curvature J_w,i^T lambda_i on the RNEA rows as the point-force recursion reads it
  //   (rnea_hessian_point_force): the foot's world point p and lambda (`force`, N x nf_max x 6) and
  //   its joint (foot_joint, N x nf_max);
  //   the feet's rows (3 per foot) of E_ss and of their acceleration's q-a derivative Pqa on the
  //   foot's chain (the dofs that move it, `chains[foot_chain[k nf_max + i]]`, increasing: every
  //   other entry is zero), n of them, sized for chain_max: Ess (3, 2n (2n + 1) / 2) per foot, E_ss
  //   over the chain's (q, v) symmetrised, its upper triangle row by row; Pqa (3, n, n) per foot,
  //   Pqa[c][j][l] = d J_w[c, vi[l]] / d q_vi[j], which is also E_sy's entry between the q rows and
  //   lambda's columns of the RNEA rows (with a minus sign);
  // the pass contracts the RNEA rows by the recursion (nv^2 work per model instead of the ny ns^2
  // entries of stored rows) and the feet's rows from Ess and Pqa (contracted.cpp, contact_upper).
  // A contact node's step is semi-implicit Euler (F1, Jr, Dsym, As, JWs as for `semi`, v+'' =
  // dt a''); an impulse node's (impulse[k]) is x+ = (q, v+): no reconstruction, v+'' read directly.
  bool contact = false;
  int ny_max = 0, nf_max = 0, chain_max = 0;
  std::vector<int> ny;
  std::vector<char> impulse;
  std::vector<int> foot_joint, foot_chain;
  std::vector<std::vector<int>> chains;
  Buffer Kt, Ess, Pqa, Yz, force;
  std::vector<JointGroup> groups;  // the SO(3)/SE(3) groups only
  int gJ = 0, gD = 0, gW = 0;      // per-node sizes of the group blocks (Jr and As: gJ each)
  Buffer Iqq, Ivv, Iqv, dM, Minv, az, F1, Jr, Dsym, As, JWs, Ts, rnea;
  int nz() const { return 2 * nv + m; }
  void resize(const Model& model, int m_, int N_, double dt_, bool semi_, bool variational_ = false,
              bool recursion_ = false, bool one_body_ = false, bool one_body_gravity_ = false);
  // For a contact schedule (contact = true): F1 and the group blocks, rnea, force, Kt, Ess, Pqa, Yz for
  // nf_max feet per node on the given chains (each foot's dofs, increasing).
  void resize_contact(const Model& model, int m_, int N_, double dt_, int nf_max_,
                      std::vector<std::vector<int>> chains_);
  // Entries of a foot row of Ess: the upper triangle of the (2 chain_max)-square (q, v) block.
  size_t chain_upper() const { return (size_t)chain_max * (2 * chain_max + 1); }

 private:
  void resize_layout(const Model& model, int m_, int N_, double dt_, bool semi_);
};

// Whether expansion_contracted leaves RNEA's second order to the recursion of rigid_body/rnea_hessian.hpp
// (default) or stores Pinocchio's tensors (ComputeRNEASecondOrderDerivatives per node), for every
// articulated model with an Euler scheme; one-body models keep their shortcut (rigid_body/one_body.hpp). The
// two agree to round-off (tests/test_core_rnea_hessian.py); the switch is for tests and benchmarks.
void set_rnea_hessian_recursion(bool on);
bool rnea_hessian_recursion();

// For the contracted pass (t.recursion): RNEA's second derivatives at node k contracted with mu (nv)
// by the recursion of rigid_body/rnea_hessian.hpp, from the node's stored terms, into r4 (4 nv^2, each
// (nv, nv) column-major: sum_i mu_i X(i, j, l) at j + nv l for X = d2tau_dqdq, d2tau_dvdv,
// d2tau_dqdv, d2tau_dadq). Keeps one work and Data per thread and set of terms (rigid_body/rnea_hessian.cpp).
void rnea_hessian_at_node(const SecondOrderTerms& t, int k, const double* mu, double* r4);
// For a contact node k: adds to Hqq (nv, nv, column-major) the point-force recursion's contraction
// (rnea_hessian_point_force) with mu of each of its nf feet's J_w,i^T lambda_i, from t.force.
void point_forces_at_node(const SecondOrderTerms& t, int k, int nf, const double* mu, double* Hqq);

// A contact node k's KKT second order contracted with mu (ny[k]): sum_r mu_r rhs_r (the (nz, nz)
// symmetric matrix of sum_r mu_r E_y^-1-free right-hand sides, whose (u, u) block is zero), its upper
// triangle added into S (nz, nz, row-major; the lower triangle is not written). With A = sum_r mu_r
// E_ss,r (ns, ns), Bq = sum_r mu_r E_sy,r's q rows (nv, ny) and P = Bq Y1 (nv, nz), it is A + P~ +
// P~^T on the (s, s) block and P~ on the (s, u) block (P~ = [P; 0]). From the factors, with
// mu = (mu_a (nv), mu_c (3 nf)):
// * the RNEA rows by the recursion (rigid_body/rnea_hessian.hpp) with mu_a: Hqq, Hvv, Hqv, Dm of the
//   robot's terms, minus each foot's J_w^T lambda curvature (rnea_hessian_point_force);
//   A gets sym(Hqq) - sum_f sym(Hqq_f), Hqv and sym(Hvv) at a contact node, and -Dm^T in the
//   (q, v) block at an impulse node (its RNEA reads a = v+ - v); Bq's a columns get Dm^T;
// * the feet's rows: A += sum_c mu_c Ess_c; with Pqa's rows (Pqa_c[j][l] = d J_w[c, l] / d q_j),
//   Bq(j, l) += sum_c mu_c Pqa_c[j][l] (their E_sy) and Bq(j, nv + c) = -sum_l Pqa_c[j][l] mu_a,l
//   (the RNEA rows' -J_w^T lambda along lambda).
// The pass calls it with mu = Kt^T w (riccati/contracted.cpp), the expansion with the friction
// cone's weights on the force rows (contact_second.cpp): one contraction for both.
void contact_kkt_upper(const SecondOrderTerms& t, int k, const double* mu, double* S);

}  // namespace dyn
}  // namespace geoddp
