// The rigid body on TSO(3) (the satellite, paper Section VI) in closed form: SO(3)'s exp, log and
// right Jacobian with its derivative, the rollout under the feedback law of Algorithm 1, the exact
// first- and second-order expansion along a trajectory and the geodesic attitude cost's
// derivatives. Plain arrays in and out (row-major,
// C-contiguous, shapes in each comment); no Pinocchio, no allocation per node.
//
// This is the satellite's backend (geoddp.models.satellite): a one-body model with a spherical
// root, no gravity and an Euler scheme, whose rollout and expansion are these closed forms instead
// of the general multibody core's Pinocchio calls. tests/oracle_satellite.py holds the numpy and
// Pinocchio finite-difference oracles they are tested against.
#pragma once

namespace geoddp {
namespace tso3 {

// Rodrigues' formula: out (3, 3) = exp(hat(x)), NaN-free at 0 (series below 1e-4 rad).
void so3_exp(double x0, double x1, double x2, double* out);

// The rotation vector of R (3, 3) into out (3,), angle in [0, pi]; robust near 0 and near pi
// (accurate to ~1e-15 up to pi, where pin.log3 loses up to ~1e-10 between 150 and 180 degrees).
void so3_log(const double* R, double* out);

// Jr(x) (3, 3) and, with derivative, Dsym (3, 3, 3): Dsym[i, a, b] = sym_{a,b} d Jr[i, a] / d x_b
// (lie::so3_jr and lie::so3_djr, row-major).
void jr_and_derivative(const double* x, double* Jr, double* Dsym, bool derivative);

// The satellite's constants: inertia I and its inverse (3, 3), actuation H (3, m), time step.
struct Body {
  const double* inertia;
  const double* inertia_inv;
  const double* actuation;
  int m;
  double dt;
  bool semi_implicit;  // R+ = R exp(dt Om+) (Crocoddyl's) instead of R exp(dt Om) (the paper's)
};

// Roll the body forward from (R0, Om0) under u_k = u_bar_k - gamma k_k - K_k zeta_k (paper eq.
// dustar), zeta_k = (log(R_bar_k^T R_k), Om_k - Om_bar_k), clamped to [lower_k, upper_k] when
// `lower` is given (a NaN stays NaN); without feedback (K_fb null) u = u_bar.
// Shapes: R_bar (H+1, 3, 3), Om_bar (H+1, 3), u_bar, k_ff (H, m), K_fb (H, m, 6), lower, upper
// (H, m); out R (H+1, 3, 3), Om (H+1, 3), u (H, m). Returns false once a state is non-finite.
bool rollout(const Body& body, int H, const double* R0, const double* Om0, const double* R_bar, const double* Om_bar,
             const double* u_bar, const double* k_ff, const double* K_fb, double gamma, const double* lower,
             const double* upper, double* R, double* Om, double* u);

// The exact expansion along body rates Om (H+1, 3) (geoddp.integrators.expand on SO(3) with the
// velocity map Om+ = Om + dt I^-1((I Om) x Om + H u), which does not depend on R and is linear in
// u): Phi (H, 6, 6), B (H, 6, m) and, when second_order, Theta (H, 6, 6, 6), Gamma (H, 6, 6, m),
// Xi (H, 6, m, m).
void linearise(const Body& body, int H, const double* Om, bool second_order, double* Phi, double* B, double* Theta,
               double* Gamma, double* Xi);

// Add 1/2 r^T W r, r = log(E_n), its trivialised gradient Ji^T W r and (0)-Hessian
// Ji^T (W - sum_p g_p Dsym_p) Ji (Ji = Jr(r)^-1) into l (N,), g (N, 3), Hs (N, 3, 3); E (N, 3, 3).
void geodesic_attitude_derivatives(int N, const double* E, const double* W, double* l, double* g, double* Hs);

}  // namespace tso3
}  // namespace geoddp
