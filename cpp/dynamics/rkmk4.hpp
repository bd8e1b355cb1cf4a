// The fourth-order Runge-Kutta-Munthe-Kaas step (RKMK4) on a Pinocchio state space, and its
// derivatives: C++ twin of the tests' oracle (tests/oracle_rkmk4.py, module docstring there for the scheme,
// and OracleMultibody._expansion_rk4 in tests/oracle_multibody.py).
//
// Over one step q(t) = q_n exp(theta(t)), theta' = Jr(theta)^-1 v, v' = aba(q_n exp(theta), v, tau), with the
// classical RK4 tableau on (theta, v) and q+ = q_n exp(theta(h)). Jr is block-diagonal over the joint groups
// (identity on vector and SO(2) joints, lie/right_jacobians.hpp's closed forms on SO(3), SE(3)).
//
// First order: the analytic step Jacobian G = d(dq+, dv+)/d(dq, dv, du), chaining the four stages'
// computeABADerivatives and the exact dJr. Second order: central differences of that analytic
// Jacobian along the nz tangent directions of z, symmetrised (the (0)-Hessian; expressing the
// output at the perturbed image adds 1/2 ad(G a) G b, antisymmetric in (a, b), which the
// symmetrisation removes), exactly as the Python path does. RK4's exact second order would need
// the second derivative of Jr and of ABA through four chained stages; it is not written yet.
//
// Arrays as in dynamics/trajectory.hpp: float64, row-major; z = (dq, dv, du), n = 2 nv, nz = n + m.
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <vector>

#include "dynamics/trajectory.hpp"

namespace geoddp {
namespace dyn {

// Central-difference step of the second order (the oracle's FD_STEP, tests/oracle_multibody.py).
constexpr double RK4_FD_STEP = 1e-5;

// Per-worker scratch of the RKMK4 kernels.
struct Rk4Work {
  pinocchio::Data data;
  Eigen::MatrixXd A, Jr, Jinv, Minv, Mdj, Pv, Th, Vi, Qtan, Kv, Kth, Tmp, ThSum, ASum, G, Gp, D;
  Eigen::VectorXd theta, vi, y, kth, kv, thSum, qi, qd, vd, ud, taud, tau;
  Rk4Work(const Model& model, int m);
};

// One RKMK4 step: q (nq), v (nv), tau (nv) generalised forces, h (s) -> q1 (nq), v1 (nv).
void rk4_step(const Model& model, pinocchio::Data& data, const std::vector<JointGroup>& groups,
              const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& tau, double h,
              Eigen::VectorXd& q1, Eigen::VectorXd& v1);

// The step Jacobian at (q, v, u = tau through H) into w.G (n, nz): oracle_rkmk4.step_jacobian.
void rk4_jacobian(const Setup& s, const std::vector<JointGroup>& groups, Rk4Work& w, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, const Eigen::VectorXd& tau);

// One node of the expansion: Phi (n, n), B (n, m) and, if Theta != nullptr, Theta (n, n, n),
// Gamma (n, n, m), Xi (n, m, m), all row-major at this node's offset (dynamics/trajectory.hpp's expansion).
void rk4_node_expansion(const Setup& s, const std::vector<JointGroup>& groups, Rk4Work& w,
                        const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& u,
                        double* Phi, double* B, double* Theta, double* Gamma, double* Xi);

}  // namespace dyn
}  // namespace geoddp
