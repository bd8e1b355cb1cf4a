// Closed forms of SO(3) and SE(3) right Jacobians and their derivatives, exact to round-off.
//
// C++ twins of geoddp.lie.SO3.right_jacobian_derivative_batch, geoddp.kernels.so3_right_jacobian
// and geoddp.kernels.se3_right_jacobian (same Taylor series and thresholds). Pinocchio's Jexp6 /
// dIntegrate lose up to 3e-5 in the SE(3) coupling block for rotations of 1e-5..1e-2 rad, so the
// reconstruction of the expansion (paper eq. for the exact second-order TSO(3)/product-group step)
// uses these instead.
//
// Conventions (Pinocchio's): right/local; SE(3) twists are [linear; angular].
// Jr(x) satisfies exp(x + d) = exp(x) exp(Jr(x) d + O(d^2)).
// The SE(3) derivative dJr is exact here (forward-mode dual numbers through the closed form),
// where the Python oracle differences its closed form (step 1e-5, ~1e-10 accurate).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross
#include <Eigen/LU>        // 3x3 inverse
#include <cmath>

namespace geoddp {
namespace lie {

typedef Eigen::Matrix<double, 3, 3> Mat3;
typedef Eigen::Matrix<double, 6, 6> Mat6;
typedef Eigen::Matrix<double, 3, 1> Vec3;

// ---------------------------------------------------------------- series helpers
// Horner evaluation of sum_i c[i] t2^i, templated so dual numbers pass through.
template <typename S>
inline S poly(const double* c, int n, const S& t2) {
  S out = S(c[n - 1]);
  for (int i = n - 2; i >= 0; --i) out = out * t2 + S(c[i]);
  return out;
}

inline double factorial(int n) {
  double f = 1.0;
  for (int i = 2; i <= n; ++i) f *= i;
  return f;
}

// Seven-term series (geoddp.lie): b = sum (-1)^k t^2k / (2k+3)!, alpha = a'/t, beta = b'/t.
struct SO3Series {
  double b[7], alpha[7], beta[7], q1[7], q2[7], q3[7];
  SO3Series() {
    for (int k = 0; k < 7; ++k) {
      double sgn = (k % 2 == 0) ? 1.0 : -1.0;
      b[k] = sgn / factorial(2 * k + 3);
      int kk = k + 1;
      double sg1 = (kk % 2 == 0) ? 1.0 : -1.0;
      alpha[k] = sg1 * 2.0 * kk / factorial(2 * kk + 2);
      beta[k] = sg1 * 2.0 * kk / factorial(2 * kk + 3);
      // SE(3) coupling Q's coefficients c1, c2, c3 (se3_coupling_coefficients)
      q1[k] = sgn / factorial(2 * k + 3);
      int j = k + 2;
      double sg2 = (j % 2 == 0) ? 1.0 : -1.0;
      q2[k] = sg2 / factorial(2 * j);
      q3[k] = sg2 * (j - 1) / factorial(2 * j + 1);
    }
  }
};

inline const SO3Series& series() {
  static const SO3Series s;
  return s;
}

inline Mat3 hat(const Vec3& x) {
  Mat3 K;
  K << 0.0, -x[2], x[1], x[2], 0.0, -x[0], -x[1], x[0], 0.0;
  return K;
}

// a, b, alpha, beta of Jr(x) = I - a hat(x) + b hat(x)^2 and of its derivative (geoddp.lie.so3._coefficients).
inline void so3_coefficients(double t, double& a, double& b, double& alpha, double& beta) {
  const SO3Series& s = series();
  const double t2 = t * t;
  if (t > 0.0) {
    const double half = 0.5 * t;
    const double sh = std::sin(half) / half;
    a = 0.5 * sh * sh;
  } else {
    a = 0.5;
  }
  const double sn = std::sin(t);
  const double omc = 2.0 * std::sin(0.5 * t) * std::sin(0.5 * t);
  b = (t < 0.25) ? poly(s.b, 7, t2) : (t - sn) / (t2 * t);
  if (t < 0.5) {
    alpha = poly(s.alpha, 7, t2);
    beta = poly(s.beta, 7, t2);
  } else {
    alpha = sn / (t2 * t) - 2.0 * omc / (t2 * t2);
    beta = omc / (t2 * t2) - 3.0 * (t - sn) / (t2 * t2 * t);
  }
}

// Jr(x) of SO(3), (3, 3), from its coefficients a, b at x (so3_coefficients).
inline Mat3 so3_jr(const Vec3& x, double a, double b) {
  const Mat3 K = hat(x);
  return Mat3::Identity() - a * K + b * (K * K);
}

// Jr(x) of SO(3), (3, 3).
inline Mat3 so3_jr(const Vec3& x) {
  double a, b, al, be;
  so3_coefficients(x.norm(), a, b, al, be);
  return so3_jr(x, a, b);
}

// Out(:, l) = (d Jr(x) / d x_l)^T u of SO(3), l = 0..2, from Jr's coefficients a, b, alpha, beta
// at x (so3_coefficients), without forming so3_djr's matrices: with K = hat(x), E = hat(e_l),
// D[l]^T = alpha x_l K + a E + beta x_l K^2 + b (K E + E K) (K, E skew, K^2 symmetric), so
//   D[l]^T u = alpha x_l (x × u) + a (e_l × u) + beta x_l (x × (x × u)) + b (x × (e_l × u) + e_l × (x × u)).
// About a third of the arithmetic of so3_djr and three matrix-vector products; equal to them to
// round-off (tests/test_core_dynamics.py, through se3_djr_transpose_apply).
inline void so3_djr_transpose_apply(const Vec3& x, const Vec3& u, double a, double b, double al, double be, Mat3& out) {
  const Vec3 xu = x.cross(u), xxu = x.cross(xu);
  for (int l = 0; l < 3; ++l) {
    const Vec3 eu = Vec3::Unit(l).cross(u);
    out.col(l) = (al * x[l]) * xu + a * eu + (be * x[l]) * xxu + b * (x.cross(eu) + Vec3::Unit(l).cross(xu));
  }
}

// D[l](i, j) = d Jr(x)(i, j) / d x_l of SO(3) (geoddp.lie.SO3.right_jacobian_derivative_batch),
// from Jr's coefficients a, b, alpha, beta at x (so3_coefficients).
inline void so3_djr(const Vec3& x, double a, double b, double al, double be, Mat3 D[3]) {
  const Mat3 K = hat(x);
  const Mat3 K2 = K * K;
  for (int l = 0; l < 3; ++l) {
    const Mat3 E = hat(Vec3::Unit(l));
    D[l] = -al * x[l] * K - a * E + be * x[l] * K2 + b * (E * K + K * E);
  }
}

// The same with the coefficients computed.
inline void so3_djr(const Vec3& x, Mat3 D[3]) {
  double a, b, al, be;
  so3_coefficients(x.norm(), a, b, al, be);
  so3_djr(x, a, b, al, be, D);
}

// ---------------------------------------------------------------- dual numbers (one direction)
struct Dual {
  double v, d;
  Dual(double v_ = 0.0, double d_ = 0.0) : v(v_), d(d_) {}
};
inline Dual operator+(const Dual& a, const Dual& b) { return Dual(a.v + b.v, a.d + b.d); }
inline Dual operator-(const Dual& a, const Dual& b) { return Dual(a.v - b.v, a.d - b.d); }
inline Dual operator-(const Dual& a) { return Dual(-a.v, -a.d); }
inline Dual operator*(const Dual& a, const Dual& b) { return Dual(a.v * b.v, a.d * b.v + a.v * b.d); }
inline Dual operator/(const Dual& a, const Dual& b) { return Dual(a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)); }
inline Dual sin(const Dual& a) { return Dual(std::sin(a.v), std::cos(a.v) * a.d); }
inline Dual cos(const Dual& a) { return Dual(std::cos(a.v), -std::sin(a.v) * a.d); }
inline Dual sqrt(const Dual& a) { const double s = std::sqrt(a.v); return Dual(s, 0.5 * a.d / s); }
inline double value(const Dual& a) { return a.v; }
inline double value(double a) { return a; }

template <typename S>
struct M3 {
  S m[3][3];
};

template <typename S>
inline M3<S> hat_t(const S x[3]) {
  M3<S> K;
  K.m[0][0] = S(0.0); K.m[0][1] = -x[2]; K.m[0][2] = x[1];
  K.m[1][0] = x[2];  K.m[1][1] = S(0.0); K.m[1][2] = -x[0];
  K.m[2][0] = -x[1]; K.m[2][1] = x[0];  K.m[2][2] = S(0.0);
  return K;
}

template <typename S>
inline M3<S> mul(const M3<S>& A, const M3<S>& B) {
  M3<S> C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      S s = A.m[i][0] * B.m[0][j];
      s = s + A.m[i][1] * B.m[1][j];
      s = s + A.m[i][2] * B.m[2][j];
      C.m[i][j] = s;
    }
  return C;
}

