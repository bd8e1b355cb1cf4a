// The explicit and semi-implicit Euler steps on a Pinocchio model (paper eq. disceq: q+ = q exp(dt w),
// w = v (euler) or v+ (semi_implicit), v+ = v + dt aba(q, v, H u)) and the exact first and second
// derivatives of their velocity update, from Pinocchio's ABA derivatives and second-order RNEA
// tensors (or rigid_body/one_body.hpp's shortcut for one body). The configuration update's
// derivatives (the reconstruction) are dynamics/expansion.cpp's, shared with the variational step.
//
// Arrays as in dynamics/trajectory.hpp: float64, row-major; z = (dq, dv, du), nz = 2 nv + m.
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "dynamics/trajectory.hpp"
#include "rigid_body/one_body.hpp"

namespace geoddp {
namespace dyn {

// One Euler step (s.integrator EULER or SEMI_IMPLICIT): q (nq), v (nv), tau (nv) -> q1 (nq), v1 (nv).
void euler_step(const Setup& s, pinocchio::Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1);

// The second derivatives of the velocity update are symmetric in (a, b) and exactly zero in the
// (v, u) and (u, u) blocks (a is affine in tau with slope Minv(q), which does not depend on v). So
// they are computed only on the "active" upper pairs (a <= b): a a q direction (b any), or a and b
// both v directions: nv nz + nv pairs instead of nz^2, stored packed, one column per pair.
struct PairIndex {
  std::vector<int> a, b;  // pair c = (a[c], b[c]), a[c] <= b[c]
  int count() const { return (int)a.size(); }
};

// Per-worker scratch of node_derivatives: Pinocchio data and the node's buffers.
struct NodeWork {
  pinocchio::Data data;
  Eigen::MatrixXd Minv, aq, av, au, az, Pj, Tu, F2u;
  Eigen::VectorXd q, v, tau, a;
  PairIndex pairs;
  std::vector<int> pair_of;  // (a, b) -> packed column or -1 (inactive), both orders
  // RNEA's second-order tensors without Pinocchio's per-node call, for a one-body model
  // (rigid_body/one_body.hpp)
  const OneBodySecondOrder* one_body = nullptr;
  NodeWork(const Model& model, int m);
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
void node_derivatives(const Setup& s, NodeWork& w, double* F1, bool second);

// The one-body shortcut for RNEA's second-order tensors when `model` is one body on a free-flyer or
// spherical root and the second order is wanted, else null.
std::unique_ptr<OneBodySecondOrder> one_body_for(const Model& model, bool second);

// Derivatives of v+ = v + dt aba(q, v, H u) w.r.t. z at N nodes: Q (N, nq), V (N, nv), U (N, m)
// -> F1 (N, nv, nz), and for order 2 F2 (N, nv, nz, nz), the symmetric (0)-Hessian (exact: from
// computeABADerivatives and ComputeRNEASecondOrderDerivatives, no differences). For the tests.
void velocity_derivatives(const Setup& s, const double* Q, const double* V, const double* U, int N,
                          int order, int threads, double* F1, double* F2);

// Pinocchio's second-order RNEA tensors at (q (nq), v (nv), a (nv)): d2tau_dqdq, d2tau_dvdv,
// d2tau_dqdv, d2tau_dadq, nv^3 each, column-major as Pinocchio stores them ((i, j, k) at
// i + nv (j + nv k)). With one_body, from the one-body shortcut the expansions use (rigid_body/one_body.hpp;
// std::invalid_argument if the model is not one body on a free-flyer or spherical root). For the tests.
void rnea_second_order(const Model& model, const double* q, const double* v, const double* a, bool one_body,
                       double* Iqq, double* Ivv, double* Iqv, double* dM);
// Whether the expansions take RNEA's second-order tensors from the one-body shortcut for `model`.
bool one_body_applies(const Model& model);

}  // namespace dyn
}  // namespace geoddp
