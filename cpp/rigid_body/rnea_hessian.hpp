// RNEA's second derivatives contracted with a vector, inside a spatial-vector recursion: the
// vector-tensor product of Nganga & Wensing (2021, arXiv 2103.03293), derived here for Pinocchio's
// conventions. The backward pass needs RNEA's second-order tensors only through mu^T d2tau
// (riccati/contracted.cpp: mu = -dt Minv c, c from V_x'), so instead of
// Pinocchio's ComputeRNEASecondOrderDerivatives (4 nv^3 entries per node, then contracted) this
// gives the four contractions directly, for phi(q, v) = mu^T RNEA(q, v, a) at fixed a and mu:
//   Hqq(j, l) = d_l d_j phi        (sum_i mu_i d2tau_dqdq(i, j, l): trivialised, iterated, the
//                                   gradient's j-th entry differenced along q exp(eps e_l))
//   Hvv(j, l) = d2 phi / dv_j dv_l (sum_i mu_i d2tau_dvdv(i, j, l))
//   Hqv(j, l) = d_j d phi / dv_l   (sum_i mu_i d2tau_dqdv(i, q_j, v_l))
//   Dm(j, l)  = d_l (M mu)_j       (sum_i mu_i d2tau_dadq(i, a_j, q_l) = D(q, mu))
// in O(nv) spatial products and O(nv depth) 6-vector dot products.
//
// The derivation (world frame, Featherstone's spatial vectors in Pinocchio's [linear; angular]
// order; x the motion cross product, x* the force one, <m x n, f> = -<n, m x* f>):
// * with data.J's world columns xi_c, body velocities V_i = sum_(c <= i) xi_c v_c, "mu-velocities"
//   W_i = sum_(c <= i) xi_c mu_c, accelerations with gravity A_i = A_p + S a + V_p x (V_i - V_p),
//   A_0 = -g, world inertias I_i, momenta h_i = I_i V_i and body forces f_i = I_i A_i + V_i x* h_i,
//   RNEA is tau_c = <xi_c, sum_(i in subtree) f_i>, so phi = sum_i <W_i, f_i>;
// * along dof k (q exp(eps e_k), right, local, as pinocchio::integrate) the subtree of k's joint J
//   turns rigidly by the world twist xi_k. phi is invariant under a common turn of every vector it
//   is built from, so only what does not turn contributes: the parent p = lambda(J)'s terms and
//   gravity. For a body i below J, W_i, V_i and A_i deviate from the rigid turn by
//   -t_k, -u_k and -xi_k x A_p - u_k x (V_i - V_p), with t_k = xi_k x W_p, u_k = xi_k x V_p;
// * so the trivialised gradient is, with the subtree composites F = sum f_i, P = sum I_i W_i,
//   H = sum h_i, Ic = sum I_i and Y = sum (V_i x* I_i W_i - W_i x* h_i + I_i (W_i x V_i)),
//     d_k phi   = -<t_k, F_J> - <s'_k, P_J> - <u_k, Y_J>,   s'_k = xi_k x A_p - u_k x V_p,
//     dphi/dv_k = <xi_k, Y_J> - <xi_k x (V_J + V_p), P_J>;
// * differentiating those again by the same rule (each composite turns with the subtree and
//   deviates by what its bodies' W, V, A deviate; the 6 x 6 composites N = -sum ((V_i x)^T I_i +
//   I_i (V_i x)) and NW (the same with W_i) carry the bilinear parts) gives every entry as at most
//   three 6-vector dot products between per-dof vectors. Per dof k (joint J, parent p), with
//   z_k = xi_k x (V_J + V_p), b_k = xi_k x* P_J and the composites of J:
//     dF_k  = xi_k x* F - u_k x* H - Ic s'_k - N u_k        (F's rate along q_k)
//     dP_k  = b_k - Ic t_k                                   (P's)
//     g_k   = t_k x* H - N t_k + NW u_k,
//     dY_k  = xi_k x* Y - u_k x* P + g_k                      (Y's)
//     dFv_k = xi_k x* H + N xi_k - Ic z_k,  dYv_k = b_k - NW xi_k   (F's and Y's along v_k)
//     e1_k  = g_k + u_k x* P,  e2_k = V_p x* b_k - xi_k x* (V_p x* P) - u_k x* P + xi_k x* Y,
//     cu_k  = -(e1_k + e2_k);
//   then, for the pairs:
//     L (l's joint) strictly supports J:
//       Hqq(k, l) = -<dF_k, t_l> - <dP_k, s'_l> + <cu_k, u_l>,  Dm(k, l) = -<Ic_J xi_k, t_l>,
//       Hqv(k, l) = <xi_l, e1_k + e2_k> + <z_l, Ic_J t_k - b_k>,  Hvv(k, l) = <xi_l, b_k - NW_J xi_k>;
//     L = J: the same without e2_k, b_k in Hqv and b_k in Hvv;
//     J strictly supports L:
//       Hqq(k, l) = -<t_k, dF_l> - <s'_k, dP_l> - <u_k, dY_l>,  Dm(k, l) = <xi_k, dP_l>,
//       Hqv(k, l) = -<t_k, dFv_l> - <u_k, dYv_l>,  Hvv(k, l) = <xi_k, dYv_l>;
//     otherwise 0.
// Checked against Pinocchio's second-order RNEA contracted with mu (1e-12) and central differences
// of Pinocchio's analytic first derivatives (1e-7) in tests/test_core_rnea_hessian.py, on the
// kinetic-energy tests' six models, gravity on and off.
// Valid for every joint lie/joint_groups.hpp accepts (motion subspace constant in the joint's frame).
#pragma once