// Barfoot's Q(rho, phi) (3, 3), the coupling block of the SE(3) left Jacobian:
//   Q = 1/2 R + c1 (PR + RP + PRP) + c2 (PPR + RPP - 3 PRP) + c3 (PRPP + PPRP),  P = hat(p), R = hat(r),
// with c1, c2, c3 functions of t2 = |p|^2 (series below |p| = 0.6, closed form above).
// Evaluated through hat(a) hat(b) = b a^T - (a.b) I and hat(p) p = 0 instead of seven 3x3
// products (every SE(3) Jr and dJr of the expansions, the variational step and the log6 costs goes
// through it): with d = p.r, w = p x r,
//   PR + RP + PRP     = r p^T + p r^T - 2 d I - d P
//   PPR + RPP - 3 PRP = w p^T - p w^T + d P
//   PRPP + PPRP       = -2 d P^2,  P^2 = p p^T - t2 I.
// Equal to the product form to round-off (1e-15 relative from 1e-9 rad to pi, around the 0.6
// branch), and to the Python closed forms in tests/test_core_dynamics.py.
template <typename S>
inline void se3_coupling_coefficients(const S& t2, S& c1, S& c2, S& c3) {
  const SO3Series& ser = series();
  if (std::sqrt(value(t2)) < 0.6) {
    c1 = poly(ser.q1, 7, t2);
    c2 = poly(ser.q2, 7, t2);
    c3 = poly(ser.q3, 7, t2);
  } else {
    using std::sin; using std::cos; using std::sqrt;
    const S t = sqrt(t2);
    const S s = sin(t), c = cos(t);
    c1 = (t - s) / (t2 * t);
    c2 = (t2 + S(2.0) * c - S(2.0)) / (S(2.0) * t2 * t2);
    c3 = (S(2.0) * t - S(3.0) * s + t * c) / (S(2.0) * t2 * t2 * t);
  }
}

