// The expansions of a multibody step over a trajectory (see trajectory.hpp): expansion (Phi, B
// and the dense Theta, Gamma, Xi) and expansion_contracted (Phi, B and the factored second order,
// second_order_terms.hpp), node-parallel on the pool (runtime/parallel.hpp).
//
// The Euler schemes and the variational step share the configuration update q+ = q exp(dt w_bar)
// (the variational step's is explicit Euler's), so their expansions are assembled here from the
// integrator's velocity-update derivatives (euler.hpp's node_derivatives, dynamics/variational.hpp's
// variational_node) and this reconstruction: with rho = dt delta w,
//   eta+ = A eta + Jr rho + 1/2 dJr[rho] rho + 1/2 [A eta, Jr rho]   (per SO(3)/SE(3) joint group),
// A = Ad_exp(-dt w_bar), Jr = Jr(dt w_bar) (geoddp.integrators' module docstring). RK4 has its own
// node expansion (dynamics/rkmk4.hpp). Compiled inside dynamics/core_algorithms.cpp.
#include <pinocchio/multibody.hpp>

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <vector>

#include "dynamics/euler.hpp"
#include "dynamics/reconstruction.hpp"
#include "dynamics/rkmk4.hpp"
#include "dynamics/trajectory.hpp"
#include "dynamics/variational.hpp"
#include "lie/joint_blocks.hpp"
#include "lie/right_jacobians.hpp"
#include "linalg/small_gemm.hpp"
#include "rigid_body/pinocchio_second_order.hpp"
#include "rigid_body/rnea_hessian.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

using lie::block_ad_jr;
using lie::GroupStructure;  // the reconstruction's structure constants C3[p], C6[p]

// The first-order blocks of node k (eta+ = A eta + Jr rho, rho = dt delta w; v+'s rows F1
// (nv, nz)): W1 = d(delta w)/dz (F1 semi-implicit, the dv selector explicit), JW = Jr W1, and
// Phi_k (n, n), B_k (n, m) from G1 = [A 0 + dt JW; F1] (G1 (n, nz) scratch).
static void first_order_blocks(const std::vector<JointGroup>& groups, bool semi, double dt, const RowMat& F1,
                               const RowMat& A, const RowMat& Jr, RowMat& W1, RowMat& JW, RowMat& G1, double* Phi_k,
                               double* B_k) {
  const int nv = (int)F1.rows(), n = 2 * nv, m = (int)F1.cols() - n;
  if (semi) {
    W1 = F1;
  } else {
    W1.setZero();
    W1.middleCols(nv, nv).setIdentity();
  }
  jr_times(groups, Jr, 1.0, W1, JW);
  G1.topRows(nv) = dt * JW;
  G1.topLeftCorner(nv, nv) += A;
  G1.bottomRows(nv) = F1;
  MatMap(Phi_k, n, n) = G1.leftCols(n);
  MatMap(B_k, n, m) = G1.rightCols(m);
}

