// The variational step for one body on a free-flyer or spherical root, on fixed-size matrices:
// the Lie-group closed forms it needs as one interface over SO(3) (N = 3) and SE(3) (N = 6)
// (FixedLie), and d/dp [K(c p)^T M p] with its exact p-derivatives. Shared by the step
// (variational_step.cpp) and the second order (variational_derivatives.cpp,
// variational_hessian.cpp).
//
// A model of one body on a free-flyer (N = 6) or spherical (N = 3) root without configuration
// dependence (VariationalModel::configuration_free: M constant, D = 0): the residual's velocity
// Jacobians are d/dp [K(c p)^T M p] (c = dt for R_dv's, c = -dt for R_y), residual_hessians takes
// their p-derivatives (phi_hessian), and each step's Newton iteration solves with them. Here
// they run on fixed-size matrices: the general path's dynamic ones spend as long in Eigen's GEMM
// dispatch, zero D products and block copies as in the closed forms they wrap (the SE(3) inverse
// and dJr^T s are closed forms too, lie::se3_jr_inverse and lie::se3_djr_transpose_apply). The
// results agree with the general path's to round-off.
#pragma once

#include <pinocchio/spatial.hpp>

#include <Eigen/Core>
#include <Eigen/LU>

#include "lie/right_jacobians.hpp"

