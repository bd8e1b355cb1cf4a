// The Euler steps and their velocity update's derivatives (see euler.hpp). Compiled inside
// dynamics/core_algorithms.cpp.
#include "dynamics/euler.hpp"

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>

#include <algorithm>
#include <stdexcept>

#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/pinocchio_second_order.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

void euler_step(const Setup& s, pinocchio::Data& data, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                const Eigen::VectorXd& tau, Eigen::VectorXd& q1, Eigen::VectorXd& v1) {
  const Model& model = *s.model;
  libpin::aba(model, data, q, v, tau);
  v1 = v + s.dt * data.ddq;
  const Eigen::VectorXd w = s.dt * (s.integrator == SEMI_IMPLICIT ? v1 : v);
  libpin::integrate(model, q, w, q1);
}

static PairIndex active_pairs(int nv, int nz) {
  PairIndex P;
  for (int a = 0; a < nv; ++a)
    for (int b = a; b < nz; ++b) P.a.push_back(a), P.b.push_back(b);
  for (int a = nv; a < 2 * nv; ++a)
    for (int b = a; b < 2 * nv; ++b) P.a.push_back(a), P.b.push_back(b);
  return P;
}

NodeWork::NodeWork(const Model& model, int m)
    : data(model), Minv(model.nv, model.nv), aq(model.nv, model.nv), av(model.nv, model.nv), au(model.nv, m),
      az(model.nv, 2 * model.nv + m), Pj(model.nv, 2 * model.nv + m), q(model.nq), v(model.nv), tau(model.nv),
      a(model.nv) {
  const int nv = model.nv, nz = 2 * nv + m;
  pairs = active_pairs(nv, nz);
  pair_of.assign((size_t)nz * nz, -1);
  for (int c = 0; c < pairs.count(); ++c) {
    pair_of[(size_t)pairs.a[c] * nz + pairs.b[c]] = c;
    pair_of[(size_t)pairs.b[c] * nz + pairs.a[c]] = c;
  }
  Tu.resize(nv, pairs.count());
  F2u.resize(nv, pairs.count());
}

// (the derivation: euler.hpp)
void node_derivatives(const Setup& s, NodeWork& w, double* F1, bool second) {
  const Model& model = *s.model;
  const int nv = model.nv, m = s.m, nz = 2 * nv + m;
  const double dt = s.dt;
  CMatMap Hm(s.H, nv, m);
  pinocchio::Data& data = w.data;
  libpin::computeABADerivatives(model, data, w.q, w.v, w.tau);
  w.Minv = data.Minv;
  w.Minv.triangularView<Eigen::StrictlyLower>() = w.Minv.transpose();
  w.aq = data.ddq_dq;
  w.av = data.ddq_dv;
  w.au.noalias() = w.Minv * Hm;
  w.a = data.ddq;
  MatMap F1m(F1, nv, nz);
  F1m.leftCols(nv) = dt * w.aq;
  F1m.middleCols(nv, nv) = dt * w.av;
  F1m.middleCols(nv, nv).diagonal().array() += 1.0;
  F1m.rightCols(m) = dt * w.au;
  if (!second) return;

  if (w.one_body)
    w.one_body->at(w.q.data(), data.d2tau_dqdq.data(), data.d2tau_dvdv.data(), data.d2tau_dqdv.data(),
                   data.d2tau_dadq.data());
  else
    libpin::rnea_second_order_tensors(model, data, w.q, w.v, w.a);
  const auto& Iqq = data.d2tau_dqdq;
  const auto& Ivv = data.d2tau_dvdv;
  const auto& Iqv = data.d2tau_dqdv;
  w.az.leftCols(nv) = w.aq;
  w.az.middleCols(nv, nv) = w.av;
  w.az.rightCols(m) = w.au;
  // Tu(i, (a, b)) = T_i(a, b) of ID_zz + ID_za a_z + (ID_za a_z)^T on the active pairs.
  w.Tu.setZero();
  double* Tu = w.Tu.data();
  for (int j = 0; j < nv; ++j) {
    // Pj(i, :) = sum_l dM(i, l, j) a_z(l, :): row i, q_j entries of ID_za a_z. dM is a
    // column-major tensor, so its slice at q_j is a column-major (nv, nv) matrix.
    Eigen::Map<const Eigen::MatrixXd> dMj(data.d2tau_dadq.data() + (size_t)nv * nv * j, nv, nv);
    if (nv <= 16)  // small: coefficient-based (Eigen's blocked GEMM packs more than it multiplies)
      w.Pj.noalias() = dMj.lazyProduct(w.az);
    else
      w.Pj.noalias() = dMj * w.az;
    for (int b = 0; b < nz; ++b) {
      // (q_j, z_b) and (z_b, q_j): the same upper pair; the diagonal gets both
      const int c = w.pair_of[(size_t)j * nz + b];
      double* t = Tu + (size_t)nv * c;
      const double* pcol = w.Pj.data() + (size_t)nv * b;
      if (b == j)
        for (int i = 0; i < nv; ++i) t[i] += 2.0 * pcol[i];
      else
        for (int i = 0; i < nv; ++i) t[i] += pcol[i];
    }
  }
  for (int j = 0; j < nv; ++j)
    for (int k = 0; k < nv; ++k) {
      if (k >= j) {
        double* tqq = Tu + (size_t)nv * w.pair_of[(size_t)j * nz + k];
        double* tvv = Tu + (size_t)nv * w.pair_of[(size_t)(nv + j) * nz + nv + k];
        for (int i = 0; i < nv; ++i) {
          tqq[i] += 0.5 * (Iqq(i, j, k) + Iqq(i, k, j));
          tvv[i] += 0.5 * (Ivv(i, j, k) + Ivv(i, k, j));
        }
      }
      double* tqv = Tu + (size_t)nv * w.pair_of[(size_t)j * nz + nv + k];
      for (int i = 0; i < nv; ++i) tqv[i] += Iqv(i, j, k);
    }
  w.F2u.noalias() = (-dt) * (w.Minv * w.Tu);
}