template <typename S>
inline M3<S> se3_coupling_assemble(const S r[3], const S p[3], const S& t2, const S& c1, const S& c2, const S& c3) {
  const S d = p[0] * r[0] + p[1] * r[1] + p[2] * r[2];
  const S w[3] = {p[1] * r[2] - p[2] * r[1], p[2] * r[0] - p[0] * r[2], p[0] * r[1] - p[1] * r[0]};
  const M3<S> P = hat_t(p), R = hat_t(r);
  const S m2 = S(-2.0) * c3 * d;  // the P^2 term's factor
  M3<S> Q;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      S q = S(0.5) * R.m[i][j] + c1 * (r[i] * p[j] + p[i] * r[j] - d * P.m[i][j]) +
            c2 * (w[i] * p[j] - p[i] * w[j] + d * P.m[i][j]) + m2 * (p[i] * p[j]);
      if (i == j) q = q - S(2.0) * c1 * d - m2 * t2;
      Q.m[i][j] = q;
    }
  return Q;
}

template <typename S>
inline M3<S> se3_coupling(const S r[3], const S p[3]) {
  const S t2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
  S c1, c2, c3;
  se3_coupling_coefficients(t2, c1, c2, c3);
  return se3_coupling_assemble(r, p, t2, c1, c2, c3);
}

// The scalar functions behind SE(3)'s Jr(x) and its derivative at one x: the rotation block's a, b,
// alpha, beta (so3_coefficients at |w|) and the coupling block's c1, c2, c3 with their
// t2-derivatives (dual parts; se3_coupling_coefficients at t2 = |w|^2). A caller that needs both
// Jr(x) and dJr(x)^T s at one x (the variational step's phi_jacobian) computes them once instead of
// twice; the values are bitwise those se3_jr computes (a dual's value part is the same double
// arithmetic, on the same t2).
struct Se3JrCoefficients {
  double a, b, al, be;
  Dual c1, c2, c3;
};
inline Se3JrCoefficients se3_jr_coefficients(const Eigen::Matrix<double, 6, 1>& x) {
  Se3JrCoefficients k;
  so3_coefficients(x.tail<3>().norm(), k.a, k.b, k.al, k.be);
  double p[3];
  for (int i = 0; i < 3; ++i) p[i] = -x[3 + i];
  // t2 summed as se3_coupling sums it, so that the values are bitwise se3_jr's
  se3_coupling_coefficients(Dual(p[0] * p[0] + p[1] * p[1] + p[2] * p[2], 1.0), k.c1, k.c2, k.c3);
  return k;
}

// Jr(x) of SE(3), x = [linear; angular]: [[Jr3(w), Q(-v, -w)], [0, Jr3(w)]], from Jr3's a, b
// and the coupling's c1, c2, c3 at x (both se3_jr below).
inline Mat6 se3_jr_assembled(const Eigen::Matrix<double, 6, 1>& x, double a, double b, double c1, double c2,
                             double c3) {
  Mat6 J = Mat6::Zero();
  const Mat3 J3 = so3_jr(x.tail<3>(), a, b);
  J.topLeftCorner<3, 3>() = J3;
  J.bottomRightCorner<3, 3>() = J3;
  double r[3], p[3];
  for (int i = 0; i < 3; ++i) { r[i] = -x[i]; p[i] = -x[3 + i]; }
  const double t2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
  const M3<double> Q = se3_coupling_assemble<double>(r, p, t2, c1, c2, c3);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) J(i, 3 + j) = Q.m[i][j];
  return J;
}

// Jr(x) of SE(3) from its coefficients at x (se3_jr_coefficients): bitwise se3_jr(x).
inline Mat6 se3_jr(const Eigen::Matrix<double, 6, 1>& x, const Se3JrCoefficients& k) {
  return se3_jr_assembled(x, k.a, k.b, k.c1.v, k.c2.v, k.c3.v);
}

