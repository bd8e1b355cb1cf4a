// RKMK4 step and derivatives (see dynamics/rkmk4.hpp; twin of the tests' oracle tests/oracle_rkmk4.py).
#include "dynamics/rkmk4.hpp"

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/spatial.hpp>

#include "lie/joint_blocks.hpp"
#include "lie/right_jacobians.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {

// the block-diagonal reconstruction operators (lie/joint_blocks.hpp)
using lie::block_jacobians;
using lie::djr_apply;

namespace {


// The classical tableau: stage offsets c_i and weights w_i (times h / 6).
const double C_STAGE[4] = {0.0, 0.5, 0.5, 1.0};
const double W_STAGE[4] = {1.0, 2.0, 2.0, 1.0};

}  // namespace

Rk4Work::Rk4Work(const Model& model, int m) : data(model) {
  const int nv = model.nv, n = 2 * nv, nz = n + m;
  for (Eigen::MatrixXd* M : {&A, &Jr, &Jinv, &Minv, &Mdj}) M->resize(nv, nv);
  for (Eigen::MatrixXd* M : {&Th, &Vi, &Qtan, &Kv, &Kth, &Tmp, &ThSum, &ASum}) M->resize(nv, nz);
  Pv = Eigen::MatrixXd::Zero(nv, nz);
  Pv.middleCols(nv, nv).setIdentity();
  G.resize(n, nz);
  Gp.resize(n, nz);
  D.resize((size_t)n * nz, nz);
  for (Eigen::VectorXd* x : {&theta, &vi, &y, &kth, &kv, &thSum, &vd, &taud, &tau}) x->resize(nv);
  qi.resize(model.nq);
  qd.resize(model.nq);
  ud.resize(m);
}

void rk4_step(const Model& model, pinocchio::Data& data, const std::vector<JointGroup>& groups,
              const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& tau, double h,
              Eigen::VectorXd& q1, Eigen::VectorXd& v1) {
  const int nv = model.nv;
  // per-thread scratch, sized on first use for a model (a rollout makes one call per node)
  struct Scratch {
    Eigen::VectorXd thSum, vSum, theta, vi, kth, kv, qi, step;
    Eigen::MatrixXd Jr, Jinv;
  };
  thread_local Scratch w;
  if (w.theta.size() != nv || w.qi.size() != model.nq) {
    for (Eigen::VectorXd* x : {&w.thSum, &w.vSum, &w.theta, &w.vi, &w.kth, &w.kv, &w.step}) x->resize(nv);
    w.qi.resize(model.nq);
    w.Jr.resize(nv, nv);
    w.Jinv.resize(nv, nv);
  }
  w.thSum.setZero();
  w.vSum.setZero();
  for (int i = 0; i < 4; ++i) {
    if (i == 0) {
      w.theta.setZero();
      w.vi = v;
    } else {
      w.theta = (C_STAGE[i] * h) * w.kth;
      w.vi = v + (C_STAGE[i] * h) * w.kv;
    }
    block_jacobians(groups, w.theta, nullptr, w.Jr, w.Jinv);
    w.kth.noalias() = w.Jinv * w.vi;
    libpin::integrate(model, q, w.theta, w.qi);
    w.kv = libpin::aba(model, data, w.qi, w.vi, tau);
    w.thSum += W_STAGE[i] * w.kth;
    w.vSum += W_STAGE[i] * w.kv;
  }
  w.step = (h / 6.0) * w.thSum;
  libpin::integrate(model, q, w.step, q1);
  v1 = v + (h / 6.0) * w.vSum;
}

