// Second-order DDP terms contracted with V_x' (the vector-tensor product idea of Nganga & Wensing
// 2021, arXiv 2103.03293, applied to the factored terms Pinocchio's RNEA second-order derivatives
// give): the backward pass needs Theta, Gamma, Xi only through
//     S = sum_i V_x'_i G2_i   (nz, nz),  G2_i = [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]]
// (paper eqs. Qfunctions), so S is assembled directly from dyn::SecondOrderTerms at the cost of a
// few nv^3 dot products per node instead of forming n^3 + n^2 m + n m^2 numbers per node.
#pragma once

#include <Eigen/Core>

#include "arrays.hpp"
#include "dynamics.hpp"

namespace geoddp {
namespace ctr {

// S (nz, nz), symmetric, = sum_i Vx_i G2_i at node k; Vx (2 nv). S is resized and overwritten.
void contract(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S);

// Node k's second-order terms for a backward pass: Qxx (n, n) += S_xx, Qux (m, n) += S_ux,
// Quu (m, m) += S_uu with S = contract(t, k, Vx); S is the caller's scratch. The hook of both the
// unconstrained and the box-constrained contracted passes.
void add_contracted(const dyn::SecondOrderTerms& t, int k, const Eigen::VectorXd& Vx, RowMat& S, RowMat& Qxx,
                    RowMat& Qux, RowMat& Quu);

// The backward Riccati pass of ric::backward_pass (same inputs, outputs and arithmetic for the
// first-order part) with the second-order terms contracted from `t` (H = t.N nodes).
int backward_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                             const double* lu, const double* lxx, const double* lux, const double* luu,
                             const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                             double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1, double* d2);

}  // namespace ctr
}  // namespace geoddp