// Jr(x) of SE(3), x = [linear; angular]: [[Jr3(w), Q(-v, -w)], [0, Jr3(w)]].
inline Mat6 se3_jr(const Eigen::Matrix<double, 6, 1>& x) {
  double a, b, al, be;
  so3_coefficients(x.tail<3>().norm(), a, b, al, be);
  const double t2 = x[3] * x[3] + x[4] * x[4] + x[5] * x[5];  // |p|^2, p = -w, as se3_coupling sums it
  double c1, c2, c3;
  se3_coupling_coefficients<double>(t2, c1, c2, c3);
  return se3_jr_assembled(x, a, b, c1, c2, c3);
}

// Jr(x)^-1 of SE(3) from Jr = [[J3, Q], [0, J3]]: [[A, -A Q A], [0, A]], A = J3^-1 (a 3x3
// cofactor inverse). Eigen's 6x6 inverse goes through a blocked LU and triangular solves on the
// identity, which costs more than the closed form of Jr itself.
inline Mat6 se3_jr_inverse(const Mat6& J) {
  const Mat3 A = J.topLeftCorner<3, 3>().inverse();
  Mat6 K = Mat6::Zero();
  K.topLeftCorner<3, 3>() = A;
  K.bottomRightCorner<3, 3>() = A;
  K.topRightCorner<3, 3>().noalias() = -(A * J.topRightCorner<3, 3>()) * A;
  return K;
}

// D[l](i, j) = d Jr(x)(i, j) / d x_l of SE(3), exact: the rotation blocks from so3_djr; the
// coupling block Q(r, p), r = -v, p = -w, by forward-mode dual numbers through its closed form.
// c1, c2, c3 depend on t2 = |p|^2 only, so they and their t2-derivatives are computed once (one
// dual evaluation seeded dt2 = 1) and each direction carries dc/dx_l = dc/dt2 * dt2/dx_l.
inline void se3_djr(const Eigen::Matrix<double, 6, 1>& x, Mat6 D[6]) {
  Mat3 D3[3];
  so3_djr(x.tail<3>(), D3);
  double rv[3], pv[3];
  for (int i = 0; i < 3; ++i) { rv[i] = -x[i]; pv[i] = -x[3 + i]; }
  const double t2v = pv[0] * pv[0] + pv[1] * pv[1] + pv[2] * pv[2];
  Dual c1, c2, c3;
  se3_coupling_coefficients(Dual(t2v, 1.0), c1, c2, c3);
  for (int l = 0; l < 6; ++l) {
    D[l].setZero();
    M3<double> Qd;
    if (l < 3) {
      // Q is linear in r (one hat(r) per term): its derivative along x_l = -r_l is Q(-e_l, p)
      double r[3] = {0.0, 0.0, 0.0};
      r[l] = -1.0;
      Qd = se3_coupling_assemble<double>(r, pv, t2v, c1.v, c2.v, c3.v);
    } else {
      D[l].topLeftCorner<3, 3>() = D3[l - 3];
      D[l].bottomRightCorner<3, 3>() = D3[l - 3];
      const int k = l - 3;  // x_l = -p_k: dp = -e_k, dt2 = -2 p_k
      const double dt2 = -2.0 * pv[k];
      Dual r[3], p[3];
      for (int i = 0; i < 3; ++i) {
        r[i] = Dual(rv[i], 0.0);
        p[i] = Dual(pv[i], i == k ? -1.0 : 0.0);
      }
      const M3<Dual> Q = se3_coupling_assemble<Dual>(r, p, Dual(t2v, dt2), Dual(c1.v, c1.d * dt2),
                                                     Dual(c2.v, c2.d * dt2), Dual(c3.v, c3.d * dt2));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Qd.m[i][j] = Q.m[i][j].d;
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) D[l](i, 3 + j) = Qd.m[i][j];
  }
}