void expansion(const Setup& s, const double* Q, const double* V, const double* U, int N, int order, int threads,
               double* Phi, double* B, double* Theta, double* Gamma, double* Xi) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, n = 2 * nv, nz = n + m;
  const double dt = s.dt;
  const bool semi = s.integrator == SEMI_IMPLICIT;
  const std::vector<JointGroup> groups = joint_groups(model);
  if (s.integrator == RK4) {
    parallel_for(N, threads, [&](int b, int e, int) {
      Rk4Work w(model, m);
      Eigen::VectorXd q(nq), v(nv), u(m);
      for (int k = b; k < e; ++k) {
        q = CVecMap(Q + (size_t)k * nq, nq);
        v = CVecMap(V + (size_t)k * nv, nv);
        u = CVecMap(U + (size_t)k * m, m);
        const bool second = order >= 2;
        rk4_node_expansion(s, groups, w, q, v, u, Phi + (size_t)k * n * n, B + (size_t)k * n * m,
                           second ? Theta + (size_t)k * n * n * n : nullptr,
                           second ? Gamma + (size_t)k * n * n * m : nullptr, second ? Xi + (size_t)k * n * m * m : nullptr);
      }
    });
    return;
  }
  const GroupStructure gs;
  CMatMap Hm(s.H, nv, m);
  // the variational step: its own velocity derivatives (dense F2), the explicit-Euler reconstruction
  const std::unique_ptr<VariationalModel> vmod =
      s.integrator == VARIATIONAL ? std::make_unique<VariationalModel>(model, s.H, m, dt) : nullptr;
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, order >= 2 && !vmod);
  parallel_for(N, threads, [&](int b0, int e0, int) {
    // each worker builds the scratch of its integrator only (a Pinocchio Data and pair tables, or
    // the variational step's)
    const std::unique_ptr<NodeWork> ew = vmod ? nullptr : std::make_unique<NodeWork>(model, m);
    if (ew) ew->one_body = one_body.get();
    const std::unique_ptr<VariationalNodeWork> vw = vmod ? std::make_unique<VariationalNodeWork>(*vmod) : nullptr;
    Eigen::VectorXd q(nq), v(nv);
    RowMat F2d(vw && order >= 2 ? nv : 0, (Eigen::Index)nz * nz);
    Eigen::VectorXd ynext(vw ? nv : 0);
    RowMat F1(nv, nz), W1(nv, nz), JW(nv, nz), G1(n, nz);
    RowMat A(nv, nv), Jr(nv, nv), G2(order >= 2 ? n : 0, (Eigen::Index)nz * nz);
    RowMat Ds, Mz, WDW;  // per-group scratch (reused: no allocation per node)
    Eigen::MatrixXd JF2u;    // dt Jr F2 on the active pairs (semi-implicit top rows)
    std::vector<double> Dt(order >= 2 ? (size_t)nv * nv * nv : 0);
    Eigen::VectorXd omega(nv);
    for (int k = b0; k < e0; ++k) {
      q = CVecMap(Q + (size_t)k * nq, nq);
      v = CVecMap(V + (size_t)k * nv, nv);
      if (vw) {
        ynext = CVecMap(V + (size_t)(k + 1) * nv, nv);
        variational_node(*vmod, *vw, q, v, ynext, F1.data(), order >= 2 ? F2d.data() : nullptr);
      } else {
        ew->q = q;
        ew->v = v;
        ew->tau = Hm * CVecMap(U + (size_t)k * m, m);
        node_derivatives(s, *ew, F1.data(), order >= 2);
      }
      // reconstruction velocity w_bar: v_k (euler) or v_{k+1} (semi-implicit)
      omega = dt * CVecMap(V + (size_t)(semi ? k + 1 : k) * nv, nv);
      block_ad_jr(groups, nv, omega.data(), A.data(), Jr.data(), order >= 2 ? Dt.data() : nullptr);
      first_order_blocks(groups, semi, dt, F1, A, Jr, W1, JW, G1, Phi + (size_t)k * n * n, B + (size_t)k * n * m);
      if (order < 2) continue;
      reconstruction_group_terms(groups, gs, dt, nv, Dt, A, W1, JW, G2, Ds, Mz, WDW);
      // velocity update: F2 (symmetric, zero off the active pairs) in the bottom rows and, for
      // the semi-implicit reconstruction, dt Jr F2 in the top rows (Jr is the identity outside
      // the SO(3)/SE(3) blocks, so only those blocks multiply)
      if (vw) {  // the variational step's dense F2; its reconstruction is explicit Euler's
        for (int p = 0; p < nv; ++p) G2.row(nv + p) = F2d.row(p);
      }
      const int np = vw ? 0 : ew->pairs.count();
      if (semi) jr_times(groups, Jr, dt, ew->F2u, JF2u);
      for (int c = 0; c < np; ++c) {
        const size_t ab = (size_t)ew->pairs.a[c] * nz + ew->pairs.b[c], ba = (size_t)ew->pairs.b[c] * nz + ew->pairs.a[c];
        const double* f = ew->F2u.data() + (size_t)nv * c;
        for (int p = 0; p < nv; ++p) {
          double* row = G2.row(nv + p).data();
          row[ab] = f[p];
          row[ba] = f[p];
        }
        if (semi) {
          const double* jf = JF2u.data() + (size_t)nv * c;
          for (int p = 0; p < nv; ++p) {
            double* row = G2.row(p).data();
            row[ab] += jf[p];
            if (ba != ab) row[ba] += jf[p];
          }
        }
      }
      symmetrise_rows(G2.data(), nv, nz);  // the reconstruction's rows (the velocity rows are exactly symmetric)
      split_second_order(G2, n, m, Theta + (size_t)k * n * n * n, Gamma + (size_t)k * n * n * m,
                         Xi + (size_t)k * n * m * m);
    }
  });
}

