// The Hessian of the kinetic energy in the configuration, in O(nv * depth) spatial-vector
// operations instead of Pinocchio's second-order RNEA (ComputeRNEASecondOrderDerivatives, O(nv^3)
// entries of which the variational step keeps one contraction with the velocity).
//
// With world-frame quantities (Pinocchio's data.J columns xi_k, body velocities V_i, world inertias
// I_i) the doubled kinetic energy is phi(q, y) = y^T M(q) y = sum_i V_i^T I_i V_i. Moving the
// configuration along dof k, q exp(eps e_k) (right, local, as pinocchio::integrate), moves every
// body of the subtree of k's joint by the world twist exp(eps xi_k): its inertia by
// dI = -ad_xi^T I - I ad_xi, its velocity relative to the joint's parent body p(k) by ad_xi, and
// the joint's own columns xi_d by ad_xi (ad_xi xi = 0). That holds for every joint whose motion
// subspace is constant in its own frame: every joint joint_groups.hpp accepts (revolute,
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

#include <Eigen/Core>
#include <vector>

namespace geoddp {
namespace dyn {

// Per-call scratch, sized once for a model.
struct KineticHessianWork {
  std::vector<pinocchio::Motion> V;   // world velocity of each joint's body (V[0] = 0: the universe)
  std::vector<pinocchio::Force> h;    // the subtree's momentum, world frame
  std::vector<pinocchio::Inertia> Ic; // the subtree's composite inertia, world frame
  // per dof (6-vectors): the world column xi_k, u_k = xi_k x V_p(k), and the pair terms' factors
  // A_k = P_k - S_k - R_k, A0_k = P_k - S_k, B_k = Q_k - w_k, w_k (kinetic_hessian.hpp's header)
  typedef Eigen::Matrix<double, 6, 1> Vector6;
  std::vector<Vector6> xi, u, A, A0, B, w;
  std::vector<int> joint;             // per dof: its joint
  std::vector<int> last;              // per joint: the last joint of its subtree (depth-first order)
  explicit KineticHessianWork(const pinocchio::Model& model);
};

// H (nv, nv) = 1/2 d^2/dq^2 (y^T M(q) y), trivialised as in the header comment. `data` is the
// model's (its kinematics are overwritten). Requires every joint to be one of joint_groups.hpp's.
void kinetic_hessian(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                     const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::MatrixXd& H);

// g (nv) = 1/2 D(q, y)^T y = 1/2 d/dq (y^T M(q) y), trivialised: g_k = -u_k . h_k (the header's
// d_k phi / 2), in O(nv) spatial operations where Pinocchio's RNEA derivatives form all of D.
// `data` is the model's (its kinematics are overwritten). Same requirement as kinetic_hessian.
void kinetic_gradient(const pinocchio::Model& model, pinocchio::Data& data, KineticHessianWork& w,
                      const Eigen::VectorXd& q, const Eigen::VectorXd& y, Eigen::VectorXd& g);

}  // namespace dyn
}  // namespace geoddp