// N(:, l) = dJr(x)/dx_l^T s of SE(3) (6, 6), what se3_djr's D[l]^T s gives, without forming D:
// D[l] = [[D3, Qd], [0, D3]] (D3 = 0 along the translation), so D[l]^T s = [D3^T s_t; Qd^T s_t +
// D3^T s_b], and Qd^T s_t is a derivative of f_j = (s_t^T Q(r, p))_j, r = -x_lin, p = -x_ang. From
// the closed form above (d = p.r, w = p x r, s = s_t, (s^T P)_j = (s x p)_j):
//   f_j = 1/2 (s x r)_j + c1 X1_j + c2 X2_j - 2 c3 d (s.p) p_j - 2 (c1 - c3 t2) d s_j,
//   X1_j = (s.r) p_j + (s.p) r_j - d (s x p)_j,   X2_j = (s.w) p_j - (s.p) w_j + d (s x p)_j,
// linear in r, and a polynomial in p times c1, c2, c3 (functions of t2 = |p|^2, derivatives c'
// from one dual evaluation), so both gradients are closed forms (N = -gradient: x = -(r, p)):
//   grad_r f_j = 1/2 (e_j x s) + c1 (p_j s + (s.p) e_j - (s x p)_j p)
//                + c2 (p_j (s x p) - (s.p)(e_j x p) + (s x p)_j p) - 2 c3 (s.p) p_j p - 2 (c1 - c3 t2) s_j p,
//   grad_p f_j = 2 c1' X1_j p + c1 ((s.r) e_j + r_j s - (s x p)_j r - d (e_j x s))
//                + 2 c2' X2_j p + c2 ((r x s) p_j + (s.w) e_j - w_j s - (s.p)(r x e_j) + (s x p)_j r + d (e_j x s))
//                - 2 (2 c3' Y_j p + c3 ((s.p) p_j r + d p_j s + d (s.p) e_j)),  Y_j = d (s.p) p_j,
//                - 2 s_j (2 d (c1' - c3' t2 - c3) p + (c1 - c3 t2) r).
// Equal to se3_djr's D[l]^T s to round-off (the variational tests check F1 against the Python
// oracle to 1e-10 through it).
// The rotation blocks' D3^T s_t and D3^T s_b come from so3_djr_transpose_apply. k: the
// coefficients at x (se3_jr_coefficients).
inline void se3_djr_transpose_apply(const Eigen::Matrix<double, 6, 1>& x, const Eigen::Matrix<double, 6, 1>& s,
                                    Mat6& N, const Se3JrCoefficients& k) {
  const Vec3 r = -x.head<3>(), p = -x.tail<3>();
  const double t2 = p.squaredNorm();
  const double c1 = k.c1.v, c2 = k.c2.v, c3 = k.c3.v, c1p = k.c1.d, c2p = k.c2.d, c3p = k.c3.d;
  const Vec3 st = s.head<3>(), sb = s.tail<3>();
  const double sp = st.dot(p), sr = st.dot(r), d = p.dot(r);
  const Vec3 sxp = st.cross(p), w = p.cross(r), rxs = r.cross(st);
  const double sw = st.dot(w), Z = c1 - c3 * t2, Zp = c1p - c3p * t2 - c3;
  for (int j = 0; j < 3; ++j) {
    const Vec3 e = Vec3::Unit(j);
    const Vec3 exs = e.cross(st);
    const Vec3 gr = 0.5 * exs + c1 * (p[j] * st + sp * e - sxp[j] * p) + c2 * (p[j] * sxp - sp * e.cross(p) + sxp[j] * p) -
                    (2.0 * c3 * sp * p[j]) * p - (2.0 * Z * st[j]) * p;
    const double X1 = sr * p[j] + sp * r[j] - d * sxp[j], X2 = sw * p[j] - sp * w[j] + d * sxp[j], Y = d * sp * p[j];
    const Vec3 gp = (2.0 * c1p * X1) * p + c1 * (sr * e + r[j] * st - sxp[j] * r - d * exs) + (2.0 * c2p * X2) * p +
                    c2 * (p[j] * rxs + sw * e - w[j] * st - sp * r.cross(e) + sxp[j] * r + d * exs) -
                    2.0 * ((2.0 * c3p * Y) * p + c3 * ((sp * p[j]) * r + (d * p[j]) * st + (d * sp) * e)) -
                    (2.0 * st[j]) * ((2.0 * d * Zp) * p + Z * r);
    for (int l = 0; l < 3; ++l) {
      N(3 + j, l) = -gr[l];
      N(3 + j, 3 + l) = -gp[l];
    }
  }
  Mat3 Dt, Db;
  so3_djr_transpose_apply(x.tail<3>(), st, k.a, k.b, k.al, k.be, Dt);
  so3_djr_transpose_apply(x.tail<3>(), sb, k.a, k.b, k.al, k.be, Db);
  N.topLeftCorner<3, 3>().setZero();
  N.topRightCorner<3, 3>() = Dt;
  N.bottomRightCorner<3, 3>() += Db;
}

inline void se3_djr_transpose_apply(const Eigen::Matrix<double, 6, 1>& x, const Eigen::Matrix<double, 6, 1>& s,
                                    Mat6& N) {
  se3_djr_transpose_apply(x, s, N, se3_jr_coefficients(x));
}

// ---------------------------------------------------------------- second derivatives of Jr
// E[b](:, a) = d^2 (Jr(x)^T u) / dx_a dx_b at fixed u (symmetric in a, b): the x-derivative of
// djr_transpose_apply's column a along x_b. The variational step's second order needs it for the
// Hessian of x -> Jr(x)^-T p (dynamics/variational_fixed.hpp, implicit_second_derivative), exactly
// and cheaper than central differences of the analytic first derivative (~1e-10 at 4 N Jacobians).
// Closed forms: the product rule on the terms of the first derivatives above, with the scalar
// coefficients' second derivatives in t2 = |w|^2 from a second-order Taylor jet (Jet2) through their
// series (below |w| = 1.5, where the closed forms' second derivatives cancel to ~1e-11) or closed
// forms. Checked against O(h^4) differences of djr_transpose_apply from the identity to near pi
// (tests/test_core_dynamics.py).

