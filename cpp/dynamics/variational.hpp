// The paper's forward variational Euler step (implicit transition dynamics, eq. disceq1/receq1/
// dynamicseq1) on a Pinocchio model, and its derivatives by implicit differentiation (eq. firstimp
// and the Hessian after it): C++ twin of the tests' oracle VariationalEuler (tests/oracle_variational.py;
// geoddp.variational's docstring for the residual R(q, v, y, u) = 0 that defines y = v+).
//
// What the compiled version computes exactly where the Python one differences: the trivialised
// Hessian of the kinetic energy in q (the q-derivative of D(q, y)^T y, D = d(M(q) y)/dq) comes
// from a spatial-vector recursion (rigid_body/kinetic_hessian.hpp) instead of central differences of D. So
// the residual's Jacobian [R_eta, R_dv, R_y] is analytic throughout, and the second-order term
// R_ww is at most one central difference of it (not the Python oracle's difference of a
// difference): F2 = -R_y^-1 P^T R_ww P. Its columns are exact (product and chain rules on the
// base point's terms; the x-derivatives of d/dx[K(x)^T p] on each SO(3) or SE(3) group's block by
// implicit differentiation of Jr^T u = p, with Jr's second derivatives from lie/right_jacobians.hpp's
// jr_transpose_hessian) but for two differenced parts of an articulated model: the kinetic-energy
// Hessian along q+'s own joint directions (QplusLinear: q+'s first-order model, which the eta and
// dv columns read by the chain rule), and the whole Jacobian along the root's pose under gravity.
// One body on a free-flyer or spherical root: exact throughout. Along eta's joint directions M(q)
// and D(q, v) move with the tensors dM/dq and d/dq D of
// rigid_body/kinetic_hessian.hpp's recursion at q; along y only R_y moves, the other entries of those
// directions being the mixed partials already taken along eta and dv.
//
// Arrays as in dynamics/trajectory.hpp: float64, row-major; z = (dq, dv, du), nz = 2 nv + m.
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <Eigen/LU>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "dynamics/trajectory.hpp"
#include "rigid_body/kinetic_hessian.hpp"

