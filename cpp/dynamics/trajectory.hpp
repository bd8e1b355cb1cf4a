// Multibody dynamics kernels over a whole trajectory: arrays in, arrays out.
//
// What geoddp.models.multibody.Multibody calls (rollout, rollout_closed_loop, expansion,
// expansion_contracted), twins of the tests' oracle OracleMultibody (tests/oracle_multibody.py),
// for four integrators, one file each: "euler" (paper eq. disceq: q+ = q exp(dt v)) and
// "semi_implicit" (q+ = q exp(dt v+)), both with v+ = v + dt aba(q, v, H u) (euler.hpp); "rk4"
// (dynamics/rkmk4.hpp); "variational" (dynamics/variational.hpp).
//
// Every array is float64, C-contiguous (row-major), shapes as documented per function. The
// tangent state is zeta = (dq, dv), n = 2 nv, z = (dq, dv, du), nz = n + m. Nothing here imports
// Python: the kernels take a const pinocchio::Model& (bindings/pin_model.hpp converts).
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>
#include <vector>

#include "dynamics/second_order_terms.hpp"
#include "lie/joint_groups.hpp"
#include "runtime/arrays.hpp"

namespace geoddp {
namespace dyn {

typedef pinocchio::Model Model;

// RK4: the Runge-Kutta-Munthe-Kaas step of dynamics/rkmk4.hpp (rollout, forward pass, expansion; not the
// factored second order, which is the Euler schemes' structure).
// VARIATIONAL: the forward variational Euler step of dynamics/variational.hpp (rollout, forward pass and
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
// With control limits lower, upper (N, m) (both or neither), u_k is clamped into
// [lower_k, upper_k] after the feedback law, before it is applied and stored (NaN stays NaN).
bool rollout_closed_loop(const Setup& s, const double* q0, const double* v0, const double* Qbar,
                         const double* Vbar, const double* Ubar, const double* kff, const double* K,
                         double gamma, int N, double* Qout, double* Vout, double* Uout,
                         const double* lower = nullptr, const double* upper = nullptr);

// Phi (N, n, n), B (N, n, m) and for order 2 Theta (N, n, n, n), Gamma (N, n, n, m),
// Xi (N, n, m, m) at the N nodes of a rollout Q (N+1, nq), V (N+1, nv), U (N, m):
// zeta+_i = Phi zeta + B du + 1/2 zeta^T Theta_i zeta + zeta^T Gamma_i du + 1/2 du^T Xi_i du.
// Same meaning and layout as geoddp.models.multibody.Multibody.expansion.
void expansion(const Setup& s, const double* Q, const double* V, const double* U, int N, int order,
               int threads, double* Phi, double* B, double* Theta, double* Gamma, double* Xi);

// Phi (N, n, n), B (N, n, m) exactly as expansion(order=1), and the factored second-order terms
// (second_order_terms.hpp) for euler, semi_implicit and variational.
void expansion_contracted(const Setup& s, const double* Q, const double* V, const double* U, int N, int threads,
                          double* Phi, double* B, SecondOrderTerms& terms);

}  // namespace dyn
}  // namespace geoddp