// f, f' and f'' in one variable, propagated by the chain and product rules.
struct Jet2 {
  double v, d, dd;
  Jet2(double v_ = 0.0, double d_ = 0.0, double dd_ = 0.0) : v(v_), d(d_), dd(dd_) {}
};
inline Jet2 operator+(const Jet2& a, const Jet2& b) { return Jet2(a.v + b.v, a.d + b.d, a.dd + b.dd); }
inline Jet2 operator-(const Jet2& a, const Jet2& b) { return Jet2(a.v - b.v, a.d - b.d, a.dd - b.dd); }
inline Jet2 operator*(const Jet2& a, const Jet2& b) {
  return Jet2(a.v * b.v, a.d * b.v + a.v * b.d, a.dd * b.v + 2.0 * a.d * b.d + a.v * b.dd);
}
inline Jet2 operator/(const Jet2& a, const Jet2& b) {
  const double q = a.v / b.v, qd = (a.d - q * b.d) / b.v;
  return Jet2(q, qd, (a.dd - 2.0 * qd * b.d - q * b.dd) / b.v);
}
inline Jet2 sin(const Jet2& a) {
  const double s = std::sin(a.v), c = std::cos(a.v);
  return Jet2(s, c * a.d, c * a.dd - s * a.d * a.d);
}
inline Jet2 cos(const Jet2& a) {
  const double s = std::sin(a.v), c = std::cos(a.v);
  return Jet2(c, -s * a.d, -s * a.dd - c * a.d * a.d);
}
inline Jet2 sqrt(const Jet2& a) {
  const double r = std::sqrt(a.v);
  return Jet2(r, 0.5 * a.d / r, 0.5 * a.dd / r - 0.25 * a.d * a.d / (r * a.v));
}

// Fourteen-term series in t2 of a = (1 - cos t) / t^2, b = (t - sin t) / t^3 and the coupling's
// c1 (= b), c2, c3 (SO3Series' q2, q3 continued): round-off accurate below t = 1.5.
struct CurvatureSeries {
  static constexpr int n = 14;
  double a[n], b[n], q2[n], q3[n];
  CurvatureSeries() {
    for (int k = 0; k < n; ++k) {
      const double sgn = (k % 2 == 0) ? 1.0 : -1.0;
      a[k] = sgn / factorial(2 * k + 2);
      b[k] = sgn / factorial(2 * k + 3);
      q2[k] = sgn / factorial(2 * k + 4);
      q3[k] = sgn * (k + 1) / factorial(2 * k + 5);
    }
  }
};

inline const CurvatureSeries& curvature_series() {
  static const CurvatureSeries s;
  return s;
}

// The second t2-derivatives a'', b'' of Jr3's coefficients and c1'', c2'', c3'' of the coupling's,
// at t2 = |w|^2.
struct SecondCoefficients {
  double a2, b2, c2[3];
};
inline SecondCoefficients second_coefficients(double t2v) {
  const CurvatureSeries& s = curvature_series();
  const Jet2 t2(t2v, 1.0);
  Jet2 a, b, c2, c3;
  if (std::sqrt(t2v) < 1.5) {
    a = poly(s.a, s.n, t2);
    b = poly(s.b, s.n, t2);
    c2 = poly(s.q2, s.n, t2);
    c3 = poly(s.q3, s.n, t2);
  } else {
    const Jet2 t = sqrt(t2), sn = sin(t), cs = cos(t), one(1.0), two(2.0);
    a = (one - cs) / t2;
    b = (t - sn) / (t2 * t);
    c2 = (t2 + two * cs - two) / (two * t2 * t2);
    c3 = (two * t - Jet2(3.0) * sn + t * cs) / (two * t2 * t2 * t);
  }
  return SecondCoefficients{a.dd, b.dd, {b.dd, c2.dd, c3.dd}};
}

// E[b](i, l) = d^2 (Jr(x)^T u)_i / dx_l dx_b of SO(3), added to E (E += ...), from Jr's
// coefficients a, b, alpha, beta at x (so3_coefficients) and ga = 4 a'', de = 4 b'' (t2-derivatives).
// With m = x × u, n = x × (x × u) (Jr^T u = u + a m + b n), da/dx_j = alpha x_j, d alpha/dx_j = ga x_j
// (and b, beta, de alike):
//   d_j d_l (Jr^T u) = (ga x_j x_l + alpha d_jl) m + alpha (x_l e_j × u + x_j e_l × u)
//                      + (de x_j x_l + beta d_jl) n + beta (x_l d_j n + x_j d_l n) + b d_jl n,
//   d_l n = e_l × (x × u) + x × (e_l × u),  d_j d_l n = e_j u_l + e_l u_j - 2 d_jl u.
inline void so3_jr_transpose_hessian_add(const Vec3& x, const Vec3& u, double b, double al, double be, double ga,
                                         double de, Mat3 E[3]) {
  const Vec3 m = x.cross(u), n = x.cross(m);
  Vec3 dn[3], eu[3];
  for (int l = 0; l < 3; ++l) {
    eu[l] = Vec3::Unit(l).cross(u);
    dn[l] = Vec3::Unit(l).cross(m) + x.cross(eu[l]);
  }
  for (int j = 0; j < 3; ++j)
    for (int l = j; l < 3; ++l) {
      Vec3 h = (ga * x[j] * x[l]) * m + al * (x[l] * eu[j] + x[j] * eu[l]) + (de * x[j] * x[l]) * n +
               be * (x[l] * dn[j] + x[j] * dn[l]);
      h[j] += b * u[l];
      h[l] += b * u[j];
      if (j == l) h += (al * m + be * n) - (2.0 * b) * u;
      E[j].col(l) += h;
      if (l != j) E[l].col(j) += h;
    }
}

