// Multibody dynamics kernels over a whole trajectory: arrays in, arrays out.
//
// C++ twins of geoddp.models.multibody.Multibody (rollout, velocity_derivatives, expansion) and
// of the forward pass of geoddp.multibody_problem.MultibodyProblem.rollout_closed_loop, for the
// integrators "euler" (paper eq. disceq: q+ = q exp(dt v)) and "semi_implicit" (q+ = q exp(dt v+)),
// both with v+ = v + dt aba(q, v, H u).
//
// Every array is float64, C-contiguous (row-major), shapes as documented per function. The
// tangent state is zeta = (dq, dv), n = 2 nv, z = (dq, dv, du), nz = n + m. Nothing here imports
// Python: the kernels take a const pinocchio::Model& (see pin_model.hpp for the conversion).
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <string>
#include <vector>

namespace geoddp {
namespace dyn {

typedef pinocchio::Model Model;
typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMat;

enum Integrator { EULER = 0, SEMI_IMPLICIT = 1 };

// One joint's Lie group (geoddp.configuration.JointGroup): kind 0 vector, 1 so2, 2 so3, 3 se3.
struct JointGroup {
  int kind, idx_v, nv, idx_q;
};
enum GroupKind { VECTOR = 0, SO2 = 1, SO3 = 2, SE3 = 3 };

// The joint groups of a model in tangent order; throws std::invalid_argument on a joint whose
// configuration space is none of R^k, SO(2), SO(3), SE(3) (e.g. planar).
std::vector<JointGroup> joint_groups(const Model& model);

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
// Returns false (and stops) as soon as a state is non-finite, as the Python path does.
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

// Reconstruction blocks at omega (nv): Ad_exp(-omega) and Jr(omega), each (nv, nv) row-major
// (geoddp.configuration.block_Ad_Jr), and D (nv, nv, nv) with D[i, j, l] = d Jr[i, j] / d omega_l
// (geoddp.configuration.second_order_tensors' D, exact).
void block_ad_jr(const std::vector<JointGroup>& groups, int nv, const double* omega, double* A, double* Jr,
                 double* D);

// Worker threads of a second-order pass when threads <= 0 ("default"); first-order passes then
// run on one (per-node work is below a thread's start-up cost).
int default_threads();

}  // namespace dyn
}  // namespace geoddp
