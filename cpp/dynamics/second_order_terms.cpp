// The factored second-order terms' storage and the pass's RNEA contraction per node (see
// second_order_terms.hpp). Compiled inside dynamics/core_algorithms.cpp.
#include "dynamics/second_order_terms.hpp"

#include <algorithm>
#include <atomic>
#include <memory>
#include <vector>

#include "linalg/small_gemm.hpp"
#include "rigid_body/rnea_hessian.hpp"

namespace geoddp {
namespace dyn {

namespace {
std::atomic<bool> RECURSION{true};
std::atomic<unsigned long long> TERMS_ID{0};
}  // namespace

void set_rnea_hessian_recursion(bool on) { RECURSION = on; }
bool rnea_hessian_recursion() { return RECURSION; }

// What every kind of terms shares: the sizes, the SO(3)/SE(3) groups and the reconstruction's blocks
// (F1, Jr, Dsym, As, JWs), a new id; the contact schedule's buffers emptied (resize_contact sets them).
void SecondOrderTerms::resize_layout(const Model& model_, int m_, int N_, double dt_, bool semi_) {
  model = &model_;
  id = ++TERMS_ID;
  N = N_;
  nv = model_.nv;
  m = m_;
  dt = dt_;
  semi = semi_;
  contact = false;
  ny_max = nf_max = 0;
  ny.clear();
  impulse.clear();
  foot_joint.clear();
  foot_chain.clear();
  chains.clear();
  chain_max = 0;
  for (Buffer* x : {&Kt, &Ess, &Pqa, &Yz, &force}) x->resize(0);
  groups.clear();
  for (const JointGroup& g : joint_groups(model_))
    if (g.kind == SO3 || g.kind == SE3) groups.push_back(g);
  const int nz = 2 * nv + m;
  gJ = gD = gW = 0;
  for (const JointGroup& g : groups) {
    gJ += g.nv * g.nv;
    gD += g.nv * g.nv * g.nv;
    gW += g.nv * nz;
  }
  F1.resize((size_t)N * nv * nz);
  Jr.resize((size_t)N * gJ);
  Dsym.resize((size_t)N * gD);
  As.resize((size_t)N * gJ);
  JWs.resize((size_t)N * gW);
}

void SecondOrderTerms::resize(const Model& model, int m_, int N_, double dt_, bool semi_, bool variational_,
                              bool recursion_, bool one_body_, bool one_body_gravity_) {
  resize_layout(model, m_, N_, dt_, semi_);
  variational = variational_;
  recursion = recursion_ && !variational_;
  one_body = one_body_ && !variational_ && !recursion;
  one_body_gravity = one_body && one_body_gravity_;
  const int nz = 2 * nv + m;
  const size_t n3 = variational || recursion ? 0 : (size_t)N * nv * nv * nv;
  rnea.resize(recursion ? (size_t)N * rnea_hessian_node_size(model) : 0);
  if (one_body) {
    Iqq.resize(one_body_gravity ? n3 : 0);
    Ivv.resize((size_t)nv * nv * nv);
    Iqv.resize(0);
    dM.resize(0);
  } else {
    for (auto* x : {&Iqq, &Ivv, &Iqv, &dM}) x->resize(n3);
  }
  Minv.resize((size_t)N * nv * nv);
  az.resize(variational || one_body ? 0 : (size_t)N * nv * nz);  // one body: read only with dM = 0
  Ts.resize(variational ? (size_t)N * variational_upper_size(nv) * nv : 0);
}

void SecondOrderTerms::resize_contact(const Model& model, int m_, int N_, double dt_, int nf_max_,
                                      std::vector<std::vector<int>> chains_) {
  resize_layout(model, m_, N_, dt_, true);  // a contact node's step is semi-implicit Euler
  variational = recursion = one_body = one_body_gravity = false;
  for (Buffer* x : {&Iqq, &Ivv, &Iqv, &dM, &Minv, &az, &Ts}) x->resize(0);  // the RNEA rows: by the recursion
  contact = true;
  nf_max = nf_max_;
  ny_max = nv + 3 * nf_max;
  ny.assign((size_t)N, 0);
  impulse.assign((size_t)N, 0);
  chains = std::move(chains_);
  chain_max = 0;
  for (const std::vector<int>& c : chains) chain_max = std::max(chain_max, (int)c.size());
  const size_t node = rnea_hessian_node_size(model), slots = (size_t)N * nf_max;
  rnea.resize((size_t)N * node);
  force.resize(slots * 6);
  foot_joint.assign(slots, 0);
  foot_chain.assign(slots, 0);
  Kt.resize((size_t)N * nv * ny_max);
  Ess.resize(slots * 3 * chain_upper());
  Pqa.resize(slots * 3 * chain_max * chain_max);
  Yz.resize((size_t)N * ny_max * nz());
}

// What a Data and RneaHessianWork depend on: the tree's shape and its joints' kinds.
static std::vector<int> model_structure(const Model& model) {
  std::vector<int> x{model.njoints, model.nq, model.nv};
  for (int j = 0; j < model.njoints; ++j) {
    x.push_back((int)model.parents[j]);
    x.push_back(model.nvs[j]);
    x.push_back(model.nqs[j]);
    x.push_back(model.joints[j].toVariant().which());
  }
  return x;
}

// The pass's work for t's model: one (and its Data) per thread, as the pass may contract on the pool's
// second worker and two passes may run side by side (riccati/ladder.hpp's speculation). Every
// linearisation makes new terms (a new id); a work is rebuilt only if their model is another (a Data
// costs more than a node).
static RneaHessianWork& pass_work(const SecondOrderTerms& t) {
  struct Cache {
    std::unique_ptr<RneaHessianWork> work;
    const Model* model = nullptr;
    std::vector<int> structure;
    unsigned long long served = 0;
  };
  thread_local Cache c;
  const Model& model = *t.model;
  if (c.served != t.id) {
    std::vector<int> structure = model_structure(model);
    if (!c.work || c.model != &model || c.structure != structure) {
      c.work = std::make_unique<RneaHessianWork>(model);
      c.model = &model;
      c.structure = std::move(structure);
    }
    c.served = t.id;
  }
  return *c.work;
}

void point_forces_at_node(const SecondOrderTerms& t, int k, int nf, const double* mu, double* Hqq) {
  const RneaHessianWork& w = pass_work(t);
  const double* node = t.rnea.data() + (size_t)k * rnea_hessian_node_size(*t.model);
  for (int i = 0; i < nf; ++i) {
    const size_t f = (size_t)k * t.nf_max + i;
    rnea_hessian_point_force(*t.model, w, node, t.foot_joint[f], t.force.data() + 6 * f, t.force.data() + 6 * f + 3,
                             mu, Hqq);
  }
}

void rnea_hessian_at_node(const SecondOrderTerms& t, int k, const double* mu, double* r4) {
  const size_t nn = (size_t)t.model->nv * t.model->nv;
  rnea_hessian_contract(*t.model, pass_work(t), t.rnea.data() + (size_t)k * rnea_hessian_node_size(*t.model), mu, r4,
                        r4 + nn, r4 + 2 * nn, r4 + 3 * nn);
}

void contact_kkt_upper(const SecondOrderTerms& t, int k, const double* mu_, double* S_) {
  const int nv = t.nv, nz = t.nz(), ns = 2 * nv, ny = t.ny[(size_t)k], nyx = t.ny_max, nc = ny - nv, nf = nc / 3;
  const size_t nn = (size_t)nv * nv;
  const bool impulse = t.impulse[(size_t)k] != 0;
  const double* mu = mu_;
  thread_local std::vector<double> Bq, P, r4, Fqq, x;
  thread_local Eigen::MatrixXd D;
  // the feet's rows on their chains, summed in each chain's (q, v) coordinates, then scattered into
  // D (ns, ns; upper triangle: the chains' dofs are increasing)
  const size_t cu = t.chain_upper(), cm = (size_t)t.chain_max * t.chain_max;
  D.setZero(ns, ns);
  for (int f = 0; f < nf; ++f) {
    const size_t slot = (size_t)k * t.nf_max + f;
    const std::vector<int>& vi = t.chains[(size_t)t.foot_chain[slot]];
    const int n = (int)vi.size(), cn = 2 * n;
    const double* ess = t.Ess.data() + slot * 3 * cu;
    x.assign((size_t)cn * (cn + 1) / 2, 0.0);
    for (int c = 0; c < 3; ++c) {
      const double m = mu[nv + 3 * f + c];
      const double* row = ess + (size_t)c * cu;
      for (size_t e = 0; e < x.size(); ++e) x[e] += m * row[e];
    }
    const double* xe = x.data();
    for (int a = 0; a < cn; ++a) {
      const int fa = a < n ? vi[(size_t)a] : nv + vi[(size_t)(a - n)];
      for (int b = a; b < cn; ++b) D(fa, b < n ? vi[(size_t)b] : nv + vi[(size_t)(b - n)]) += *xe++;
    }
  }
  // the RNEA rows: the robot's recursion, and each foot's force curvature
  r4.resize(4 * nn);
  rnea_hessian_at_node(t, k, mu, r4.data());
  const double *Hqq = r4.data(), *Hvv = Hqq + nn, *Hqv = Hvv + nn, *Dm = Hqv + nn;
  Fqq.assign(nn, 0.0);
  point_forces_at_node(t, k, nf, mu, Fqq.data());
  // sum_r mu_r E_ss,r (a <= b): the feet's D plus the RNEA rows'
  auto ess = [&](int a, int b) {
    double x = D(a, b);
    if (b < nv) {
      x += 0.5 * (Hqq[a + nv * b] + Hqq[b + nv * a]) - 0.5 * (Fqq[a + nv * b] + Fqq[b + nv * a]);
    } else if (a < nv) {
      const int l = b - nv;
      x += impulse ? -Dm[l + nv * a] : Hqv[a + nv * l];
    } else if (!impulse) {
      const int j = a - nv, l = b - nv;
      x += 0.5 * (Hvv[j + nv * l] + Hvv[l + nv * j]);
    }
    return x;
  };
  // Bq (nv, ny), row-major
  Bq.assign((size_t)nv * ny, 0.0);
  for (int j = 0; j < nv; ++j) {
    double* Bj = Bq.data() + (size_t)j * ny;
    for (int l = 0; l < nv; ++l) Bj[l] = Dm[l + nv * j];
  }
  for (int f = 0; f < nf; ++f) {
    const size_t slot = (size_t)k * t.nf_max + f;
    const std::vector<int>& vi = t.chains[(size_t)t.foot_chain[slot]];
    const int n = (int)vi.size();
    const double* pqa = t.Pqa.data() + slot * 3 * cm;
    for (int c = 0; c < 3; ++c) {
      const int r = 3 * f + c;
      const double m = mu[nv + r];
      for (int j = 0; j < n; ++j) {
        const double* xr = pqa + (size_t)c * cm + (size_t)j * n;
        double* Bj = Bq.data() + (size_t)vi[(size_t)j] * ny;
        double s = 0.0;
        for (int l = 0; l < n; ++l) {
          Bj[vi[(size_t)l]] += m * xr[l];
          s += xr[l] * mu[vi[(size_t)l]];
        }
        Bj[nv + r] = -s;
      }
    }
  }
  P.resize((size_t)nv * nz);
  gemm::gemm(false, nv, nz, ny, 1.0, Bq.data(), ny, t.Yz.data() + (size_t)k * nyx * nz, nz, false, P.data(), nz);
  // the (s, s) block: sum_r mu_r E_ss,r (symmetric) plus P~ + P~^T; the (s, u) block P~; the (u, u)
  // block of y'' is zero
  for (int a = 0; a < ns; ++a) {
    double* Sa = S_ + (size_t)a * nz;
    const double* Pa = a < nv ? P.data() + (size_t)a * nz : nullptr;
    for (int b = a; b < ns; ++b) {
      double x = ess(a, b);
      if (Pa) x += Pa[b];
      if (b < nv) x += P[(size_t)b * nz + a];
      Sa[b] += x;
    }
    if (Pa)
      for (int b = ns; b < nz; ++b) Sa[b] += Pa[b];
  }
}

}  // namespace dyn
}  // namespace geoddp