// E[b](i, l) = d^2 (Jr(x)^T u)_i / dx_l dx_b of SO(3), from Jr's coefficients at x.
inline void so3_jr_transpose_hessian(const Vec3& x, const Vec3& u, double b, double al, double be, Mat3 E[3]) {
  const SecondCoefficients k2 = second_coefficients(x.squaredNorm());
  for (int l = 0; l < 3; ++l) E[l].setZero();
  so3_jr_transpose_hessian_add(x, u, b, al, be, 4.0 * k2.a2, 4.0 * k2.b2, E);
}

// The same of SE(3), x = [linear; angular], from Jr's coefficients at x (se3_jr_coefficients).
// Jr^T u = [J3^T u_t; Q(r, p)^T u_t + J3^T u_b] (r = -x_lin, p = -w): the rotation blocks' Hessians
// as SO(3)'s, and that of f = Q^T s (s = u_t), linear in r, so zero along two linear directions.
// From se3_djr_transpose_apply's f = 1/2 s × r + c1 A + c2 B - 2 c3 C with (rho = p.r, sig = p.s,
// k = s × p, kap = k.r, w = p × r, all polynomials in p)
//   A = (s.r) p + sig r - 2 rho s - rho k,  B = kap p - sig w + rho k,  C = rho (sig p - t2 s),
// the p-p block is sum_i [(4 c_i'' p_a p_b + 2 c_i' d_ab) X_i + 2 c_i' (p_a d_b X_i + p_b d_a X_i)
// + c_i d_a d_b X_i] (X = A, B, C with the weights 1, 1, -2), and the r_a-p_b block the p_b-derivative
// of df/dr_a = 1/2 s × e_a + c1 A_a + c2 B_a - 2 c3 C_a,
//   A_a = s_a p + sig e_a - 2 p_a s - p_a k,  B_a = k_a p - sig (p × e_a) + p_a k,  C_a = p_a (sig p - t2 s).
// Two minus signs (x = -(r, p)) cancel in every second derivative.
inline void se3_jr_transpose_hessian(const Eigen::Matrix<double, 6, 1>& x, const Eigen::Matrix<double, 6, 1>& u,
                                     const Se3JrCoefficients& k, Mat6 E[6]) {
  const Vec3 xw = x.tail<3>(), r = -x.head<3>(), p = -xw, s = u.head<3>();
  const double t2 = p.squaredNorm();
  const SecondCoefficients k2 = second_coefficients(t2);
  for (int l = 0; l < 6; ++l) E[l].setZero();
  // rotation blocks: top-right from u_t, bottom-right from u_b (rows 0-2 and 3-5, angular columns)
  Mat3 Et[3] = {Mat3::Zero(), Mat3::Zero(), Mat3::Zero()}, Eb[3] = {Mat3::Zero(), Mat3::Zero(), Mat3::Zero()};
  so3_jr_transpose_hessian_add(xw, s, k.b, k.al, k.be, 4.0 * k2.a2, 4.0 * k2.b2, Et);
  so3_jr_transpose_hessian_add(xw, u.tail<3>(), k.b, k.al, k.be, 4.0 * k2.a2, 4.0 * k2.b2, Eb);
  const double c[3] = {k.c1.v, k.c2.v, -2.0 * k.c3.v}, cp[3] = {k.c1.d, k.c2.d, -2.0 * k.c3.d},
               cpp[3] = {k2.c2[0], k2.c2[1], -2.0 * k2.c2[2]};
  const double sig = p.dot(s), rho = p.dot(r), sr = s.dot(r);
  const Vec3 kk = s.cross(p), w = p.cross(r), rxs = r.cross(s);
  const double kap = kk.dot(r);
  Vec3 X[3], dX[3][3], sxe[3];
  X[0] = sr * p + sig * r - (2.0 * rho) * s - rho * kk;
  X[1] = kap * p - sig * w + rho * kk;
  X[2] = rho * (sig * p - t2 * s);
  for (int b = 0; b < 3; ++b) {
    const Vec3 e = Vec3::Unit(b);
    sxe[b] = s.cross(e);
    dX[0][b] = sr * e + s[b] * r - (2.0 * r[b]) * s - r[b] * kk - rho * sxe[b];
    dX[1][b] = rxs[b] * p + kap * e - s[b] * w - sig * e.cross(r) + r[b] * kk + rho * sxe[b];
    dX[2][b] = (r[b] * sig + rho * s[b]) * p + (rho * sig) * e - (r[b] * t2 + 2.0 * rho * p[b]) * s;
  }
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b) {
      const Vec3 ea = Vec3::Unit(a), eb = Vec3::Unit(b);
      Vec3 ddX[3];
      ddX[0] = -r[b] * sxe[a] - r[a] * sxe[b];
      ddX[1] = rxs[b] * ea + rxs[a] * eb - s[b] * ea.cross(r) - s[a] * eb.cross(r) + r[b] * sxe[a] + r[a] * sxe[b];
      ddX[2] = (r[b] * s[a] + r[a] * s[b]) * p + (r[b] * sig + rho * s[b]) * ea + (r[a] * sig + rho * s[a]) * eb -
               (2.0 * (r[b] * p[a] + r[a] * p[b])) * s;
      if (a == b) ddX[2] -= (2.0 * rho) * s;
      Vec3 h = Vec3::Zero();
      for (int i = 0; i < 3; ++i) {
        double f2 = 4.0 * cpp[i] * p[a] * p[b];
        if (a == b) f2 += 2.0 * cp[i];
        h += f2 * X[i] + (2.0 * cp[i]) * (p[a] * dX[i][b] + p[b] * dX[i][a]) + c[i] * ddX[i];
      }
      E[3 + a].block<3, 1>(3, 3 + b) = h;
      E[3 + b].block<3, 1>(3, 3 + a) = h;
    }
  // the r_a-p_b block: d/dp_b of df/dr_a (the mixed second derivative along x_lin_a, w_b)
  for (int a = 0; a < 3; ++a) {
    const Vec3 ea = Vec3::Unit(a), pxe = p.cross(ea);
    const Vec3 Xa[3] = {s[a] * p + sig * ea - (2.0 * p[a]) * s - p[a] * kk, kk[a] * p - sig * pxe + p[a] * kk,
                        p[a] * (sig * p - t2 * s)};
    for (int b = 0; b < 3; ++b) {
      const Vec3 eb = Vec3::Unit(b);
      const Vec3 dXa[3] = {
          s[a] * eb + s[b] * ea - (a == b ? Vec3(2.0 * s + kk) : Vec3::Zero()) - p[a] * sxe[b],
          sxe[b][a] * p + kk[a] * eb - s[b] * pxe - sig * eb.cross(ea) + (a == b ? kk : Vec3(Vec3::Zero())) + p[a] * sxe[b],
          (a == b ? Vec3(sig * p - t2 * s) : Vec3::Zero()) + p[a] * (s[b] * p + sig * eb - (2.0 * p[b]) * s)};
      Vec3 h = Vec3::Zero();
      for (int i = 0; i < 3; ++i) h += (2.0 * cp[i] * p[b]) * Xa[i] + c[i] * dXa[i];
      E[3 + b].block<3, 1>(3, a) = h;  // d/dw_b of column a (linear)
      E[a].block<3, 1>(3, 3 + b) = h;  // d/dx_lin_a of column 3 + b
    }
  }
  for (int l = 0; l < 3; ++l) {
    E[3 + l].block<3, 3>(0, 3) += Et[l];
    E[3 + l].block<3, 3>(3, 3) += Eb[l];
  }
}