// Per node: the first-order part exactly as expansion() computes it (same expressions, so Phi and
// B are bitwise those of order 1), then RNEA's second-order tensors and the reconstruction's group
// blocks copied into `t` instead of being assembled into Theta, Gamma, Xi.
void expansion_contracted(const Setup& s, const double* Q, const double* V, const double* U, int N, int threads,
                          double* Phi, double* B, SecondOrderTerms& t) {
  if (s.integrator == RK4)
    throw std::invalid_argument("integrator: the factored second order is for euler, semi_implicit and variational");
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, n = 2 * nv, nz = n + m;
  const double dt = s.dt;
  const bool semi = s.integrator == SEMI_IMPLICIT;
  // the variational step: its residual Hessians and R_y^-T (variational_node_factored); its
  // reconstruction is explicit Euler's, so the group blocks below are those of euler
  const std::unique_ptr<VariationalModel> vmod =
      s.integrator == VARIATIONAL ? std::make_unique<VariationalModel>(model, s.H, m, dt) : nullptr;
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, !vmod);
  t.resize(model, m, N, dt, semi, vmod != nullptr, !vmod && !one_body && rnea_hessian_recursion(), one_body != nullptr,
           one_body && one_body->with_gravity());
  if (t.one_body) std::copy(one_body->d2tau_dvdv().begin(), one_body->d2tau_dvdv().end(), t.Ivv.data());
  t.variational_separable = vmod && vmod->configuration_free;
  const std::vector<JointGroup> groups = joint_groups(model);
  CMatMap Hm(s.H, nv, m);
  const size_t n3 = (size_t)nv * nv * nv, nts = (size_t)variational_upper_size(nv) * nv;
  parallel_for(N, threads, [&](int b0, int e0, int) {
    const std::unique_ptr<NodeWork> ew = vmod ? nullptr : std::make_unique<NodeWork>(model, m);
    const std::unique_ptr<VariationalNodeWork> vw = vmod ? std::make_unique<VariationalNodeWork>(*vmod) : nullptr;
    const std::unique_ptr<RneaHessianWork> rw = t.recursion ? std::make_unique<RneaHessianWork>(model) : nullptr;
    RowMat F1(nv, nz), W1(nv, nz), JW(nv, nz), G1(n, nz);
    RowMat A(nv, nv), Jr(nv, nv);
    std::vector<double> Dt((size_t)nv * nv * nv);
    Eigen::VectorXd omega(nv), q(nq), v(nv), ynext(nv);
    for (int k = b0; k < e0; ++k) {
      if (vw) {
        q = CVecMap(Q + (size_t)k * nq, nq);
        v = CVecMap(V + (size_t)k * nv, nv);
        ynext = CVecMap(V + (size_t)(k + 1) * nv, nv);
        variational_node_factored(*vmod, *vw, q, v, ynext, F1.data(), t.Minv.data() + (size_t)k * nv * nv,
                                  t.Ts.data() + k * nts);
      } else {
        ew->q = CVecMap(Q + (size_t)k * nq, nq);
        ew->v = CVecMap(V + (size_t)k * nv, nv);
        ew->tau = Hm * CVecMap(U + (size_t)k * m, m);
        node_derivatives(s, *ew, F1.data(), false);
      }
      omega = dt * CVecMap(V + (size_t)(semi ? k + 1 : k) * nv, nv);
      block_ad_jr(groups, nv, omega.data(), A.data(), Jr.data(), Dt.data());
      first_order_blocks(groups, semi, dt, F1, A, Jr, W1, JW, G1, Phi + (size_t)k * n * n, B + (size_t)k * n * m);
      if (ew) {
        NodeWork& w = *ew;
        // the velocity update's second order: RNEA's tensors at (q, v, a), as node_derivatives uses
        // them (the one-body shortcut writes them in place); the variational step's are written above
        if (one_body) {  // d2tau_dqdq only (the rest is zero or constant, stored once above)
          if (t.one_body_gravity) one_body->dqdq_at(w.q.data(), t.Iqq.data() + k * n3);
        } else if (t.recursion) {  // contracted in the pass (rigid_body/rnea_hessian.hpp): its mu-free terms
          rnea_hessian_node(model, *rw, w.q.data(), w.v.data(), w.a.data(),
                            t.rnea.data() + (size_t)k * rnea_hessian_node_size(model));
        } else {
          libpin::rnea_second_order_tensors(model, w.data, w.q, w.v, w.a, t.Iqq.data() + k * n3, t.Ivv.data() + k * n3,
                                            t.Iqv.data() + k * n3, t.dM.data() + k * n3);
        }
        MatMap(t.Minv.data() + (size_t)k * nv * nv, nv, nv) = w.Minv;
        if (!t.one_body) {
          MatMap azk(t.az.data() + (size_t)k * nv * nz, nv, nz);
          azk.leftCols(nv) = w.aq;
          azk.middleCols(nv, nv) = w.av;
          azk.rightCols(m) = w.au;
        }
      }
      MatMap(t.F1.data() + (size_t)k * nv * nz, nv, nz) = F1;
      store_group_blocks(groups, t, k, Jr, A, JW, Dt, nv, nz);
    }
  });
}

}  // namespace dyn
}  // namespace geoddp
