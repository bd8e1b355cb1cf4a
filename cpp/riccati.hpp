// The backward Riccati recursion of DDP on trivialised derivatives (paper eqs. Qfunctions, dustar,
// backv), C++ twin of geoddp.kernels.riccati.backward_pass: same inputs, outputs and semantics
// (reads only the upper triangle of the symmetric blocks l_xx, l_uu, Vxx_final, Theta_i, Xi_i).
#pragma once

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

}  // namespace ric
}  // namespace geoddp