namespace geoddp {
namespace dyn {
namespace var {

template <int N>
struct FixedLie;
// Each keeps the scalar coefficients of Jr at a point (Coef) so that Jr(x) and dJr(x)^T s at one x
// share their transcendental functions and Taylor series (lie::se3_jr_coefficients).
template <>
struct FixedLie<6> {
  typedef lie::Mat6 Mat;
  typedef Eigen::Matrix<double, 6, 1> Vec;
  typedef lie::Se3JrCoefficients Coef;
  static Coef coefficients(const Vec& x) { return lie::se3_jr_coefficients(x); }
  static Mat jr(const Vec& x, const Coef& k) { return lie::se3_jr(x, k); }
  static Mat inverse(const Mat& J) { return lie::se3_jr_inverse(J); }
  static void djr_transpose_apply(const Vec& x, const Vec& s, Mat& N, const Coef& k) {
    lie::se3_djr_transpose_apply(x, s, N, k);
  }
  static void jr_transpose_hessian(const Vec& x, const Vec& u, const Coef& k, Mat E[6]) {
    lie::se3_jr_transpose_hessian(x, u, k, E);
  }
  static Mat ad_exp_minus(const Vec& x) { return pinocchio::exp6(pinocchio::Motion(-x)).toActionMatrix(); }
  static void djr(const Vec& x, Mat D[6]) { lie::se3_djr(x, D); }
  // ad(xi) of se(3), xi = [v; w]: [[hat(w), hat(v)], [0, hat(w)]], Pinocchio's motion action matrix
  static Mat ad(const Vec& xi) { return pinocchio::Motion(xi).toActionMatrix(); }
};
template <>
struct FixedLie<3> {
  typedef lie::Mat3 Mat;
  typedef lie::Vec3 Vec;
  struct Coef {
    double a, b, al, be;
  };
  static Coef coefficients(const Vec& x) {
    Coef k;
    lie::so3_coefficients(x.norm(), k.a, k.b, k.al, k.be);
    return k;
  }
  static Mat jr(const Vec& x, const Coef& k) { return lie::so3_jr(x, k.a, k.b); }
  static Mat inverse(const Mat& J) { return J.inverse(); }
  static void djr_transpose_apply(const Vec& x, const Vec& s, Mat& N, const Coef& k) {
    lie::so3_djr_transpose_apply(x, s, k.a, k.b, k.al, k.be, N);
  }
  static void jr_transpose_hessian(const Vec& x, const Vec& u, const Coef& k, Mat E[3]) {
    lie::so3_jr_transpose_hessian(x, u, k.b, k.al, k.be, E);
  }
  static Mat ad_exp_minus(const Vec& x) { return pinocchio::exp3(x).transpose(); }
  static void djr(const Vec& x, Mat D[3]) { lie::so3_djr(x, D); }
  static Mat ad(const Vec& xi) { return lie::hat(xi); }
};

// d/dp [K(c p)^T M p] = K^T M + c d/dx[K(x)^T (M p)] = K^T (M - c N), K = Jr(c p)^-1 given with
// Jr's coefficients k at c p, and N(:, l) = dJr/dx_l^T K^T M p (the general path's dKT and
// velocity_jacobian).
template <int N>
typename FixedLie<N>::Mat phi_jacobian_K(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p,
                                         double c, const typename FixedLie<N>::Mat& K,
                                         const typename FixedLie<N>::Coef& k) {
  typedef FixedLie<N> L;
  const typename L::Vec s = K.transpose() * (M * p);
  typename L::Mat Nm;
  L::djr_transpose_apply(c * p, s, Nm, k);
  return K.transpose() * (M - c * Nm);
}

// The same with Jr and K computed; Jr(c p) into *jr.
template <int N>
typename FixedLie<N>::Mat phi_jacobian(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p,
                                       double c, typename FixedLie<N>::Mat* jr = nullptr) {
  typedef FixedLie<N> L;
  const typename L::Vec x = c * p;
  const typename L::Coef k = L::coefficients(x);
  const typename L::Mat J = L::jr(x, k);
  if (jr) *jr = J;
  return phi_jacobian_K<N>(M, p, c, L::inverse(J), k);
}

// The second derivatives of u(z) solving Jr(c z)^T u = b(z), b affine in z, from u, its first
// derivatives du (column a: du/dz_a) and Jr's coefficients k and inverse K at x = c z. Once more
// differentiating Jr^T du_a = db/dz_a - c G_a(u), G_a(w) = (dJr/dx_a)^T w (djr_transpose_apply's
// column a), gives
//   Jr^T d2u_al = -c (c E_al(u) + G_a(du_l) + G_l(du_a)),
// E_al(u) = dG_a(u)/dx_l (lie's jr_transpose_hessian): H[l](:, a) = d2u/dz_a dz_l, exact, where
// central differences of du would take 2 N closed-form evaluations. Two uses: u = K(c p)^T M p
// (phi_hessian: z = p) and u = K(x)^T p at fixed p (kt_hessian: z = x, c = 1).
template <int N>
void implicit_second_derivative(const typename FixedLie<N>::Vec& x, const typename FixedLie<N>::Coef& k,
                                const typename FixedLie<N>::Mat& K, const typename FixedLie<N>::Mat D[N],
                                const typename FixedLie<N>::Vec& u, const typename FixedLie<N>::Mat& du, double c,
                                typename FixedLie<N>::Mat H[N]) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  Mat G[N], E[N];  // G[l](:, a) = G_l(du_a) = dJr_l^T du_a, from dJr's matrices D at x
  for (int l = 0; l < N; ++l) G[l].noalias() = D[l].transpose() * du;
  L::jr_transpose_hessian(x, u, k, E);
  const Mat cKt = -c * K.transpose();
  for (int l = 0; l < N; ++l) {
    Mat S;
    for (int a = 0; a < N; ++a) S.col(a) = c * E[l].col(a) + G[a].col(l) + G[l].col(a);
    H[l].noalias() = cKt * S;
  }
}

// H[l] = d/dp_l of phi_jacobian(M, p, c) = d/dp [K(c p)^T M p], exactly (implicit_second_derivative),
// from dJr's matrices D at c p.
template <int N>
void phi_hessian(const typename FixedLie<N>::Mat& M, const typename FixedLie<N>::Vec& p, double c,
                 const typename FixedLie<N>::Mat D[N], typename FixedLie<N>::Mat H[N]) {
  typedef FixedLie<N> L;
  typedef typename L::Mat Mat;
  typedef typename L::Vec Vec;
  const Vec x = c * p;
  const typename L::Coef k = L::coefficients(x);
  const Mat K = L::inverse(L::jr(x, k));
  const Vec u = K.transpose() * (M * p);
  implicit_second_derivative<N>(x, k, K, D, u, phi_jacobian_K<N>(M, p, c, K, k), c, H);
}

}  // namespace var
}  // namespace dyn
}  // namespace geoddp
