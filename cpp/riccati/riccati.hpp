// The backward Riccati recursion of DDP on trivialised derivatives (paper eqs. Qfunctions, dustar,
// backv), geoddp.kernels.backward_pass (reads only the upper triangle of the symmetric blocks l_xx,
// l_uu, Theta_i, Xi_i), its box-constrained twin and the cost gradient's costate recursion.
#pragma once

#include <Eigen/Core>
#include <functional>

#include "runtime/arrays.hpp"

namespace geoddp {
namespace ric {

// Shapes (row-major, float64): Phi (H, n, n), B (H, n, m), lx (H, n), lu (H, m), lxx (H, n, n),
// lux (H, m, n), luu (H, m, m), Vx_final (n), Vxx_final (n, n), and if second_order Theta
// (H, n, n, n), Gamma (H, n, n, m), Xi (H, n, m, m). Writes k_ff (H, m), K_fb (H, m, n) and
// quu_eig (H) (min_j L_jj^2 of Q_uu + reg I's Cholesky factor) for nodes H-1 .. failed+1.
// Returns the node where Q_uu + reg I is not positive definite (the pass stops there) or -1;
// d1 = sum_k Q_u^T k_k, d2 = sum_k k_k^T Q_uu k_k.
int backward_pass(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                  const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                  const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi,
                  bool second_order, double reg, double* k_ff, double* K_fb, double* quu_eig, double* d1,
                  double* d2);

// dJ/du_k = l_u^k + B_k^T psi^{k+1}, psi^k = l_x^k + Phi_k^T psi^{k+1}, psi^H = l_x^H (Lemma
// lemm:psi) into out (H, m); Phi (H, n, n), B (H, n, m), lx (H, n), lu (H, m), lx_final (n,).
void gradient(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
              const double* lx_final, double* out);

// Box-constrained twin of backward_pass (control limits; projected Newton after Tassa, Mansard and
// Todorov, ICRA 2014). Same inputs plus u_bar, lower, upper (H, m): the controls of node k must stay
// in [lower_k, upper_k]; with u = u_bar - k_k - K_k zeta, each node minimises its Q model
// -Q_u^T k + 1/2 k^T Q_uu k over u_bar_k - upper_k <= k <= u_bar_k - lower_k (box_qp, warm-started
// from k_ff's incoming content). Rule for indefinite Q_uu: as the unconstrained pass, the node
// fails when Q_uu + reg I (the whole m x m block) is not positive definite, so each box QP is
// strictly convex; the caller raises reg and restarts. Feedback rows of clamped inputs are zero,
// free rows (Q_uu + reg I)_ff^-1 Q_ux,f. The value function is updated in full (exact with clamped
// inputs and with reg > 0): Vx = Qx - K^T Qu - Qux^T k + K^T Quu k, Vxx = Qxx - K^T Qux - Qux^T K +
// K^T Quu K, Quu unregularised. Writes active (H, m): -1 where the input sits at its lower bound,
// +1 at its upper bound, 0 free; and Vx0 (n), Vxx0 (n, n): the value function at node 0.
int backward_pass_box(int H, int n, int m, const double* Phi, const double* B, const double* lx, const double* lu,
                      const double* lxx, const double* lux, const double* luu, const double* Vx_final,
                      const double* Vxx_final, const double* Theta, const double* Gamma, const double* Xi,
                      bool second_order, double reg, const double* u_bar, const double* lower, const double* upper,
                      double* k_ff, double* K_fb, double* quu_eig, signed char* active, double* Vx0, double* Vxx0,
                      double* d1, double* d2);

// backward_pass_box with the second-order terms supplied by a hook (null: first order): at node
// k it adds sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]] (Vx = V_x' of node k + 1) into
// Qxx (n, n), Qux (m, n; Gamma_i^T) and Quu (m, m), upper triangles at least. Lets a backend that
// keeps the second order factored (a contraction with V_x') run the same box pass.
// vx_final (may be null) is called as unconstrained_pass's is (riccati/riccati_blocks.hpp): with node k's
// V_x' as soon as it is known, before the rest of node k + 1's work.
typedef std::function<void(int k, const Eigen::VectorXd& Vx, RowMat& Qxx, RowMat& Qux, RowMat& Quu)>
    SecondOrderHook;
typedef std::function<void(int k, const Eigen::VectorXd& Vx)> HandOverHook;
int backward_pass_box_hook(int H, int n, int m, const double* Phi, const double* B, const double* lx,
                           const double* lu, const double* lxx, const double* lux, const double* luu,
                           const double* Vx_final, const double* Vxx_final, const SecondOrderHook* second,
                           double reg, const double* u_bar, const double* lower, const double* upper, double* k_ff,
                           double* K_fb, double* quu_eig, signed char* active, double* Vx0, double* Vxx0, double* d1,
                           double* d2, const HandOverHook* vx_final = nullptr);

// One box QP: min_x 1/2 x^T Hq x - q^T x over lo <= x <= hi (m,), Hq (m, m) symmetric positive
// definite, by projected Newton from x (in: warm start, clipped into the box; out: the
// minimiser). clamped (m): -1 at lo, +1 at hi, 0 free (an input with lo == hi is always clamped).
// Returns the number of Newton iterations, or -1 if Hq is not positive definite on a free set.
int box_qp(int m, const double* Hq, const double* q, const double* lo, const double* hi, double* x,
           signed char* clamped);

}  // namespace ric
}  // namespace geoddp
