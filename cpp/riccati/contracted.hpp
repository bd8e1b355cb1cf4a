// Second-order DDP terms contracted with V_x' (the vector-tensor product idea of Nganga & Wensing
// 2021, arXiv 2103.03293, applied to the factored terms Pinocchio's RNEA second-order derivatives
// give): the backward pass needs Theta, Gamma, Xi only through
//     S = sum_i V_x'_i G2_i   (nz, nz),  G2_i = [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]]
// (paper eqs. Qfunctions), so S is assembled directly from dyn::SecondOrderTerms at the cost of a
// few nv^3 dot products per node instead of forming n^3 + n^2 m + n m^2 numbers per node.
#pragma once

#include <Eigen/Core>

#include "runtime/arrays.hpp"
#include "dynamics/second_order_terms.hpp"

namespace geoddp {
namespace ctr {

// S (nz, nz), symmetric, = sum_i Vx_i G2_i at node k; Vx (2 nv). S is resized and overwritten.
void contract(const dyn::SecondOrderTerms& t, int k, const double* Vx, RowMat& S);

// The backward Riccati pass of ric::backward_pass (same inputs, outputs and arithmetic for the
// first-order part) with the second-order terms contracted from `t` (H = t.N nodes). workers: 1,
// or 2 (each node's contraction on the pool's second worker beside the node's first-order blocks;
// riccati/contracted.cpp, on_two_workers), or 0 (whichever of the two has been faster here for passes of
// this shape: riccati/contracted.cpp, WorkersChoice). Every choice gives bitwise the same results.
int backward_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                             const double* lu, const double* lxx, const double* lux, const double* luu,
                             const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                             double reg, int workers, double* k_ff, double* K_fb, double* quu_eig, double* d1,
                             double* d2);

// ric::backward_pass_box_hook (cpp/riccati/riccati.hpp: controls kept in [lower, upper]; same inputs,
// outputs and arithmetic) with the second-order terms contracted from `t`; workers as above.
int box_pass_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                        const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                        const double* Vxx_final, const dyn::SecondOrderTerms& t, double reg, const double* u_bar,
                        const double* lower, const double* upper, int workers, double* k_ff, double* K_fb,
                        double* quu_eig, signed char* active, double* Vx0, double* Vxx0, double* d1, double* d2);

// geoddp.solver.backward.regularised_backward for the contracted pass, in one call: the pass at
// lam, then, if Q_uu + lam I is not positive definite at some node, the lowest rung of the ladder
// lam_{j+1} = max(reg_increase lam_j, reg_min) whose pass factorises, found by the same galloping
// and bisection as geoddp.solver.ladder.LadderSearch (the same rungs in the same order), or gives
// up at the first rung above reg_max. With `speculate`, each round's two rungs run side by side
// on the pool's two workers. Before a pass has factorised, the lower rung runs in k_ff/K_fb/quu_eig
// and the higher in spare_* (copied over for the nodes it solved when it is the one kept); after,
// the factorised pass stays in k_ff/K_fb/quu_eig and the probes run in spare_* and a buffer of
// this call. Returns the failed node of the last pass kept (-1: it factorised); *lam, *d1, *d2 and
// *restarts (rungs climbed) as regularised_backward returns them.
int regularised_contracted(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                           const double* lu, const double* lxx, const double* lux, const double* luu,
                           const double* Vx_final, const double* Vxx_final, const dyn::SecondOrderTerms& t,
                           double reg_increase, double reg_min, double reg_max, bool speculate, double* k_ff,
                           double* K_fb, double* quu_eig, double* spare_k, double* spare_K, double* spare_eig,
                           double* lam, double* d1, double* d2, int* restarts);

}  // namespace ctr
}  // namespace geoddp
