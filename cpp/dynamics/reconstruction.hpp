// The second-order part of the Euler schemes' configuration update q+ = q exp(dt w) (explicit
// Euler: w = v; semi-implicit: w = v+), shared by the multibody expansions (dynamics/expansion.cpp)
// and the contact schedule's (dynamics/contact_second.cpp). With rho = dt delta w, per SO(3)/SE(3)
// joint group (geoddp.models.integrators' module docstring):
//   eta+ = A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [A eta, Jr rho],
// A = Ad_exp(-dt w_bar), Jr = Jr(dt w_bar) (lie/joint_blocks.hpp's block_ad_jr), so that eta+'s
// Hessian in z is dt^2 W1^T Dsym W1 + the bracket's block + dt Jr (delta w)'s Hessian, W1 =
// d(delta w)/dz. Header-only (inline): its two callers compile in different unity files.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "lie/joint_groups.hpp"
#include "lie/right_jacobians.hpp"
#include "linalg/small_gemm.hpp"
#include "runtime/arrays.hpp"
#include "dynamics/second_order_terms.hpp"

namespace geoddp {
namespace dyn {

// out = alpha Jr X for the block-diagonal right Jacobian Jr (nv, nv) of the reconstruction, X and
// out (nv, c), out not aliasing X. Jr is the identity off the SO(3)/SE(3) groups, so only those
// groups' rows are multiplied; the others are copied, scaled.
template <typename XMat, typename OutMat>
inline void jr_times(const std::vector<JointGroup>& groups, const RowMat& Jr, double alpha, const XMat& X,
                     OutMat& out) {
  out = alpha * X;
  for (const JointGroup& g : groups)
    if (g.kind == SO3 || g.kind == SE3)
      out.middleRows(g.idx_v, g.nv).noalias() =
          alpha * Jr.block(g.idx_v, g.idx_v, g.nv, g.nv).lazyProduct(X.middleRows(g.idx_v, g.nv));
}

// sym D[o+p, o+a, o+c] over (a, c) for the group at tangent offset o (Dt (nv, nv, nv) row-major,
// the derivative of Jr from block_ad_jr): 1/2 dJr[rho] rho = rho^T Dsym_p rho.
inline double dsym_entry(const std::vector<double>& Dt, int nv, int o, int p, int a, int c) {
  return 0.5 * (Dt[((size_t)(o + p) * nv + (o + a)) * nv + (o + c)] + Dt[((size_t)(o + p) * nv + (o + c)) * nv + (o + a)]);
}

// 1/2 [A eta, Jr rho]_p = z^T Mz z on the (eta in the group, z) block: Mz = dt/2 As^T C_p JWs
// (As the group's block of A, JWs its rows of JW, row-major; Ds scratch). As^T C_p is a fixed-size
// 3x3 or 6x6 product, and Ds JWs runs on linalg/small_gemm.hpp: Eigen's dynamic lazy product of
// these d x nz blocks spends more on dispatch than on arithmetic.
template <typename ABlock, typename JWBlock>
inline void bracket_block(const lie::GroupStructure& gs, const JointGroup& g, int p, double dt, const ABlock& As,
                          const JWBlock& JWs, RowMat& Ds, RowMat& Mz) {
  const int d = g.nv;
  if (g.kind == SO3) Ds = lie::Mat3(As).transpose() * gs.C3[p];
  else Ds = lie::Mat6(As).transpose() * gs.C6[p];
  const int nz = (int)JWs.cols();
  Mz.resize(d, nz);
  gemm::gemm(false, d, nz, d, 0.5 * dt, Ds.data(), d, JWs.data(), (int)JWs.outerStride(), false, Mz.data(), nz);
}

// Each of `rows` rows of X (rows, nz*nz) is an (nz, nz) matrix: make it exactly symmetric (the
// products forming it round differently in (a, b) and (b, a)).
inline void symmetrise_rows(double* X, int rows, int nz) {
  for (int r = 0; r < rows; ++r) {
    double* x = X + (size_t)r * nz * nz;
    for (int a = 0; a < nz; ++a)
      for (int b = a + 1; b < nz; ++b) {
        const double v = 0.5 * (x[(size_t)a * nz + b] + x[(size_t)b * nz + a]);
        x[(size_t)a * nz + b] = v;
        x[(size_t)b * nz + a] = v;
      }
  }
}

// G2's first nv rows (each an (nz, nz) matrix, row-major), overwritten: the Hessians in z of the
// reconstruction's group terms, dt^2 Ws^T Dsym_p Ws + 1/2 [A eta, Jr rho]_p's block, per SO(3)/SE(3)
// group (zero elsewhere; the dt Jr (delta w)'' part is the caller's). Dt: block_ad_jr's D at
// dt w_bar; A its Ad_exp(-dt w_bar); W1 = d(delta w)/dz (nv, nz); JW = Jr W1. Ds, Mz, WDW: scratch.
inline void reconstruction_group_terms(const std::vector<JointGroup>& groups, const lie::GroupStructure& gs, double dt,
                                       int nv, const std::vector<double>& Dt, const RowMat& A, const RowMat& W1,
                                       const RowMat& JW, RowMat& G2, RowMat& Ds, RowMat& Mz, RowMat& WDW) {
  const int nz = (int)W1.cols();
  // eta+ = A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [A eta, Jr rho], rho = dt delta w
  // (geoddp.integrators' module docstring; per non-commutative joint group).
  G2.setZero();
  for (const JointGroup& g : groups) {
    if (g.kind != SO3 && g.kind != SE3) continue;
    const int o = g.idx_v, d = g.nv;
    const auto Ws = W1.middleRows(o, d);
    const auto JWs = JW.middleRows(o, d);
    const auto As = A.block(o, o, d, d);
    Ds.resize(d, d);
    for (int p = 0; p < d; ++p) {
      // 1/2 dJr[rho] rho: dt^2 Ws^T Dsym_p Ws, Dsym_p(a, b) = sym D[p, a, b]
      for (int a = 0; a < d; ++a)
        for (int c = 0; c < d; ++c) Ds(a, c) = dsym_entry(Dt, nv, o, p, a, c);
      Eigen::Map<RowMat> G2p(G2.row(o + p).data(), nz, nz);
      // coefficient-based products: these are (nz, d) x (d, d) x (d, nz) with d <= 6, where
      // Eigen's blocked GEMM spends more on packing than on arithmetic
      Mz.noalias() = Ds.lazyProduct(Ws);
      WDW.noalias() = Ws.transpose().lazyProduct(Mz);
      G2p += (dt * dt) * WDW;
      // 1/2 [A eta, Jr rho]_p = z^T Mz_p z, Mz_p = dt/2 A^T C_p JW on the (eta in s, z) block
      bracket_block(gs, g, p, dt, As, JWs, Ds, Mz);
      G2p.middleRows(o, d) += Mz;
      G2p.middleCols(o, d) += Mz.transpose();
    }
  }
}

// G2 (n, nz * nz): row i the symmetric (nz, nz) Hessian of x+_i in z = (x, u), row-major, split
// into one node's Theta (n, n, n), Gamma (n, n, nu) and Xi (n, nu, nu) (the expansions' layout):
// Theta[i][a][c] = G2_i(a, c), Gamma[i][a][c] = G2_i(a, n + c), Xi[i][a][c] = G2_i(n + a, n + c).
inline void split_second_order(const RowMat& G2, int n, int nu, double* Theta, double* Gamma, double* Xi) {
  const size_t nz = (size_t)n + nu;
  for (int i = 0; i < n; ++i) {
    const double* g2 = G2.row(i).data();
    for (int a = 0; a < n; ++a) {
      for (int c = 0; c < n; ++c) Theta[((size_t)i * n + a) * n + c] = g2[(size_t)a * nz + c];
      for (int c = 0; c < nu; ++c) Gamma[((size_t)i * n + a) * nu + c] = g2[(size_t)a * nz + n + c];
    }
    for (int a = 0; a < nu; ++a)
      for (int c = 0; c < nu; ++c) Xi[((size_t)i * nu + a) * nu + c] = g2[(size_t)(n + a) * nz + n + c];
  }
}

// Node k's reconstruction group blocks (Jr, As, JWs, Dsym) into t, from block_ad_jr's A, Jr, D
// and JW = Jr W1 (the multibody expansion's first_order_blocks, the contact schedule's
// contact_linearise_contracted).
inline void store_group_blocks(const std::vector<JointGroup>& groups, SecondOrderTerms& t, int k, const RowMat& Jr,
                               const RowMat& A, const RowMat& JW, const std::vector<double>& Dt, int nv, int nz) {
  double* jr = t.Jr.data() + (size_t)k * t.gJ;
  double* as = t.As.data() + (size_t)k * t.gJ;
  double* dsym = t.Dsym.data() + (size_t)k * t.gD;
  double* jw = t.JWs.data() + (size_t)k * t.gW;
  for (const JointGroup& g : groups) {
    if (g.kind != SO3 && g.kind != SE3) continue;
    const int o = g.idx_v, d = g.nv;
    MatMap(jr, d, d) = Jr.block(o, o, d, d);
    MatMap(as, d, d) = A.block(o, o, d, d);
    MatMap(jw, d, nz) = JW.middleRows(o, d);
    jr += d * d;
    as += d * d;
    jw += d * nz;
    for (int p = 0; p < d; ++p)
      for (int a = 0; a < d; ++a)
        for (int c = 0; c < d; ++c) dsym[(size_t)(p * d + a) * d + c] = dsym_entry(Dt, nv, o, p, a, c);
    dsym += d * d * d;
  }
}

}  // namespace dyn
}  // namespace geoddp
