// The Hessian of the kinetic energy in the configuration, in O(nv * depth) spatial-vector
// operations instead of Pinocchio's second-order RNEA (ComputeRNEASecondOrderDerivatives, O(nv^3)
// entries of which the variational step keeps one contraction with the velocity), and the two of
// that RNEA's tensors the variational step reads at its base points (mass_tensors, below).
//
// With world-frame quantities (Pinocchio's data.J columns xi_k, body velocities V_i, world inertias
// I_i) the doubled kinetic energy is phi(q, y) = y^T M(q) y = sum_i V_i^T I_i V_i. Moving the
// configuration along dof k, q exp(eps e_k) (right, local, as pinocchio::integrate), moves every
// body of the subtree of k's joint by the world twist exp(eps xi_k): its inertia by
// dI = -ad_xi^T I - I ad_xi, its velocity relative to the joint's parent body p(k) by ad_xi, and
// the joint's own columns xi_d by ad_xi (ad_xi xi = 0). That holds for every joint whose motion
// subspace is constant in its own frame: every joint lie/joint_groups.hpp accepts (revolute,
// prismatic, translation, continuous, spherical, free-flyer). Then, with u_k = xi_k x V_p(k) and
// h_k the subtree's momentum sum_(i in subtree) I_i V_i,
//   d_k phi = -2 u_k . h_k,
// and differentiating along dof l (Ic_l the subtree's composite inertia):
//   l's joint an ancestor of k's, or the same joint:
//     d_l d_k phi = -2 [(du_k) . h_k + u_k . (xi_l x* h_k - Ic_k u_l)],
//     du_k = (xi_l x xi_k) x V_p(k) + xi_k x dV_p(k),
//     dV_p(k) = xi_l x (V_p(k) - V_p(l)) (zero for the same joint),
//   k's joint a strict ancestor of l's:  d_l d_k phi = -2 u_k . (xi_l x* h_l - Ic_l u_l),
//   otherwise 0.
// The pair terms reduce to two 6-vector dot products with per-dof vectors, by (a x b) . f =
// -b . (a x* f) = a . (b x* f): with G_k = V_p(k) x* h_k, P_k = xi_k x* G_k, Q_k = xi_k x* h_k,
// S_k = u_k x* h_k, R_k = V_p(k) x* Q_k and w_k = Ic_k u_k,
//   l's joint supports k's:  d_l d_k phi = -2 [xi_l . (P_k - S_k - R_k) + u_l . (Q_k - w_k)],
//   the same joint:          d_l d_k phi = -2 [xi_l . (P_k - S_k) - u_l . w_k],
//   k's joint supports l's:  d_l d_k phi = -2 u_k . (Q_l - w_l),
// so a Hessian costs O(nv) spatial operations and O(nv depth) dot products. Along a joint on the
// universe (V_p(l) = 0) the whole tree moves rigidly with its velocities and the column is zero,
// which is set exactly.
// H(k, l) = 1/2 d_l d_k phi: the trivialised gradient differenced along q exp(eps e_l), the order
// of the variational step's 1/2 sum_p v_p d2tau_p/dq_k dq_l (not symmetric in a free-flyer's or
// spherical joint's own rotation block, whose directions do not commute).
#pragma once

#include <pinocchio/multibody.hpp>