#include <pinocchio/multibody.hpp>

#include "rigid_body/tree_dofs.hpp"

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace geoddp {
namespace dyn {

// The work splits in two so that the expansion, which runs over the nodes in parallel, does what
// does not depend on mu, and the pass only what does:
// * node_terms (rnea_hessian_node, at (q, v, a)): per joint V, A, the world inertia I and the
//   composites F, H, Ic, N; per dof xi, u, s', z, Ic xi and the rates dF along q and along v;
//   node_size(model) doubles, written into the caller's buffer (SecondOrderTerms keeps one per node);
// * the contraction (rnea_hessian_contract, with mu): W, P, Y, NW and the per-dof vectors that
//   read them, then the pairs.
// Per-call scratch and the model's Data, sized once for a model; where each dof sits in the tree
// (joint, own_end, end_dof, above) from TreeDofs.
struct RneaHessianWork : TreeDofs {
  typedef Eigen::Matrix<double, 6, 1> V6;
  typedef Eigen::Matrix<double, 6, 6> M6;
  typedef Eigen::Matrix<double, 6, Eigen::Dynamic> Cols;
  pinocchio::Data data;
  // the contraction's per joint terms (index 0: the universe) and per dof vectors (columns)
  std::vector<V6> W, P, Y;
  std::vector<M6> NW;
  // t, dP, dY, dYv are read for every dof l of a pair, e1 (e1 + e2 in e12), Ict and nw only for k
  Cols t, dP, dY, dYv, e1, e12, Ict, nw;
  std::vector<double> node;  // one node's terms, for rnea_hessian
  explicit RneaHessianWork(const pinocchio::Model& model);
};

// Doubles of one node's mu-free terms: 132 per joint (the universe included) and 42 per dof.
inline size_t rnea_hessian_node_size(const pinocchio::Model& model) {
  return 132 * (size_t)model.njoints + 42 * (size_t)model.nv;
}

// One node's mu-free terms at (q (nq), v (nv), a (nv)) into node (rnea_hessian_node_size doubles).
// `w`'s data's kinematics are overwritten.
void rnea_hessian_node(const pinocchio::Model& model, RneaHessianWork& w, const double* q, const double* v,
                       const double* a, double* node);

// The four contractions with mu (nv) from one node's terms, each (nv, nv) column-major (entry
// (j, l) at j + nv l, the layout of sum_i mu_i X(i, j, l) for Pinocchio's column-major tensors X),
// overwritten.
void rnea_hessian_contract(const pinocchio::Model& model, RneaHessianWork& w, const double* node, const double* mu,
                           double* Hqq, double* Hvv, double* Hqv, double* Dm);

// The first contraction (Hqq) for a model whose only mass is a unit point mass at the world point p
// (3) on joint `joint`'s body, at v = a = 0 under the gravity -lambda (3, world): the curvature of
// J_p(q)^T lambda, the generalised force of a world force lambda held at the point, contracted with
// mu: sum_i mu_i d_l d_j (J_p^T lambda)_i, added into Hqq (nv, nv, column-major as above). node holds
// the terms of any model of the same tree at the same q (only its dofs' world columns xi are read),
// so a contact node's feet need p and lambda alone. Only the dofs supporting the joint take part,
// and every body velocity and acceleration vanishes, so this is the recursion above with u = z = 0,
// A = (lambda, 0), F = I_p A and P = I_p W on the chain (I_p the point mass's spatial inertia).
void rnea_hessian_point_force(const pinocchio::Model& model, const TreeDofs& tree, const double* node, int joint,
                              const double* p, const double* lambda, const double* mu, double* Hqq);

// Both at once at (q, v, a): the four contractions. `w` must have been made for `model`; its data's
// kinematics are overwritten. Every joint must be one lie/joint_groups.hpp accepts.
void rnea_hessian(const pinocchio::Model& model, RneaHessianWork& w, const double* q, const double* v,
                  const double* a, const double* mu, double* Hqq, double* Hvv, double* Hqv, double* Dm);

}  // namespace dyn
}  // namespace geoddp