// The dense symmetric (nv, nz, nz) F2 (row-major [p][a*nz + b]) from the packed pairs.
static void unpack_pairs(const NodeWork& w, int rows, const Eigen::MatrixXd& Xu, int nz, double* X) {
  std::fill(X, X + (size_t)rows * nz * nz, 0.0);
  for (int c = 0; c < w.pairs.count(); ++c) {
    const int a = w.pairs.a[c], b = w.pairs.b[c];
    const double* x = Xu.data() + (size_t)rows * c;
    for (int p = 0; p < rows; ++p) {
      X[(size_t)p * nz * nz + (size_t)a * nz + b] = x[p];
      X[(size_t)p * nz * nz + (size_t)b * nz + a] = x[p];
    }
  }
}

std::unique_ptr<OneBodySecondOrder> one_body_for(const Model& model, bool second) {
  return second && OneBodySecondOrder::applies(model) ? std::make_unique<OneBodySecondOrder>(model) : nullptr;
}

bool one_body_applies(const Model& model) { return OneBodySecondOrder::applies(model); }

void rnea_second_order(const Model& model, const double* q, const double* v, const double* a, bool one_body,
                       double* Iqq, double* Ivv, double* Iqv, double* dM) {
  if (one_body) {
    if (!OneBodySecondOrder::applies(model))
      throw std::invalid_argument("model: the one-body shortcut needs one free-flyer or spherical joint");
    OneBodySecondOrder(model).at(q, Iqq, Ivv, Iqv, dM);
    return;
  }
  pinocchio::Data data(model);
  libpin::rnea_second_order_tensors(model, data, CVecMap(q, model.nq), CVecMap(v, model.nv), CVecMap(a, model.nv), Iqq,
                                    Ivv, Iqv, dM);
}

static void node_velocity_derivatives(const Setup& s, NodeWork& w, double* F1, double* F2) {
  node_derivatives(s, w, F1, F2 != nullptr);
  if (F2 != nullptr) unpack_pairs(w, s.model->nv, w.F2u, 2 * s.model->nv + s.m, F2);
}

void velocity_derivatives(const Setup& s, const double* Q, const double* V, const double* U, int N, int order,
                          int threads, double* F1, double* F2) {
  const Model& model = *s.model;
  const int nq = model.nq, nv = model.nv, m = s.m, nz = 2 * nv + m;
  CMatMap Hm(s.H, nv, m);
  const std::unique_ptr<OneBodySecondOrder> one_body = one_body_for(model, order >= 2);
  parallel_for(N, threads, [&](int b, int e, int) {
    NodeWork w(model, m);
    w.one_body = one_body.get();
    for (int k = b; k < e; ++k) {
      w.q = CVecMap(Q + (size_t)k * nq, nq);
      w.v = CVecMap(V + (size_t)k * nv, nv);
      w.tau = Hm * CVecMap(U + (size_t)k * m, m);
      node_velocity_derivatives(s, w, F1 + (size_t)k * nv * nz,
                                order >= 2 ? F2 + (size_t)k * nv * nz * nz : nullptr);
    }
  });
}

}  // namespace dyn
}  // namespace geoddp