void rk4_jacobian(const Setup& s, const std::vector<JointGroup>& groups, Rk4Work& w, const Eigen::VectorXd& q,
                  const Eigen::VectorXd& v, const Eigen::VectorXd& tau) {
  const Model& model = *s.model;
  const int nv = model.nv, m = s.m;
  const double h = s.dt;
  CMatMap Hm(s.H, nv, m);
  pinocchio::Data& data = w.data;
  w.thSum.setZero();
  w.ThSum.setZero();
  w.ASum.setZero();
  for (int i = 0; i < 4; ++i) {
    const double ch = C_STAGE[i] * h;
    if (i == 0) {
      w.theta.setZero();
      w.vi = v;
      w.Th.setZero();
      w.Vi = w.Pv;
    } else {  // from the previous stage's slopes (k, K) before they are overwritten
      w.theta = ch * w.kth;
      w.vi = v + ch * w.kv;
      w.Th = ch * w.Kth;
      w.Vi = w.Pv + ch * w.Kv;
    }
    libpin::integrate(model, q, w.theta, w.qi);
    block_jacobians(groups, w.theta, &w.A, w.Jr, w.Jinv);
    // tangent of q_i = q exp(dq) exp(theta_i) at q_i: Ad_exp(-theta_i) dq + Jr dtheta_i
    w.Qtan.noalias() = w.Jr * w.Th;
    w.Qtan.leftCols(nv) += w.A;
    libpin::computeABADerivatives(model, data, w.qi, w.vi, tau);
    w.Minv = data.Minv;
    w.Minv.triangularView<Eigen::StrictlyLower>() = w.Minv.transpose();
    w.Kv.noalias() = data.ddq_dq * w.Qtan;
    w.Kv.noalias() += data.ddq_dv * w.Vi;
    w.Kv.rightCols(m).noalias() += w.Minv * Hm;
    w.kv = data.ddq;
    w.y.noalias() = w.Jinv * w.vi;
    djr_apply(groups, w.theta, w.y, w.Mdj);
    w.kth = w.y;
    w.Tmp = w.Vi;
    w.Tmp.noalias() -= w.Mdj * w.Th;
    w.Kth.noalias() = w.Jinv * w.Tmp;
    w.thSum += W_STAGE[i] * w.kth;
    w.ThSum += W_STAGE[i] * w.Kth;
    w.ASum += W_STAGE[i] * w.Kv;
  }
  w.theta = (h / 6.0) * w.thSum;
  block_jacobians(groups, w.theta, &w.A, w.Jr, w.Jinv);
  w.G.topRows(nv).noalias() = w.Jr * ((h / 6.0) * w.ThSum);
  w.G.topLeftCorner(nv, nv) += w.A;
  w.G.bottomRows(nv) = w.Pv + (h / 6.0) * w.ASum;
}

void rk4_node_expansion(const Setup& s, const std::vector<JointGroup>& groups, Rk4Work& w,
                        const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& u,
                        double* Phi, double* B, double* Theta, double* Gamma, double* Xi) {
  const Model& model = *s.model;
  const int nv = model.nv, m = s.m, n = 2 * nv, nz = n + m;
  CMatMap Hm(s.H, nv, m);
  w.tau.noalias() = Hm * u;
  rk4_jacobian(s, groups, w, q, v, w.tau);
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) Phi[(size_t)a * n + b] = w.G(a, b);
    for (int c = 0; c < m; ++c) B[(size_t)a * m + c] = w.G(a, n + c);
  }
  if (Theta == nullptr) return;
  // D(p * nz + a, j) = d G(p, a) / d z_j by central differences along z_j (q through integrate,
  // u through H (u + h e_j) as the Python path forms it).
  const double hfd = RK4_FD_STEP;
  for (int j = 0; j < nz; ++j) {
    for (int sign = 1; sign >= -1; sign -= 2) {
      const double e = sign * hfd;
      const Eigen::VectorXd* qa = &q;
      const Eigen::VectorXd* va = &v;
      const Eigen::VectorXd* ta = &w.tau;
      if (j < nv) {
        w.vd.setZero();
        w.vd[j] = e;
        libpin::integrate(model, q, w.vd, w.qd);
        qa = &w.qd;
      } else if (j < n) {
        w.vd = v;
        w.vd[j - nv] += e;
        va = &w.vd;
      } else {
        w.ud = u;
        w.ud[j - n] += e;
        w.taud.noalias() = Hm * w.ud;
        ta = &w.taud;
      }
      rk4_jacobian(s, groups, w, *qa, *va, *ta);
      if (sign == 1) {
        w.Gp = w.G;
      } else {
        for (int p = 0; p < n; ++p)
          for (int a = 0; a < nz; ++a) w.D((size_t)p * nz + a, j) = (w.Gp(p, a) - w.G(p, a)) / (2.0 * hfd);
      }
    }
  }
  // the symmetric (0)-Hessian, split into Theta, Gamma, Xi
  for (int p = 0; p < n; ++p)
    for (int a = 0; a < nz; ++a)
      for (int b = 0; b < nz; ++b) {
        const double x = 0.5 * (w.D((size_t)p * nz + a, b) + w.D((size_t)p * nz + b, a));
        if (a < n && b < n) Theta[((size_t)p * n + a) * n + b] = x;
        else if (a < n) Gamma[((size_t)p * n + a) * m + (b - n)] = x;
        else if (b >= n) Xi[((size_t)p * m + (a - n)) * m + (b - n)] = x;
      }
}

}  // namespace dyn
}  // namespace geoddp