// Structure constants of so(3) and se(3): [x, y]_i = sum_{p, q} C[i](p, q) x_p y_q
// (the structure_constants of geoddp.lie.so3 and geoddp.lie.se3: ad of se(3) in [linear; angular]
// order).
inline void so3_structure(Mat3 C[3]) {
  for (int i = 0; i < 3; ++i) C[i].setZero();
  for (int p = 0; p < 3; ++p) {
    const Mat3 E = hat(Vec3::Unit(p));  // [e_p, e_q]_i = hat(e_p)(i, q)
    for (int i = 0; i < 3; ++i)
      for (int q = 0; q < 3; ++q) C[i](p, q) = E(i, q);
  }
}

inline void se3_structure(Mat6 C[6]) {
  for (int i = 0; i < 6; ++i) C[i].setZero();
  for (int p = 0; p < 6; ++p) {
    // ad_{e_p} = [[hat(w), hat(v)], [0, hat(w)]] with e_p = (v, w)
    Vec3 v = Vec3::Zero(), w = Vec3::Zero();
    if (p < 3) v[p] = 1.0; else w[p - 3] = 1.0;
    Mat6 ad = Mat6::Zero();
    ad.topLeftCorner<3, 3>() = hat(w);
    ad.topRightCorner<3, 3>() = hat(v);
    ad.bottomRightCorner<3, 3>() = hat(w);
    for (int i = 0; i < 6; ++i)
      for (int q = 0; q < 6; ++q) C[i](p, q) = ad(i, q);
  }
}

// The structure constants of so(3) and se(3), made once per user (dynamics/expansion.cpp,
// riccati/contracted.cpp).
struct GroupStructure {
  Mat3 C3[3];
  Mat6 C6[6];
  GroupStructure() {
    so3_structure(C3);
    se3_structure(C6);
  }
};

}  // namespace lie
}  // namespace geoddp
