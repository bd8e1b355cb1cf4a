// The rigid body on TSO(3) in closed form (see tso3/tso3.hpp). The loops are written out over the
// 3 x 3 blocks: at these sizes that is faster than any matrix library's dispatch, and it keeps
// the order of every sum fixed.
#include "tso3/tso3.hpp"

#include "lie/right_jacobians.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

namespace geoddp {
namespace tso3 {

namespace {

inline void matmul33(const double* A, const double* B, double* out) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

// out = Om + dt I^-1 ((I Om) x Om + tau)   (paper eq. disceqs, velocity part).
inline void velocity_step(const Body& b, const double* Om, const double* tau, double* out) {
  const double* I = b.inertia;
  const double* Ii = b.inertia_inv;
  const double L0 = I[0] * Om[0] + I[1] * Om[1] + I[2] * Om[2];
  const double L1 = I[3] * Om[0] + I[4] * Om[1] + I[5] * Om[2];
  const double L2 = I[6] * Om[0] + I[7] * Om[1] + I[8] * Om[2];
  const double g0 = L1 * Om[2] - L2 * Om[1] + tau[0];
  const double g1 = L2 * Om[0] - L0 * Om[2] + tau[1];
  const double g2 = L0 * Om[1] - L1 * Om[0] + tau[2];
  for (int i = 0; i < 3; ++i) out[i] = Om[i] + b.dt * (Ii[3 * i] * g0 + Ii[3 * i + 1] * g1 + Ii[3 * i + 2] * g2);
}

}  // namespace

void so3_exp(double x0, double x1, double x2, double* out) {
  const double t2 = x0 * x0 + x1 * x1 + x2 * x2;
  const double t = std::sqrt(t2);
  double s, a;
  if (t < 1e-4) {
    s = 1.0 - t2 / 6.0;
    a = 0.5 - t2 / 24.0;
  } else {
    s = std::sin(t) / t;
    const double h = std::sin(0.5 * t) / (0.5 * t);
    a = 0.5 * h * h;
  }
  out[0] = 1.0 - a * (x1 * x1 + x2 * x2);
  out[4] = 1.0 - a * (x0 * x0 + x2 * x2);
  out[8] = 1.0 - a * (x0 * x0 + x1 * x1);
  out[1] = -s * x2 + a * x0 * x1;
  out[3] = s * x2 + a * x0 * x1;
  out[2] = s * x1 + a * x0 * x2;
  out[6] = -s * x1 + a * x0 * x2;
  out[5] = -s * x0 + a * x1 * x2;
  out[7] = s * x0 + a * x1 * x2;
}

void so3_log(const double* R, double* out) {
  const double w0 = 0.5 * (R[7] - R[5]);
  const double w1 = 0.5 * (R[2] - R[6]);
  const double w2 = 0.5 * (R[3] - R[1]);
  const double s = std::sqrt(w0 * w0 + w1 * w1 + w2 * w2);  // sin(theta)
  const double c = 0.5 * (R[0] + R[4] + R[8] - 1.0);         // cos(theta)
  const double t = std::atan2(s, c);
  if (c > -0.99) {
    // theta / sin(theta), with its series where sin(theta) ~ theta
    const double f = s < 1e-6 ? 1.0 + s * s / 6.0 : t / s;
    out[0] = f * w0;
    out[1] = f * w1;
    out[2] = f * w2;
    return;
  }
  // Near pi the skew part vanishes: the axis from the symmetric part,
  // (R + R^T)/2 - cos I = (1 - cos) n n^T, its sign from the skew part.
  const double d0 = R[0] - c, d1 = R[4] - c, d2 = R[8] - c, omc = 1.0 - c;
  double n0, n1, n2;
  if (d0 >= d1 && d0 >= d2) {
    n0 = std::sqrt(std::max(d0 / omc, 0.0));
    n1 = 0.5 * (R[1] + R[3]) / (omc * n0);
    n2 = 0.5 * (R[2] + R[6]) / (omc * n0);
  } else if (d1 >= d2) {
    n1 = std::sqrt(std::max(d1 / omc, 0.0));
    n0 = 0.5 * (R[1] + R[3]) / (omc * n1);
    n2 = 0.5 * (R[5] + R[7]) / (omc * n1);
  } else {
    n2 = std::sqrt(std::max(d2 / omc, 0.0));
    n0 = 0.5 * (R[2] + R[6]) / (omc * n2);
    n1 = 0.5 * (R[5] + R[7]) / (omc * n2);
  }
  const double nn = std::sqrt(n0 * n0 + n1 * n1 + n2 * n2);
  n0 /= nn;
  n1 /= nn;
  n2 /= nn;
  if (n0 * w0 + n1 * w1 + n2 * w2 < 0.0) {
    n0 = -n0;
    n1 = -n1;
    n2 = -n2;
  }
  out[0] = t * n0;
  out[1] = t * n1;
  out[2] = t * n2;
}

void jr_and_derivative(const double* x, double* Jr, double* Dsym, bool derivative) {
  const lie::Vec3 xv(x[0], x[1], x[2]);
  double a, b, alpha, beta;
  lie::so3_coefficients(xv.norm(), a, b, alpha, beta);
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> J(Jr);
  J = lie::so3_jr(xv, a, b);
  if (!derivative) return;
  lie::Mat3 D[3];  // D[l](i, j) = d Jr(i, j) / d x_l
  lie::so3_djr(xv, a, b, alpha, beta, D);
  for (int i = 0; i < 3; ++i)
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) Dsym[9 * i + 3 * p + q] = 0.5 * (D[q](i, p) + D[p](i, q));
}

bool rollout(const Body& body, int H, const double* R0, const double* Om0, const double* R_bar, const double* Om_bar,
             const double* u_bar, const double* k_ff, const double* K_fb, double gamma, const double* lower,
             const double* upper, double* R, double* Om, double* u) {
  const int m = body.m;
  const double dt = body.dt;
  std::copy(R0, R0 + 9, R);
  std::copy(Om0, Om0 + 3, Om);
  double E[9], Ex[9], zeta[6], tau[3], next[3];
  for (int k = 0; k < H; ++k) {
    const double* Rk = R + 9 * k;
    const double* Omk = Om + 3 * k;
    double* uk = u + (size_t)m * k;
    if (K_fb) {
      const double* Rb = R_bar + 9 * k;
      for (int i = 0; i < 3; ++i)  // E = R_bar^T R
        for (int j = 0; j < 3; ++j) E[3 * i + j] = Rb[i] * Rk[j] + Rb[3 + i] * Rk[3 + j] + Rb[6 + i] * Rk[6 + j];
      so3_log(E, zeta);
      for (int i = 0; i < 3; ++i) zeta[3 + i] = Omk[i] - Om_bar[3 * k + i];
      const double* Kk = K_fb + (size_t)6 * m * k;
      for (int a = 0; a < m; ++a) {
        double acc = u_bar[(size_t)m * k + a] - gamma * k_ff[(size_t)m * k + a];
        for (int b = 0; b < 6; ++b) acc -= Kk[6 * a + b] * zeta[b];
        if (lower) {  // explicit comparisons: a NaN stays NaN
          if (acc < lower[(size_t)m * k + a]) acc = lower[(size_t)m * k + a];
          else if (acc > upper[(size_t)m * k + a]) acc = upper[(size_t)m * k + a];
        }
        uk[a] = acc;
      }
    } else {
      std::copy(u_bar + (size_t)m * k, u_bar + (size_t)m * (k + 1), uk);
    }
    for (int i = 0; i < 3; ++i) {
      double acc = 0.0;
      for (int a = 0; a < m; ++a) acc += body.actuation[(size_t)m * i + a] * uk[a];
      tau[i] = acc;
    }
    velocity_step(body, Omk, tau, next);
    const double* w = body.semi_implicit ? next : Omk;
    so3_exp(dt * w[0], dt * w[1], dt * w[2], Ex);
    matmul33(Rk, Ex, R + 9 * (k + 1));
    bool finite = true;
    for (int i = 0; i < 3; ++i) {
      Om[3 * (k + 1) + i] = next[i];
      if (!std::isfinite(next[i])) finite = false;
    }
    if (!finite) return false;
  }
  return true;
}

void linearise(const Body& body, int H, const double* Om, bool second_order, double* Phi, double* B, double* Theta,
               double* Gamma, double* Xi) {
  const int m = body.m, nz = 6 + m;
  const double dt = body.dt;
  const double* I = body.inertia;
  const double* Ii = body.inertia_inv;
  const double* Hm = body.actuation;
  // Fu = dt I^-1 H (3, m)
  std::vector<double> Fu(3 * m);
  double* Fuh = Fu.data();
  for (int i = 0; i < 3; ++i)
    for (int a = 0; a < m; ++a) Fuh[m * i + a] = dt * (Ii[3 * i] * Hm[a] + Ii[3 * i + 1] * Hm[m + a] + Ii[3 * i + 2] * Hm[2 * m + a]);
  // the constant second derivative of Om+ in Om: T[i, j, l] = dt I^-1((I e_j) x e_l + (I e_l) x e_j)
  double T[27] = {0.0};
  for (int j = 0; j < 3; ++j)
    for (int l = 0; l < 3; ++l) {
      const double Ij0 = I[j], Ij1 = I[3 + j], Ij2 = I[6 + j];  // column j of I
      const double c0 = Ij1 * (l == 2 ? 1.0 : 0.0) - Ij2 * (l == 1 ? 1.0 : 0.0);
      const double c1 = Ij2 * (l == 0 ? 1.0 : 0.0) - Ij0 * (l == 2 ? 1.0 : 0.0);
      const double c2 = Ij0 * (l == 1 ? 1.0 : 0.0) - Ij1 * (l == 0 ? 1.0 : 0.0);
      for (int i = 0; i < 3; ++i) T[9 * i + 3 * j + l] += dt * (Ii[3 * i] * c0 + Ii[3 * i + 1] * c1 + Ii[3 * i + 2] * c2);
    }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int l = 0; l <= j; ++l) {
        const double s = T[9 * i + 3 * j + l] + T[9 * i + 3 * l + j];
        T[9 * i + 3 * j + l] = s;
        T[9 * i + 3 * l + j] = s;
      }
  std::vector<double> W1(3 * nz), JW(3 * nz), DW(3 * nz);  // reconstruction velocity's first order in z, Jr W1
  double Ex[9], A[9], Jr[9], Dsym[27], Fx[9], G[9], L[3], w[3];
  for (int k = 0; k < H; ++k) {
    const double* Omk = Om + 3 * k;
    for (int i = 0; i < 3; ++i) L[i] = I[3 * i] * Omk[0] + I[3 * i + 1] * Omk[1] + I[3 * i + 2] * Omk[2];
    // Fx = I + dt I^-1 (hat(I Om) - hat(Om) I): column j is L x e_j - Om x I e_j
    for (int j = 0; j < 3; ++j) {
      const double e0 = j == 0 ? 1.0 : 0.0, e1 = j == 1 ? 1.0 : 0.0, e2 = j == 2 ? 1.0 : 0.0;
      G[j] = (L[1] * e2 - L[2] * e1) - (Omk[1] * I[6 + j] - Omk[2] * I[3 + j]);
      G[3 + j] = (L[2] * e0 - L[0] * e2) - (Omk[2] * I[j] - Omk[0] * I[6 + j]);
      G[6 + j] = (L[0] * e1 - L[1] * e0) - (Omk[0] * I[3 + j] - Omk[1] * I[j]);
    }
    matmul33(Ii, G, Fx);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) Fx[3 * i + j] *= dt;
      Fx[4 * i] += 1.0;
    }
    for (int i = 0; i < 3; ++i) w[i] = dt * (body.semi_implicit ? Om[3 * (k + 1) + i] : Omk[i]);
    so3_exp(w[0], w[1], w[2], Ex);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) A[3 * i + j] = Ex[3 * j + i];
    jr_and_derivative(w, Jr, Dsym, second_order);
    std::fill(W1.begin(), W1.end(), 0.0);
    if (body.semi_implicit) {
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) W1[nz * i + 3 + j] = Fx[3 * i + j];
        for (int a = 0; a < m; ++a) W1[nz * i + 6 + a] = Fuh[m * i + a];
      }
    } else {
      for (int i = 0; i < 3; ++i) W1[nz * i + 3 + i] = 1.0;
    }
    for (int i = 0; i < 3; ++i)
      for (int b = 0; b < nz; ++b) JW[nz * i + b] = Jr[3 * i] * W1[b] + Jr[3 * i + 1] * W1[nz + b] + Jr[3 * i + 2] * W1[2 * nz + b];
    // first order
    double* Ph = Phi + (size_t)36 * k;
    double* Bk = B + (size_t)6 * m * k;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        Ph[6 * i + j] = A[3 * i + j] + dt * JW[nz * i + j];
        Ph[6 * i + 3 + j] = dt * JW[nz * i + 3 + j];
        Ph[6 * (3 + i) + j] = 0.0;
        Ph[6 * (3 + i) + 3 + j] = Fx[3 * i + j];
      }
      for (int a = 0; a < m; ++a) {
        Bk[m * i + a] = dt * JW[nz * i + 6 + a];
        Bk[m * (3 + i) + a] = Fuh[m * i + a];
      }
    }
    if (!second_order) continue;
    double* Th = Theta + (size_t)216 * k;  // (6, 6, 6)
    double* Ga = Gamma + (size_t)36 * m * k;  // (6, 6, m)
    double* X = Xi + (size_t)6 * m * m * k;  // (6, m, m)
    std::fill(Th, Th + 216, 0.0);
    std::fill(Ga, Ga + 36 * m, 0.0);
    std::fill(X, X + 6 * m * m, 0.0);
    for (int i = 0; i < 3; ++i) {
      // dt^2 W1^T Dsym_i W1 (+ dt (Jr T)_i in the Omega block for semi-implicit)
      const double* Di = Dsym + 9 * i;
      for (int p = 0; p < 3; ++p)
        for (int b = 0; b < nz; ++b) DW[nz * p + b] = Di[3 * p] * W1[b] + Di[3 * p + 1] * W1[nz + b] + Di[3 * p + 2] * W1[2 * nz + b];
      for (int a = 3; a < nz; ++a)
        for (int b = 3; b < nz; ++b) {
          double s = dt * dt * (W1[a] * DW[b] + W1[nz + a] * DW[nz + b] + W1[2 * nz + a] * DW[2 * nz + b]);
          if (body.semi_implicit && a < 6 && b < 6) {
            const int ab = 3 * (a - 3) + (b - 3);
            s += dt * (Jr[3 * i] * T[ab] + Jr[3 * i + 1] * T[9 + ab] + Jr[3 * i + 2] * T[18 + ab]);
          }
          if (a < 6 && b < 6) Th[36 * i + 6 * a + b] += s;
          else if (a < 6) Ga[6 * m * i + m * a + (b - 6)] += s;
          else if (b >= 6) X[m * m * i + m * (a - 6) + (b - 6)] += s;
        }
      // 1/2 [A eta, Jr rho]: M[a, b] = 1/2 dt ((A e_a) x (JW e_b))_i, a in eta, b in z
      const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
      for (int a = 0; a < 3; ++a)
        for (int b = 3; b < nz; ++b) {
          const double mab = 0.5 * dt * (A[3 * i1 + a] * JW[nz * i2 + b] - A[3 * i2 + a] * JW[nz * i1 + b]);
          if (b < 6) {
            Th[36 * i + 6 * a + b] += mab;
            Th[36 * i + 6 * b + a] += mab;
          } else {
            Ga[6 * m * i + m * a + (b - 6)] += mab;
          }
        }
    }
    for (int i = 0; i < 3; ++i)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) Th[36 * (3 + i) + 6 * (3 + a) + 3 + b] = T[9 * i + 3 * a + b];
  }
}