namespace geoddp {
namespace dyn {

// Newton's method for the implicit velocity update did not converge (dt too large). what() is
// |v| at the step, formatted %.3g (the Python wrapper writes the message, naming dt).
struct StepNotConverged : std::runtime_error {
  explicit StepNotConverged(const std::string& what) : std::runtime_error(what) {}
};

// Central-difference step of R_ww: the Jacobian differenced is analytic (round-off ~1e-16 / h,
// truncation ~h^2: both ~1e-10 at 1e-5).
constexpr double VARIATIONAL_FD_STEP = 1e-5;

// The model and its gravity-free copy (for D(q, w)), shared read-only by every worker.
struct VariationalModel {
  const Model* model;
  Model free_model;
  std::vector<JointGroup> groups;
  const double* H;  // (nv, m) row-major
  int m;
  double dt;
  // one body on a free-flyer or spherical root (rigid_body/one_body.hpp): the gravity-free model's tau does not
  // depend on q, so D(q, w) and the kinetic-energy Hessian are zero and Pinocchio's calls are skipped
  bool configuration_free;
  // The velocity dofs of a free-flyer (6) or spherical (3) first joint, else 0. Perturbing them,
  // q exp(h e_j), moves that joint's whole subtree rigidly: M, D and the kinetic-energy Hessian
  // (local frames, gravity-free model) do not change, only the gravity terms do; with no gravity
  // (gravity_free) R's Jacobian does not change at all. One body: all of its nv dofs.
  int root_dirs;
  bool gravity_free;
  // per velocity dof: it belongs to a commutative group (vector, SO(2)), along which the residual
  // Jacobian moves linearly in dv and y (residual_hessians takes those columns exactly)
  std::vector<char> flat_dof;
  Eigen::MatrixXd M_body;  // configuration_free: the constant mass matrix (nv, nv)
  VariationalModel(const Model& model_, const double* H_, int m_, double dt_);
};

// Per-worker scratch: every matrix and vector a step or a Jacobian needs, sized once (no
// allocation per call).
struct VariationalWork {
  pinocchio::Data data, fdata;
  KineticHessianWork kh;
  Eigen::MatrixXd M0, M1, K0, K1, D0, D1, A, Jv, Jr, Kt, S, N, Hk, Hkin, J, Jp, T, Sq, Ry, Kx, P1, P2;
  Eigen::VectorXd qn, y, r, g1, b, tmp, s, x, omega, r0, rt, yt, dy, xi, grad;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  // dM/dq and d/dq D(q+, y) (nv^3 each, column-major as Pinocchio's d2tau_dadq, d2tau_dqdq at
  // (q+, 0, y); mass_tensors) at the base point: residual_hessians' exact q+ terms and D(q+, e_l)
  std::vector<double> dMdq, d2q;
  explicit VariationalWork(const VariationalModel& vm);
};

// One step: q (nq), v (nv), tau (nv) -> q1 (nq), v1 (nv). Throws StepNotConverged.
void variational_step(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1);

// The residual Jacobian's q+-dependent parts near a node's q+, to first order: with xi = difference(q+, q+')
// (nv), Sq(q+') = Sq0 + sum_k xi_k dSq[k] and R_y(q+') = Ry0 + sum_k xi_k dRy[k] (Sq = dR/deta+; y fixed).
// R_ww's columns along eta and dv move q+ only through these (the chain rule at d xi; the root's pose under
// gravity: central differences of the Jacobian, equal to those of the exact terms to O(h^2);
// dynamics/variational_hessian.cpp, residual_hessians), and q+'s nv directions are taken once instead of each
// of eta's and dv's: dRy exactly (from the base point's dM/dq and d2tau/dq2), dSq with only its
// kinetic-energy Hessian and gravity part differenced (exactly along the root's pose).
struct QplusLinear {
  Eigen::VectorXd qn, xi;
  Eigen::MatrixXd Sq0, Ry0;
  std::vector<Eigen::MatrixXd> dSq, dRy;
  std::vector<char> dSq_zero, dRy_zero;  // exactly zero (the root's pose moves the model rigidly)
  bool fixed = false;    // every dSq and dRy zero: Sq and R_y do not move (one body, no gravity)
  bool Sq_zero = false;  // and Sq0 = 0 (no D, no kinetic-energy Hessian, no gravity): R_eta = 0
};

// d/dx [K(x)^T p] (K = Jr(x)^-1, block-diagonal over the joint groups) at one x, for any p: the
// map is linear in p, zero outside the SO(3) and SE(3) groups' diagonal blocks, and there
// -K^T N, N(:, c) = (dJr/dx_c)^T K^T p, so column c is C_c p with C_c = -K^T dJr_c^T K^T, formed once
// at x from dJr's matrices (lie::so3_djr, se3_djr). residual_hessians applies it about 2 nv times a
// node at each of two points (x = dt v and -dt y), where each call would re-evaluate the closed-form
// gradients, their coefficients and the dense block products (dynamics/variational_residual.cpp's dKT).
struct KtMap {
  struct Block {
    int o, n;                          // offset and size (3 or 6) of the group's velocity block
    Eigen::Matrix<double, 6, 6> C[6];  // the top-left n x n of each, c < n
    Eigen::Matrix<double, 6, 6> D[6];  // dJr/dx_c on the block (top-left n x n), which residual_hessians also reads
  };
  std::vector<Block> blocks;
  // at x, with K = Jr(x)^-1 (nv x nv, the blocks() of x)
  void set(const std::vector<JointGroup>& groups, const Eigen::VectorXd& x, const Eigen::MatrixXd& K);
  // out = d/dx [K(x)^T p] (nv x nv)
  void apply(const Eigen::VectorXd& p, Eigen::MatrixXd& out) const;
  // the dJr matrices of the group block at velocity offset o (nullptr if none is there)
  const Eigen::Matrix<double, 6, 6>* djr(int o) const {
    for (const Block& b : blocks)
      if (b.o == o) return b.D;
    return nullptr;
  }
};

// Scratch of variational_node beyond VariationalWork (the second order's buffers).
struct VariationalNodeWork {
  VariationalWork w;
  Eigen::VectorXd qp, e, vp;
  Eigen::MatrixXd Rz, F1k, Jm, Tj, Ts, G, CF, stack;
  std::vector<Eigen::MatrixXd> T;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_y;  // R_y at the node
  Eigen::MatrixXd Dbase, Dl;                  // D(q, v) at the base point, D(., e_l)
  QplusLinear lin;
  // the base call's M(q+); the kinetic-energy Hessian at q+ exp(h e_k)
  Eigen::MatrixXd M1b, Hp;
  // dM/dq and d2tau/dq2 at (q, 0, v) (nv^3 each, as VariationalWork's at q+): the exact columns of
  // R_ww along eta's joint directions and D(q, e_l) along dv
  std::vector<double> dMq, d2qq;
  Eigen::MatrixXd dSqj, dRyj, X;  // scratch of those columns
  KtMap kt0, kt1;                 // d/dx[K(x)^T p] at x = dt v (K0) and x = -dt y (K1)
  // a copy of the model whose gravity residual_hessians turns (the root's rotation directions;
  // made only for a free-flyer or spherical root under gravity)
  struct TurnedGravity {
    Model model;
    pinocchio::Data data;
    explicit TurnedGravity(const Model& m) : model(m), data(model) {}
  };
  std::unique_ptr<TurnedGravity> turned;
  explicit VariationalNodeWork(const VariationalModel& vm);
};

// One node: F1 (nv, nz) row-major and, if F2 != nullptr, F2 (nv, nz, nz) row-major, symmetric,
// at (q, v) with the solved v+ = y.
void variational_node(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, double* F2);

// One node in factored form, for the backward pass to contract with V_x' (dynamics/second_order_terms.hpp's
// SecondOrderTerms): F1 (nv, nz) row-major, bitwise variational_node's; RyInvT (nv, nv) row-major = R_y^-T;
// Ts the upper triangles of the symmetrised residual Hessians R_ww,i (i < nv) over w = (eta, dv, y) (3 nv),
// entry (a, b), a <= b, of Ts_i at [c * nv + i] with c the row-major index of (a, b) in the upper triangle
// (variational_upper_size(nv) entries per i, dynamics/second_order_terms.hpp). Then
//   sum_p lv_p F2_p = P^T (sum_i mu_i Ts_i) P,  mu = -R_y^-T lv,  P = [I_2nv 0; F1] (3 nv, nz):
// one projection per contraction instead of nv per node (variational_node's F2).
void variational_node_factored(const VariationalModel& vm, VariationalNodeWork& nw, const Eigen::VectorXd& q,
                               const Eigen::VectorXd& v, const Eigen::VectorXd& y, double* F1, double* RyInvT,
                               double* Ts);

// Derivatives of v+ at N nodes by implicit differentiation: Q (N, nq), V (N, nv), Vnext (N, nv)
// the solved v+, -> F1 (N, nv, nz) and for order 2 F2 (N, nv, nz, nz) (symmetric (0)-Hessian).
// The controls enter R only affinely (through b), so neither F1 nor F2 depends on them.
void variational_velocity_derivatives(const VariationalModel& vm, const double* Q, const double* V,
                                      const double* Vnext, int N, int order, int threads, double* F1, double* F2);

}  // namespace dyn
}  // namespace geoddp