#include "rigid_body/tree_dofs.hpp"

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace geoddp {
namespace dyn {

// The same moves give the tensors themselves, which the variational step's second order reads at
// its base points (Pinocchio's second-order RNEA at (q, 0, y) on the gravity-free model gave them,
// with d2tau/dv2 and d2tau/dqdv it does not read, at many times the cost of these):
//   dM(i, j, k) = d M(i, j) / dq_k   (d2tau_dadq),   T(i, j, k) = d_k D(i, j)   (d2tau_dqdq at a = y),
// D(q, y) = d(M(q) y)/dq. With J_i dof i's joint, F_i = Ic_i xi_i and B_j = xi_j x* h_j - Ic_j u_j
// (the subtree momentum's rate along dof j), M(i, j) = xi_i . Ic_j xi_j for J_i <= J_j (<=: is, or
// supports), and D(i, j) = -xi_i . Ic_i u_j (J_j <= J_i) or xi_i . B_j (J_i < J_j), else 0. Along
// dof k everything in k's subtree turns with it, which leaves these world-frame scalars unchanged;
// what remains comes from what does not turn (the parent's velocity, hence -u_k on every velocity
// below k, and the part of a subtree or chain above k):
//   dM(a, b, k), J_a <= J_b:  xi_a . (xi_k x* F_b)                          if J_a < J_k <= J_b,
//                             xi_a . (xi_k x* Ic_k xi_b - Ic_k (xi_k x xi_b))  if J_b < J_k,    else 0;
//   T(i, j, k), J_j <= J_i:   F_i . (xi_j x u_k)                            if J_k <= J_j,
//                             F_i . (xi_k x u_j)                            if J_j < J_k <= J_i,
//                             -xi_i . E_jk, E_jk = xi_k x* Ic_k u_j - Ic_k (xi_k x u_j)  if J_i < J_k;
//   T(i, j, k), J_i < J_j:    xi_i . C_jk, C_jk = Ic_j (xi_j x u_k) - xi_j x* Ic_j u_k   if J_k <= J_i,
//                             xi_i . (xi_k x* B_j + C_jk)                   if J_i < J_k <= J_j,
//                             xi_i . (xi_j x* B_k - E_jk)                   if J_j < J_k;
// every other entry is 0, and so are the pages of a joint on the universe (u_k = 0, nothing above
// it). Each related pair (j, k) costs a few spatial products, each entry one 6-vector dot product
// (benchmarks/pinocchio_calls.py times them against Pinocchio's second-order RNEA at (q, 0, y)).

// Per-call scratch, sized once for a model; where each dof sits in the tree (joint, last,
// first_dof, end_dof, above) from TreeDofs.
struct KineticHessianWork : TreeDofs {
  std::vector<pinocchio::Motion> V;   // world velocity of each joint's body (V[0] = 0: the universe)
  std::vector<pinocchio::Force> h;    // the subtree's momentum, world frame
  std::vector<pinocchio::Inertia> Ic; // the subtree's composite inertia, world frame
  // per dof (6-vectors): the world column xi_k, u_k = xi_k x V_p(k), and the pair terms' factors
  // A_k = P_k - S_k - R_k, A0_k = P_k - S_k, B_k = Q_k - w_k, w_k (rigid_body/kinetic_hessian.hpp's header)
  typedef Eigen::Matrix<double, 6, 1> Vector6;
  std::vector<Vector6> xi, u, A, A0, B, w;
  // mass_tensors: per dof, as the columns of 6 x nv matrices, u_k, F_k = Ic_k xi_k and B_k (xi_k is
  // data.J's column); per joint, Ic as a 6 x 6 matrix
  Eigen::Matrix<double, 6, Eigen::Dynamic> U, Fm, Bm;
  std::vector<Eigen::Matrix<double, 6, 6>> Icm;
  // Each body's inertia in the world frame, and the configuration (and Data) at which data's
  // kinematics, Iw and Ic were last formed: a call at the same q with the same Data keeps them
  // (bitwise what it would form) and redoes only the velocity terms. The variational step's Newton
  // iteration evaluates these recursions 6-7 times per step at one q+ with a moving velocity, and
  // its expansion 2-3 times at each of q and q+. The contract: nothing but these functions writes
  // that Data's kinematics (oMi, J) while the work is in use (VariationalWork's fdata, the bindings'
  // Data made per call).
  std::vector<pinocchio::Inertia> Iw;
  Eigen::VectorXd q_kin;
  const pinocchio::Data* data_kin = nullptr;
  explicit KineticHessianWork(const pinocchio::Model& model);
};

// H (nv, nv) = 1/2 d^2/dq^2 (y^T M(q) y), trivialised as in the header comment. `data` is the
// model's (its kinematics are overwritten). Requires every joint to be one of lie/joint_groups.hpp's.
void kinetic_hessian(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::MatrixXd& H);

// g (nv) = 1/2 D(q, y)^T y = 1/2 d/dq (y^T M(q) y), trivialised: g_k = -u_k . h_k (the header's
// d_k phi / 2), in O(nv) spatial operations where Pinocchio's RNEA derivatives form all of D.
// `data` is the model's (its kinematics are overwritten). Same requirement as kinetic_hessian.
void kinetic_gradient(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                      const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::VectorXd& g);

// D (nv, nv) = D(q, y) = d(M(q) y)/dq, trivialised as Pinocchio's dtau_dq at (q, 0, y) without
// gravity (the header comment above: -F_i . u_k where k's joint is or supports i's, xi_i . B_k where
// i's strictly supports k's, else 0, with F_i = Ic_i xi_i), in O(nv depth) 6-vector dot products
// after the O(nv) recursion: the variational step's D at every Newton iteration and base point,
// where Pinocchio's RNEA derivatives also form dtau/dv and M. `data` is the model's (its
// kinematics are overwritten). Same requirement as kinetic_hessian.
void mass_velocity_derivative(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                              const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::MatrixXd& D);

// dM = dM/dq and T = d/dq D(q, y) (nv^3 each, column-major (i, j, k) as Pinocchio's d2tau_dadq and
// d2tau_dqdq at (q, 0, y) without gravity; the header comment), overwritten. `data` is the model's
// (its kinematics are overwritten). Same requirement as kinetic_hessian.
void mass_tensors(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                  const Eigen::VectorXd& q, const Eigen::VectorXd& y, double* dM, double* T);

}  // namespace dyn
}  // namespace geoddp