void geodesic_attitude_derivatives(int N, const double* E, const double* W, double* l, double* g, double* Hs) {
  double r[3], Jr[9], Dsym[27], M[9], T[9];
  for (int n = 0; n < N; ++n) {
    so3_log(E + 9 * n, r);
    jr_and_derivative(r, Jr, Dsym, true);
    const Eigen::Matrix3d Ji = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(Jr).inverse();
    double Wr[3], gn[3];
    for (int i = 0; i < 3; ++i) Wr[i] = W[3 * i] * r[0] + W[3 * i + 1] * r[1] + W[3 * i + 2] * r[2];
    for (int i = 0; i < 3; ++i) gn[i] = Ji(0, i) * Wr[0] + Ji(1, i) * Wr[1] + Ji(2, i) * Wr[2];
    l[n] += 0.5 * (r[0] * Wr[0] + r[1] * Wr[1] + r[2] * Wr[2]);
    for (int i = 0; i < 3; ++i) g[3 * n + i] += gn[i];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        M[3 * a + b] = W[3 * a + b] - (gn[0] * Dsym[3 * a + b] + gn[1] * Dsym[9 + 3 * a + b] + gn[2] * Dsym[18 + 3 * a + b]);
    for (int a = 0; a < 3; ++a)  // T = M Ji
      for (int b = 0; b < 3; ++b) T[3 * a + b] = M[3 * a] * Ji(0, b) + M[3 * a + 1] * Ji(1, b) + M[3 * a + 2] * Ji(2, b);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) Hs[9 * n + 3 * a + b] += Ji(0, a) * T[b] + Ji(1, a) * T[3 + b] + Ji(2, a) * T[6 + b];
  }
}

}  // namespace tso3
}  // namespace geoddp
