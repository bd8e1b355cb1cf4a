// The exact second order of a contact schedule (see contact.hpp): the twin of
// geoddp.models.contact.ContactDynamics.contact_second / impulse_second (point feet), of
// geoddp.problem.legged.ContactProblem._cost_hessian and of its linearise(order=2), term for term.
// Compiled inside dynamics/contact_algorithms.cpp.
//
// A node's KKT system E(s, y) = 0 (s = (q, v), y = (a, lambda) at a contact node, (v+, Lambda) at
// an impulse node) is differentiated twice: E_y y'' = -E_ww[X, X], X = dw/dz (E is affine in y).
// E_ww's blocks are second-order RNEA derivatives of three kinds of model: the robot (its RNEA
// rows), the robot without gravity (the impulse's M(q) w), and per foot a massless copy carrying a
// unit point mass at the foot's origin (its RNEA is J_w^T p'': the foot's acceleration rows, and
// J_w^T lambda's q-q curvature under the gravity -lambda). The dense expansion (node_kkt) forms
// them from Pinocchio's tensors; the factored one (node_factored) keeps the robot's as the
// contracted recursion's terms and each foot's force curvature as its point and force
// (rigid_body/rnea_hessian.hpp), and works out the feet's rows on each foot's chain (FootChain).
// The semi-implicit Euler step then carries a'' into Theta, Gamma, Xi (dynamics/reconstruction.hpp),
// and each node's cost gets its residuals' curvature (the SE(3) state difference's, the CoM's, the
// swing feet's and the friction cone's through the forces' second derivatives).
#include <pinocchio/algorithm/center-of-mass.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include <Eigen/LU>
#include <algorithm>
#include <stdexcept>
#include <map>
#include <memory>

#include "dynamics/contact.hpp"
#include "dynamics/euler.hpp"
#include "dynamics/reconstruction.hpp"
#include "lie/joint_blocks.hpp"
#include "linalg/small_gemm.hpp"
#include "rigid_body/pinocchio_compiled.hpp"
#include "rigid_body/pinocchio_second_order.hpp"
#include "rigid_body/rnea_hessian.hpp"
#include "runtime/parallel.hpp"

namespace geoddp {
namespace dyn {

namespace contact_second_detail {

// One model's second-order RNEA tensors (Pinocchio's column-major (i, j, k) at i + nv (j + nv k)).
struct Rnea2 {
  int nv = 0;
  std::vector<double> qq, vv, qv, aq;  // sized at the first call (only the dense expansions call it)
  explicit Rnea2(int n) : nv(n) {}
  void at(const pinocchio::Model& m, pinocchio::Data& d, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
          const Eigen::VectorXd& a) {
    for (auto* x : {&qq, &vv, &qv, &aq}) x->resize((size_t)nv * nv * nv);
    libpin::rnea_second_order_tensors(m, d, q, v, a, qq.data(), vv.data(), qv.data(), aq.data());
  }
  static double get(const std::vector<double>& T, int nv, int i, int j, int k) {
    return T[(size_t)i + (size_t)nv * ((size_t)j + (size_t)nv * k)];
  }
};

}  // namespace contact_second_detail

namespace {

// A massless copy of the robot with a unit point mass at frame f's origin, no gravity.
pinocchio::Model point_mass_model(const pinocchio::Model& model, int f) {
  pinocchio::Model mf = model;
  for (size_t j = 0; j < mf.inertias.size(); ++j) mf.inertias[j] = pinocchio::Inertia::Zero();
  const pinocchio::Frame& fr = mf.frames[(size_t)f];
  mf.inertias[fr.parentJoint] = pinocchio::Inertia(1.0, fr.placement.translation(), Eigen::Matrix3d::Zero());
  mf.gravity.setZero();
  return mf;
}

// The dofs that move frame f (its parent joint's supports'), increasing.
std::vector<int> chain_dofs(const pinocchio::Model& model, int f) {
  std::vector<int> vi;
  for (const pinocchio::JointIndex j : model.supports[model.frames[(size_t)f].parentJoint])
    for (int d = 0; d < model.nvs[j]; ++d) vi.push_back(model.idx_vs[j] + d);
  return vi;
}

// The chain of joints that carries frame f (the root's free flyer and the joints down to the frame's
// parent), as a model of its own with a unit point mass at the frame's origin and no gravity: the
// point-mass model's terms restricted to the dofs that move the point (every other dof carries no
// mass), nv_chain (9 on a quadruped's leg) instead of nv. qi, vi (chain_dofs) map its q and v
// entries to the robot's.
struct FootChain {
  pinocchio::Model model;
  std::vector<int> qi, vi;
  FootChain(const pinocchio::Model& full, int f) : vi(chain_dofs(full, f)) {
    const pinocchio::Frame& fr = full.frames[(size_t)f];
    pinocchio::JointIndex parent = 0;
    for (const pinocchio::JointIndex j : full.supports[fr.parentJoint]) {
      if (j == 0) continue;
      parent = model.addJoint(parent, full.joints[j], full.jointPlacements[j], full.names[j]);
      for (int d = 0; d < full.nqs[j]; ++d) qi.push_back(full.idx_qs[j] + d);
    }
    for (auto& I : model.inertias) I = pinocchio::Inertia::Zero();
    model.inertias[parent] = pinocchio::Inertia(1.0, fr.placement.translation(), Eigen::Matrix3d::Zero());
    model.gravity.setZero();
  }
};

// Crocoddyl's quadratic barrier's excess (0 inside [lb, ub]).
double excess(double r, double lb, double ub) { return std::min(r - lb, 0.0) + std::max(r - ub, 0.0); }

Eigen::Vector3d cross_e(int i, const Eigen::Vector3d& x) { return Eigen::Vector3d::Unit(i).cross(x); }

}  // namespace
using contact_second_detail::Rnea2;  // named, not anonymous: ContactSecondWork (declared in contact.hpp) holds it

// A worker's models and scratch for the second order (its own copies: the force and curvature
// terms set a model's gravity).
struct ContactSecondWork {
  const pinocchio::Model* robot;
  std::vector<JointGroup> groups;  // the robot's joints as Lie groups (once per worker, not per node)
  pinocchio::Model zero_gravity;
  pinocchio::Data zero_data, data;
  std::map<int, size_t> foot_index;  // frame id -> its index in chain (and point_mass)
  // per foot: its chain, the chain's Data and recursion work (point_terms, the swing feet's
  // curvature)
  std::vector<FootChain> chain;
  std::vector<pinocchio::Data> chain_data;
  std::vector<RneaHessianWork> chain_rh;
  Rnea2 t, tf;
  // the robot's recursion terms (rigid_body/rnea_hessian.hpp) for the factored expansion, and the
  // chains' contraction outputs (sized by point_terms)
  RneaHessianWork rh;
  std::vector<double> r4, unit;
  std::vector<double> total;  // force_terms' sum over the feet
  explicit ContactSecondWork(const ContactSetup& s)
      : robot(s.model), groups(joint_groups(*s.model)),
        zero_gravity(*s.model), zero_data(*s.model), data(*s.model), t(s.model->nv), tf(s.model->nv),
        rh(*s.model) {
    zero_gravity.gravity.setZero();
    for (const ContactNode& n : s.nodes) {
      for (int f : n.feet) add_foot(*s.model, f);
      for (int f : n.swing) add_foot(*s.model, f);
    }
  }
  void add_foot(const pinocchio::Model& model, int f) {
    if (foot_index.count(f)) return;
    foot_index[f] = chain.size();
    frames.push_back(f);
    chain.emplace_back(model, f);
    chain_data.emplace_back(chain.back().model);
    chain_rh.emplace_back(chain.back().model);
    point_models.emplace_back();
    point_data.emplace_back();
  }
  // Foot idx's point-mass copy of the whole robot and its Data, made at the first call: only the
  // dense expansion's force terms read them (the factored one works on the chains).
  std::pair<pinocchio::Model&, pinocchio::Data&> point_mass(size_t idx) {
    if (!point_models[idx]) {
      point_models[idx] = std::make_unique<pinocchio::Model>(point_mass_model(*robot, frames[idx]));
      point_data[idx] = std::make_unique<pinocchio::Data>(*point_models[idx]);
    }
    return {*point_models[idx], *point_data[idx]};
  }

 private:
  std::vector<int> frames;
  std::vector<std::unique_ptr<pinocchio::Model>> point_models;
  std::vector<std::unique_ptr<pinocchio::Data>> point_data;
};

namespace {

// Foot frame f's chain dofs (FootChain::vi: the robot's dofs that move it, increasing).
const std::vector<int>& chain_of(const ContactSecondWork& w, int f) { return w.chain[w.foot_index.at(f)].vi; }

// The feet's world accelerations p''(q, v, a) (3 rows per foot) and their derivatives in the right
// chart: Jw (3 nf, nv) = P_a and P_qq (symmetric), P_qv, P_qa, P_vv on each foot's chain
// (FootChain: every other entry is zero), each (3 nf, nmax^2) with foot i's rows [c][j][l]
// row-major over its chain's n_i dofs (P_qa[c][j][l] = d J_w[c, vi[l]] / d q_vi[j]; chain_of(w,
// foot) gives vi). From the point-mass model's RNEA: tau = J_w^T p'', whose free-flyer
// translational rows are oR_b^T p'' (ContactDynamics._point_terms).
void point_terms(ContactSecondWork& w, const std::vector<int>& feet, const Eigen::VectorXd& q,
                 const Eigen::VectorXd& v, const Eigen::VectorXd& a, RowMat& Jw, RowMat& Pqq, RowMat& Pqv,
                 RowMat& Pqa, RowMat& Pvv) {
  const int nv = (int)v.size(), nf = (int)feet.size();
  int nmax = 0;
  for (int f : feet) nmax = std::max(nmax, (int)chain_of(w, f).size());
  Jw.setZero(3 * nf, nv);
  for (RowMat* P : {&Pqq, &Pqv, &Pqa, &Pvv}) P->resize(3 * nf, (Eigen::Index)nmax * nmax);
  const Eigen::Matrix3d R = Eigen::Quaterniond(q[6], q[3], q[4], q[5]).toRotationMatrix();
  for (int i = 0; i < nf; ++i) {
    // on the foot's chain (FootChain: the dofs that move it; the others' entries are zero)
    const size_t idx = w.foot_index.at(feet[(size_t)i]);
    const FootChain& ch = w.chain[idx];
    const pinocchio::Model& mf = ch.model;
    pinocchio::Data& df = w.chain_data[idx];
    RneaHessianWork& rh = w.chain_rh[idx];
    const int n = mf.nv, cn = n * n;
    Eigen::VectorXd qc(mf.nq), vc(n), ac(n);
    for (int j = 0; j < mf.nq; ++j) qc[j] = q[ch.qi[(size_t)j]];
    for (int j = 0; j < n; ++j) {
      vc[j] = v[ch.vi[(size_t)j]];
      ac[j] = a[ch.vi[(size_t)j]];
    }
    RowMat Lqq(3, cn), Lqv(3, cn), Lqa(3, cn), Lvv(3, cn);
    const Eigen::Vector3d W = libpin::rnea(mf, df, qc, vc, ac).head<3>();
    libpin::computeRNEADerivatives(mf, df, qc, vc, ac);
    const Eigen::MatrixXd Wq = df.dtau_dq.topRows(3), Wv = df.dtau_dv.topRows(3);
    const Eigen::MatrixXd Wa = Eigen::MatrixXd(df.M.selfadjointView<Eigen::Upper>()).topRows(3);
    // only the three translational rows c of the base are needed: sum_i e_c,i X(i, j, l) for the four
    // tensors X, by the recursion (a few n^2 products) instead of Pinocchio's whole tensors (4 n^3)
    rnea_hessian_node(mf, rh, qc.data(), vc.data(), ac.data(), rh.node.data());
    w.r4.resize(4 * (size_t)cn);
    const double *Hqq = w.r4.data(), *Hvv = Hqq + cn, *Hqv = Hvv + cn, *Dm = Hqv + cn;
    for (int c = 0; c < 3; ++c) {
      w.unit.assign((size_t)n, 0.0);
      w.unit[(size_t)c] = 1.0;
      rnea_hessian_contract(mf, rh, rh.node.data(), w.unit.data(), w.r4.data(), w.r4.data() + cn,
                            w.r4.data() + 2 * cn, w.r4.data() + 3 * cn);
      for (int j = 0; j < n; ++j)
        for (int l = 0; l < n; ++l) {
          Lqq(c, j * n + l) = 0.5 * (Hqq[j + n * l] + Hqq[l + n * j]);
          Lqv(c, j * n + l) = Hqv[j + n * l];
          Lqa(c, j * n + l) = Dm[l + n * j];
          Lvv(c, j * n + l) = Hvv[j + n * l];
        }
    }
    // the product rule's terms: oR_b(q exp(eta)) = oR_b exp(eta_rot) on the base's rotational
    // directions 3..5 (E_i = skew(e_i)), the chain's dofs 3..5 as the robot's
    for (int e = 0; e < 3; ++e)
      for (int j = 0; j < n; ++j) {
        const Eigen::Vector3d gq = cross_e(e, Wq.col(j)), gv = cross_e(e, Wv.col(j)), ga = cross_e(e, Wa.col(j));
        for (int c = 0; c < 3; ++c) {
          Lqq(c, (3 + e) * n + j) += gq[c];
          Lqq(c, j * n + 3 + e) += gq[c];
          Lqv(c, (3 + e) * n + j) += gv[c];
          Lqa(c, (3 + e) * n + j) += ga[c];
        }
      }
    for (int e = 0; e < 3; ++e)
      for (int f = 0; f < 3; ++f) {
        const Eigen::Vector3d gg = 0.5 * (cross_e(e, cross_e(f, W)) + cross_e(f, cross_e(e, W)));
        for (int c = 0; c < 3; ++c) Lqq(c, (3 + e) * n + 3 + f) += gg[c];
      }
    // rotated to the world; Jw scattered to the robot's dofs
    const Eigen::Matrix<double, 3, Eigen::Dynamic> RWa = R * Wa;
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < n; ++j) Jw(3 * i + c, ch.vi[(size_t)j]) = RWa(c, j);
    Pqq.block(3 * i, 0, 3, cn).noalias() = R * Lqq;
    Pqv.block(3 * i, 0, 3, cn).noalias() = R * Lqv;
    Pqa.block(3 * i, 0, 3, cn).noalias() = R * Lqa;
    Pvv.block(3 * i, 0, 3, cn).noalias() = R * Lvv;
  }
}

// Subtract from Hss's RNEA rows (q-q block) the curvature of sum_f J_w,f(q)^T lambda_f (world
// forces held): the point-mass model's RNEA at v = a = 0 under the gravity -lambda_f.
void force_terms(ContactSecondWork& w, const std::vector<int>& feet, const Eigen::VectorXd& q,
                 const Eigen::VectorXd& forces, Eigen::Map<RowMat>& Hss) {
  const int nv = w.zero_gravity.nv, ns = 2 * nv, nf = (int)feet.size();
  if (nf == 0) return;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(nv);
  std::vector<double>& total = w.total;
  total.assign((size_t)nv * nv * nv, 0.0);
  for (int i = 0; i < nf; ++i) {
    auto [mf, df] = w.point_mass(w.foot_index.at(feet[(size_t)i]));
    mf.gravity = pinocchio::Motion(-forces.segment<3>(3 * i), Eigen::Vector3d::Zero());
    w.tf.at(mf, df, q, zero, zero);
    mf.gravity.setZero();
    for (size_t x = 0; x < total.size(); ++x) total[x] += w.tf.qq[x];
  }
  for (int r = 0; r < nv; ++r)
    for (int a = 0; a < nv; ++a)
      for (int b = 0; b < nv; ++b)
        Hss(r, a * ns + b) -= 0.5 * (Rnea2::get(total, nv, r, a, b) + Rnea2::get(total, nv, r, b, a));
}

// E_y = [[M, -Jw^T], [Jw, 0]] (ny, ny).
Eigen::MatrixXd kkt_matrix(const Eigen::MatrixXd& M, const RowMat& Jw) {
  const int nv = (int)M.rows(), nc = (int)Jw.rows(), ny = nv + nc;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(ny, ny);
  K.topLeftCorner(nv, nv) = M;
  if (nc > 0) {
    K.topRightCorner(nv, nc) = -Jw.transpose();
    K.bottomLeftCorner(nc, nv) = Jw;
  }
  return K;
}

// The right-hand side of E_y y'' = -(E_ss + E_sy Y1 + its transpose) from E_ww's blocks Hss
// (ny, ns * ns), Hsy (ny, nv * ny: E_sy's q rows, its others are zero) and Y1 = dy/dz (ny, nz), and Kinv = -E_y^-1 (ny, ny), E_y =
// [[M, -Jw^T], [Jw, 0]] (ContactDynamics._kkt_second), so that y'' = Kinv rhs row by row. Each row r of
// rhs (ny, ns * nz) is the (s, z) block (ns, nz) of that row's symmetric (nz, nz) matrix, whose
// (u, u) block is zero (E is affine in u).
void kkt_rhs(const double* Hss, const double* Hsy, const RowMat& Y1, const Eigen::MatrixXd& M, const RowMat& Jw,
             double* rhs, RowMat& Kinv) {
  const int nv = (int)M.rows(), ny = nv + (int)Jw.rows(), ns = 2 * nv, nz = (int)Y1.cols();
  for (int r = 0; r < ny; ++r) {
    // E_sy is zero in v's rows, and the foot rows' (r >= nv) only couple with a
    // (linalg/small_gemm.hpp: AVX2/FMA where the CPU has it)
    Eigen::Map<RowMat> out(rhs + (size_t)r * ns * nz, ns, nz);
    gemm::gemm(false, nv, nz, r < nv ? ny : nv, 1.0, Hsy + (size_t)r * nv * ny, ny, Y1.data(), nz, false, out.data(),
               nz);
    out.bottomRows(nv).setZero();
    // out's (s, s) block += Hss_r + its transpose, pair by pair (no copy of the block)
    Eigen::Map<const RowMat> Hr(Hss + (size_t)r * ns * ns, ns, ns);
    for (int a = 0; a < ns; ++a)
      for (int b = a; b < ns; ++b) {
        const double p = out(a, b) + out(b, a);
        out(a, b) = Hr(a, b) + p;
        if (b != a) out(b, a) = Hr(b, a) + p;
      }
  }
  Kinv = -kkt_matrix(M, Jw).partialPivLu().inverse();
}

// Rows [r0, r1) of y'' (Y (ny, nz * nz), each row a symmetric (nz, nz) matrix, row-major) from
// kkt_rhs's rhs and Kinv; Y's other rows are left as they are.
void y_rows(const double* rhs, const RowMat& Kinv, int nv, int nz, int r0, int r1, RowMat& Y) {
  const int ny = (int)Kinv.rows(), ns = 2 * nv, rows = r1 - r0;
  if (rows <= 0) return;
  RowMat Ys(rows, (Eigen::Index)ns * nz);
  gemm::gemm(false, rows, ns * nz, ny, 1.0, Kinv.row(r0).data(), ny, rhs, ns * nz, false, Ys.data(), ns * nz);
  for (int r = 0; r < rows; ++r) {
    Eigen::Map<RowMat> Yr(Y.row(r0 + r).data(), nz, nz);
    Eigen::Map<const RowMat> Ysr(Ys.row(r).data(), ns, nz);
    Yr.topRows(ns) = Ysr;
    Yr.bottomLeftCorner(nz - ns, ns) = Ysr.rightCols(nz - ns).transpose();
    Yr.bottomRightCorner(nz - ns, nz - ns).setZero();
  }
}

}  // namespace

namespace {

// A node's KKT system's first-order blocks (see kkt_rhs): Y1 = dy/dz, M and the feet's acceleration
// Jacobian Jw (3 nf, nv). node_kkt writes the second-order ones, Hss (ny, ns * ns) and Hsy (ny,
// nv * ny, E_sy's q rows), into its caller's arrays; node_factored keeps them factored.
struct NodeKkt {
  RowMat Y1, Jw;
  Eigen::MatrixXd M;
};

// The rows y of a node's KKT system: nv + 3 per foot.
int kkt_rows(const ContactSetup& s, const ContactNode& node) { return s.model->nv + 3 * (int)node.feet.size(); }

// The point terms' outputs (point_terms), kept per worker.
struct PointTerms {
  RowMat Pqq, Pqv, Pqa, Pvv;
};

// point_terms at a node: the feet's accelerations at (q, v, a + Kd v) at a contact node (Kd v: the
// Baumgarte drift's velocity term), their velocity jumps at (q, 0, v+) at an impulse node.
void node_point_terms(const ContactSetup& s, ContactSecondWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                      const Eigen::VectorXd& v, const ContactEval& ev, RowMat& Jw, PointTerms& pt) {
  if (!node.impulse) point_terms(w, node.feet, q, v, ev.acc + s.Kd * v, Jw, pt.Pqq, pt.Pqv, pt.Pqa, pt.Pvv);
  else point_terms(w, node.feet, q, Eigen::VectorXd::Zero(v.size()), ev.v_next, Jw, pt.Pqq, pt.Pqv, pt.Pqa, pt.Pvv);
}

// NodeKkt's M and Y1 at q (Jw: node_point_terms'; emptied to (0, nv) at a node without feet).
void kkt_blocks(const ContactSetup& s, ContactSecondWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                const ContactEval& ev, NodeKkt& out) {
  const int nv = s.model->nv, nc = 3 * (int)node.feet.size();
  libpin::crba(*s.model, w.data, q);
  out.M = w.data.M.selfadjointView<Eigen::Upper>();
  out.Y1.resize(nv + nc, ev.Az.cols());
  out.Y1.topRows(nv) = ev.Az;
  if (nc > 0) out.Y1.bottomRows(nc) = ev.Lz;
  if (nc == 0) out.Jw.resize(0, nv);
}

void node_kkt(const ContactSetup& s, ContactSecondWork& w, const ContactNode& node, const Eigen::VectorXd& q,
              const Eigen::VectorXd& v, const ContactEval& ev, double* hss_out, double* hsy_out, NodeKkt& out) {
  const pinocchio::Model& m = *s.model;
  const int nv = m.nv, nf = (int)node.feet.size(), nc = 3 * nf, ny = nv + nc, ns = 2 * nv;
  Eigen::Map<RowMat> Hss(hss_out, ny, (Eigen::Index)ns * ns), Hsy(hsy_out, ny, (Eigen::Index)nv * ny);
  Hss.setZero();
  Hsy.setZero();
  auto hss = [&](int r, int a, int b) -> double& { return Hss(r, a * ns + b); };
  auto hsy = [&](int r, int a, int y) -> double& { return Hsy(r, a * ny + y); };
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(nv);
  Rnea2& T = w.t;
  PointTerms pt;
  node_point_terms(s, w, node, q, v, ev, out.Jw, pt);
  const RowMat &Pqq = pt.Pqq, &Pqv = pt.Pqv, &Pqa = pt.Pqa, &Pvv = pt.Pvv;
  if (!node.impulse) {
    const double Kp = s.Kp, Kd = s.Kd;
    T.at(m, w.data, q, v, ev.acc);
    for (int i = 0; i < nv; ++i)
      for (int a = 0; a < nv; ++a)
        for (int b = 0; b < nv; ++b) {
          hss(i, a, b) = 0.5 * (Rnea2::get(T.qq, nv, i, a, b) + Rnea2::get(T.qq, nv, i, b, a));
          hss(i, a, nv + b) = Rnea2::get(T.qv, nv, i, a, b);
          hss(i, nv + b, a) = Rnea2::get(T.qv, nv, i, a, b);
          hss(i, nv + a, nv + b) = Rnea2::get(T.vv, nv, i, a, b);
          hsy(i, a, b) = Rnea2::get(T.aq, nv, i, b, a);
        }
    force_terms(w, node.feet, q, ev.forces, Hss);
    for (int c = 0; c < nc; ++c) {
      const int r = nv + c;
      const std::vector<int>& vi = chain_of(w, node.feet[(size_t)(c / 3)]);
      const int n = (int)vi.size();
      for (int j = 0; j < n; ++j)
        for (int l = 0; l < n; ++l) {
          const int a = vi[(size_t)j], b = vi[(size_t)l];
          hss(r, a, b) = Pqq(c, j * n + l) + Kp * 0.5 * (Pqa(c, j * n + l) + Pqa(c, l * n + j));
          const double qv = Pqv(c, j * n + l) + Kd * Pqa(c, j * n + l);
          hss(r, a, nv + b) = qv;
          hss(r, nv + b, a) = qv;
          hss(r, nv + a, nv + b) = Pvv(c, j * n + l);
          hsy(r, a, b) = Pqa(c, j * n + l);
          hsy(b, a, nv + c) = -Pqa(c, j * n + l);
        }
    }
  } else {
    T.at(w.zero_gravity, w.zero_data, q, zero, ev.v_next - v);
    for (int i = 0; i < nv; ++i)
      for (int a = 0; a < nv; ++a)
        for (int b = 0; b < nv; ++b) {
          hss(i, a, b) = 0.5 * (Rnea2::get(T.qq, nv, i, a, b) + Rnea2::get(T.qq, nv, i, b, a));
          hsy(i, a, b) = Rnea2::get(T.aq, nv, i, b, a);
          hss(i, nv + a, b) = -Rnea2::get(T.aq, nv, i, a, b);
          hss(i, a, nv + b) = -Rnea2::get(T.aq, nv, i, b, a);
        }
    force_terms(w, node.feet, q, ev.forces, Hss);
    for (int c = 0; c < nc; ++c) {
      const int r = nv + c;
      const std::vector<int>& vi = chain_of(w, node.feet[(size_t)(c / 3)]);
      const int n = (int)vi.size();
      for (int j = 0; j < n; ++j)
        for (int l = 0; l < n; ++l) {
          const int a = vi[(size_t)j], b = vi[(size_t)l];
          hss(r, a, b) = Pqq(c, j * n + l);
          hsy(r, a, b) = Pqa(c, j * n + l);
          hsy(b, a, nv + c) = -Pqa(c, j * n + l);
        }
    }
  }
  kkt_blocks(s, w, node, q, ev, out);
}

}  // namespace

void contact_node_second(const ContactSetup& s, ContactSecondWork& w, const ContactNode& node, const Eigen::VectorXd& q,
                         const Eigen::VectorXd& v, const ContactEval& ev, RowMat& Y, bool forces) {
  NodeKkt e;
  const int nv = s.model->nv, ns = 2 * nv, ny = kkt_rows(s, node);
  std::vector<double> Hss((size_t)ny * ns * ns), Hsy((size_t)ny * nv * ny);
  node_kkt(s, w, node, q, v, ev, Hss.data(), Hsy.data(), e);
  const int nz = (int)e.Y1.cols();
  RowMat rhs(ny, (Eigen::Index)ns * nz), Kinv;
  kkt_rhs(Hss.data(), Hsy.data(), e.Y1, e.M, e.Jw, rhs.data(), Kinv);
  // the forces' rows only when asked (the cost curvature reads them where a friction-cone barrier
  // is active); otherwise they are left unset
  Y.resize(ny, (Eigen::Index)nz * nz);
  y_rows(rhs.data(), Kinv, nv, nz, 0, forces ? ny : nv, Y);
}

namespace {

// The index of a chain in t.chains (contact_linearise_contracted lists every foot's).
int chain_index(const SecondOrderTerms& t, const std::vector<int>& vi) {
  for (size_t c = 0; c < t.chains.size(); ++c)
    if (t.chains[c] == vi) return (int)c;
  throw std::logic_error("contact second order: a foot's chain was not listed");
}

// Node k's second order in factored form (SecondOrderTerms, contact = true; see second_order_terms.hpp)
// and its KKT blocks M, Jw, Y1 (into out): the RNEA rows as the recursion's mu-free terms of the robot
// (or, at an impulse node, of the robot without gravity at (q, 0, v+ - v)), each foot's point and
// force (J_w,i^T lambda_i's curvature, subtracted in the pass); the feet's rows of E_ss (packed,
// symmetrised) and their Pqa, as node_kkt forms them densely.
void node_factored(const ContactSetup& s, ContactSecondWork& w, int k, const ContactNode& node,
                   const Eigen::VectorXd& q, const Eigen::VectorXd& v, const ContactEval& ev, PointTerms& pt,
                   NodeKkt& out, SecondOrderTerms& t) {
  const pinocchio::Model& m = *s.model;
  const int nv = m.nv, nf = (int)node.feet.size();
  const size_t size = rnea_hessian_node_size(m);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(nv);
  double* rnea = t.rnea.data() + (size_t)k * size;
  if (!node.impulse) {
    rnea_hessian_node(m, w.rh, q.data(), v.data(), ev.acc.data(), rnea);
  } else {
    const Eigen::VectorXd dv = ev.v_next - v;
    rnea_hessian_node(w.zero_gravity, w.rh, q.data(), zero.data(), dv.data(), rnea);
  }
  // each foot's point and force, for the point-force recursion (w.rh's kinematics are at q)
  for (int i = 0; i < nf; ++i) {
    const pinocchio::Frame& fr = m.frames[(size_t)node.feet[(size_t)i]];
    const size_t f = (size_t)k * t.nf_max + i;
    t.foot_joint[f] = (int)fr.parentJoint;
    Eigen::Map<Eigen::Vector3d>(t.force.data() + 6 * f) = w.rh.data.oMi[fr.parentJoint].act(fr.placement).translation();
    Eigen::Map<Eigen::Vector3d>(t.force.data() + 6 * f + 3) = ev.forces.segment<3>(3 * i);
  }
  node_point_terms(s, w, node, q, v, ev, out.Jw, pt);
  // the feet's rows of E_ss on their chains, symmetrised, upper triangle row by row (node_kkt's
  // entries), and Pqa
  const double Kp = node.impulse ? 0.0 : s.Kp, Kd = node.impulse ? 0.0 : s.Kd;
  const size_t cu = t.chain_upper(), cm = (size_t)t.chain_max * t.chain_max;
  for (int i = 0; i < nf; ++i) {
    const size_t slot = (size_t)k * t.nf_max + i;
    const std::vector<int>& vi = chain_of(w, node.feet[(size_t)i]);
    const int n = (int)vi.size();
    t.foot_chain[slot] = chain_index(t, vi);
    for (int c = 0; c < 3; ++c) {
      const int r = 3 * i + c;
      const double *Pqq = pt.Pqq.row(r).data(), *Pqv = pt.Pqv.row(r).data(), *Pqa = pt.Pqa.row(r).data(),
                   *Pvv = pt.Pvv.row(r).data();
      double* packed = t.Ess.data() + (slot * 3 + c) * cu;
      for (int a = 0; a < n; ++a) {
        for (int b = a; b < n; ++b)
          *packed++ = 0.5 * (Pqq[a * n + b] + Pqq[b * n + a]) + Kp * 0.5 * (Pqa[a * n + b] + Pqa[b * n + a]);
        for (int b = 0; b < n; ++b) *packed++ = node.impulse ? 0.0 : Pqv[a * n + b] + Kd * Pqa[a * n + b];
      }
      for (int a = 0; a < n; ++a)
        for (int b = a; b < n; ++b) *packed++ = node.impulse ? 0.0 : 0.5 * (Pvv[a * n + b] + Pvv[b * n + a]);
      std::copy(Pqa, Pqa + (size_t)n * n, t.Pqa.data() + (slot * 3 + c) * cm);
    }
  }
  kkt_blocks(s, w, node, q, ev, out);
}

}  // namespace

namespace {

// sum_p c_p d^2 r_p (nv, nv) of r(eta) = difference(q_ref, q exp(eta)), exactly: -K^T ((K^T c) .
// Dsym) K per SO(3)/SE(3) group (K = Jr(r0)^-1, D = dJr at r0), zero on the commutative joints
// (ContactProblem._difference_curvature).
void difference_curvature(const std::vector<JointGroup>& groups, const Eigen::VectorXd& r0, const Eigen::VectorXd& c,
                          double weight, Eigen::MatrixXd& out) {
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SE3) {
      const Eigen::Matrix<double, 6, 1> x = r0.segment<6>(o);
      const lie::Mat6 K = lie::se3_jr_inverse(lie::se3_jr(x));
      const Eigen::Matrix<double, 6, 1> kc = K.transpose() * c.segment<6>(o);
      lie::Mat6 D[6], Ms;
      lie::se3_djr(x, D);
      for (int b = 0; b < 6; ++b) Ms.col(b) = D[b].transpose() * kc;  // Ms(a, b) = sum_p kc_p dJr(p, a) / dx_b
      const lie::Mat6 S = 0.5 * (Ms + Ms.transpose());
      out.block<6, 6>(o, o) -= weight * (K.transpose() * S * K);
    } else if (g.kind == SO3) {
      const lie::Vec3 x = r0.segment<3>(o);
      const lie::Mat3 K = lie::so3_jr(x).inverse();
      const lie::Vec3 kc = K.transpose() * c.segment<3>(o);
      lie::Mat3 D[3], Ms;
      lie::so3_djr(x, D);
      for (int b = 0; b < 3; ++b) Ms.col(b) = D[b].transpose() * kc;
      const lie::Mat3 S = 0.5 * (Ms + Ms.transpose());
      out.block<3, 3>(o, o) -= weight * (K.transpose() * S * K);
    }
  }
}

// The chart Hessian (nv, nv) of a potential whose generalised force is J^T force: the model's
// generalised gravity under the gravity -force (ContactProblem._gravity_curvature), times weight.
void gravity_curvature(pinocchio::Model& model, pinocchio::Data& data, const Eigen::VectorXd& q,
                       const Eigen::Vector3d& force, double weight, Eigen::MatrixXd& out) {
  const pinocchio::Motion g0 = model.gravity;
  model.gravity = pinocchio::Motion(-force, Eigen::Vector3d::Zero());
  Eigen::MatrixXd dg = Eigen::MatrixXd::Zero(model.nv, model.nv);
  libpin::computeGeneralizedGravityDerivatives(model, data, q, dg);
  model.gravity = g0;
  out += weight * 0.5 * (dg + dg.transpose());
}

// gravity_curvature of a foot's point mass (a foot-tracking residual's curvature), on its chain
// (FootChain: the other dofs' entries are zero), scattered into out.
void chain_gravity_curvature(ContactSecondWork& w, size_t idx, const Eigen::VectorXd& q, const Eigen::Vector3d& force,
                             double weight, Eigen::MatrixXd& out) {
  FootChain& ch = w.chain[idx];
  pinocchio::Model& mc = ch.model;
  const int n = mc.nv;
  Eigen::VectorXd qc(mc.nq);
  for (int j = 0; j < mc.nq; ++j) qc[j] = q[ch.qi[(size_t)j]];
  Eigen::MatrixXd dg = Eigen::MatrixXd::Zero(n, n);
  mc.gravity = pinocchio::Motion(-force, Eigen::Vector3d::Zero());
  libpin::computeGeneralizedGravityDerivatives(mc, w.chain_data[idx], qc, dg);
  mc.gravity.setZero();
  for (int j = 0; j < n; ++j)
    for (int l = 0; l < n; ++l) out(ch.vi[(size_t)j], ch.vi[(size_t)l]) += weight * 0.5 * (dg(j, l) + dg(l, j));
}

}  // namespace

bool cone_weights(const ContactSetup& s, const ContactNode& node, const ContactEval& ev, Eigen::VectorXd& wy) {
  const int nv = s.model->nv, r = (int)s.cone_A.rows();
  wy.setZero(kkt_rows(s, node));
  if (node.impulse) return false;  // an impulse node's cost has no friction cone
  bool active = false;
  for (size_t i = 0; i < node.feet.size(); ++i) {
    const Eigen::VectorXd fr = s.cone_A * ev.forces.segment<3>(3 * (Eigen::Index)i);
    Eigen::Vector3d exA = Eigen::Vector3d::Zero();
    bool any = false;
    for (int j = 0; j < r; ++j) {
      const double e = excess(fr[j], s.cone_lb[j], s.cone_ub[j]);
      if (e != 0.0) any = true;
      exA += e * s.cone_A.row(j).transpose();
    }
    if (!any) continue;  // inside the cone the barrier is flat
    active = true;
    wy.segment<3>(nv + 3 * (Eigen::Index)i) = (s.w.friction_cone * s.dt) * exA;
  }
  return active;
}

bool cone_active(const ContactSetup& s, const ContactNode& node, const ContactEval& ev) {
  Eigen::VectorXd wy;
  return cone_weights(s, node, ev, wy);
}

void contact_cost_curvature(const ContactSetup& s, ContactSecondWork& w, int k, const Eigen::VectorXd& q,
                            const Eigen::VectorXd& v, const ContactEval* ev, const RowMat* Y, RowMat& Hs) {
  const pinocchio::Model& m = *s.model;
  pinocchio::Data& d = w.data;
  const int nv = m.nv, nz = (int)Hs.cols();
  const bool terminal = k == s.horizon();
  const ContactNode& node = s.nodes[(size_t)k];
  const GaitWeights& c = s.w;
  const std::vector<JointGroup>& groups = w.groups;
  libpin::forwardKinematics(m, d, q);
  libpin::updateFramePlacements(m, d);
  Eigen::MatrixXd curv = Eigen::MatrixXd::Zero(nv, nv);
  Eigen::VectorXd rq(nv);
  libpin::difference(m, s.q_ref, q, rq);
  auto feet = [&](double weight) {
    for (size_t i = 0; i < node.swing.size(); ++i) {
      chain_gravity_curvature(w, w.foot_index.at(node.swing[i]), q,
                              d.oMf[(size_t)node.swing[i]].translation() - node.swing_target[i], weight, curv);
    }
  };
  if (node.impulse && !terminal) {
    difference_curvature(groups, rq, s.w_impulse.head(nv).cwiseProduct(rq), c.impulse_state, curv);
    feet(c.impulse_foot);
    Hs.topLeftCorner(nv, nv) += curv;
    return;
  }
  difference_curvature(groups, rq, s.w_state.head(nv).cwiseProduct(rq), c.state, curv);
  if (c.bounds != 0.0) {
    Eigen::VectorXd rb(nv), ex(nv);
    libpin::difference(m, s.q_neutral, q, rb);
    bool any = false;
    for (int i = 0; i < nv; ++i) {
      ex[i] = excess(rb[i], s.lb[i], s.ub[i]);
      any = any || ex[i] != 0.0;
    }
    if (any) difference_curvature(groups, rb, ex, c.bounds, curv);
  }
  if (node.has_com) {
    const Eigen::Vector3d r = libpin::centerOfMass(m, d, q) - node.com;
    gravity_curvature(w.zero_gravity, w.zero_data, q, r / libpin::computeTotalMass(m), c.com, curv);
  }
  feet(c.foot);
  Hs.topLeftCorner(nv, nv) += (terminal ? 1.0 : s.dt) * curv;
  if (terminal || node.feet.empty() || Y == nullptr) return;
  Eigen::VectorXd wy;
  if (!cone_weights(s, node, *ev, wy)) return;
  Eigen::Map<RowMat> H(Hs.data(), nz, nz);
  for (Eigen::Index r = nv; r < wy.size(); ++r)
    if (wy[r] != 0.0) H += wy[r] * Eigen::Map<const RowMat>(Y->row(r).data(), nz, nz);
}

namespace {

// The second-order expansions' node loop: for_each_node (contact.hpp) with, per worker, a
// ContactSecondWork and a Scratch(nv, nz); the terminal node's exact cost expansion into lfx, lfxx;
// each running node, evaluated with derivatives, handed to node(k, q, v, ev, g, Hs, w, scratch),
// which adds its second order.
template <class Scratch>
struct SecondOrderExtra {
  ContactWork node;
  ContactSecondWork w;
  Scratch scratch;
  explicit SecondOrderExtra(const ContactSetup& s)
      : node(*s.model), w(s), scratch(s.model->nv, 2 * s.model->nv + s.nu()) {}
  ContactWork& node_work() { return node; }
};

template <class Scratch, class NodeFn>
void second_order_nodes(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                        double* lfx, double* lfxx, double* costs, NodeFn&& node) {
  const int n = 2 * s.model->nv;
  typedef SecondOrderExtra<Scratch> Extra;
  for_each_node<Extra>(
      s, Q, V, U, threads, true, costs,
      [&](int k, const Eigen::VectorXd& q, const Eigen::VectorXd& v, const ContactEval& ev, const Eigen::VectorXd& g,
          RowMat& Hs, Extra& x) { node(k, q, v, ev, g, Hs, x.w, x.scratch); },
      [&](const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& g, RowMat& Hs, Extra& x) {
        contact_cost_curvature(s, x.w, s.horizon(), q, v, nullptr, nullptr, Hs);
        store_terminal_expansion(n, g, Hs, lfx, lfxx);
      });
}

// The semi-implicit Euler step's chart blocks at a contact node (q+ = q exp(dt v+)): A, Jr and
// block_ad_jr's D at dt v+, W1 = dv+/dz (ev.Fz's velocity rows) and JW = Jr W1.
struct StepBlocks {
  RowMat A, Jr, W1, JW;
  std::vector<double> Dt;
  Eigen::VectorXd omega;
  explicit StepBlocks(int nv) : A(nv, nv), Jr(nv, nv), Dt((size_t)nv * nv * nv), omega(nv) {}
  void at(const std::vector<JointGroup>& groups, double dt, const ContactEval& ev) {
    const int nv = (int)omega.size();
    omega = dt * ev.v_next;
    lie::block_ad_jr(groups, nv, omega.data(), A.data(), Jr.data(), Dt.data());
    W1 = ev.Fz.bottomRows(nv);
    jr_times(groups, Jr, 1.0, W1, JW);
  }
};

struct DenseScratch {
  StepBlocks step;
  RowMat Y, G2, JF2, Ds, Mz, WDW;
  DenseScratch(int nv, int nz) : step(nv), G2(2 * nv, (Eigen::Index)nz * nz) {}
};

struct FactoredScratch {
  StepBlocks step;
  NodeKkt kkt;
  PointTerms points;
  RowMat Kinv, S;
  Eigen::VectorXd wy, mu;
  FactoredScratch(int nv, int) : step(nv) {}
};

}  // namespace

void contact_linearise_second(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                              double* Phi, double* B, double* Theta, double* Gamma, double* Xi, double* lx, double* lu,
                              double* lxx, double* lux, double* luu, double* lfx, double* lfxx, double* costs) {
  const int nv = s.model->nv, nu = s.nu(), n = 2 * nv, nz = n + nu;
  const double dt = s.dt;
  const lie::GroupStructure gs;
  second_order_nodes<DenseScratch>(s, Q, V, U, threads, lfx, lfxx, costs, [&](int k, const Eigen::VectorXd& q,
                                   const Eigen::VectorXd& v, const ContactEval& ev, const Eigen::VectorXd& g,
                                   RowMat& Hs, ContactSecondWork& w, DenseScratch& x) {
    const ContactNode& node = s.nodes[(size_t)k];
    RowMat& G2 = x.G2;
    contact_node_second(s, w, node, q, v, ev, x.Y, cone_active(s, node, ev));
    contact_cost_curvature(s, w, k, q, v, &ev, &x.Y, Hs);
    store_node_expansion(k, n, nu, ev, g, Hs, Phi, B, lx, lu, lxx, lux, luu);
    if (node.impulse) {  // q+ = q: only v+'s rows
      G2.topRows(nv).setZero();
      G2.bottomRows(nv) = x.Y.topRows(nv);
    } else {
      // the semi-implicit Euler step q+ = q exp(dt v+), v+ = v + dt a (geoddp.models.integrators.expand)
      StepBlocks& st = x.step;
      st.at(w.groups, dt, ev);
      reconstruction_group_terms(w.groups, gs, dt, nv, st.Dt, st.A, st.W1, st.JW, G2, x.Ds, x.Mz, x.WDW);
      G2.bottomRows(nv) = dt * x.Y.topRows(nv);  // v+'' = dt a''
      jr_times(w.groups, st.Jr, dt, G2.bottomRows(nv), x.JF2);
      G2.topRows(nv) += x.JF2;
      symmetrise_rows(G2.data(), nv, nz);
    }
    split_second_order(G2, n, nu, Theta + (size_t)k * n * n * n, Gamma + (size_t)k * n * n * nu,
                       Xi + (size_t)k * n * nu * nu);
  });
}

void contact_linearise_contracted(const ContactSetup& s, const double* Q, const double* V, const double* U, int threads,
                                  double* Phi, double* B, double* lx, double* lu, double* lxx, double* lux, double* luu,
                                  double* lfx, double* lfxx, double* costs, SecondOrderTerms& t) {
  const pinocchio::Model& m = *s.model;
  const int H = s.horizon(), nv = m.nv, nu = s.nu(), n = 2 * nv, nz = n + nu, ns = n;
  const double dt = s.dt;
  int nf_max = 0;
  std::vector<std::vector<int>> chains;  // every contact foot's chain dofs (FootChain::vi)
  std::vector<int> listed;
  for (const ContactNode& node : s.nodes) {
    nf_max = std::max(nf_max, (int)node.feet.size());
    for (int f : node.feet) {
      if (std::find(listed.begin(), listed.end(), f) != listed.end()) continue;
      listed.push_back(f);
      std::vector<int> vi = chain_dofs(m, f);
      if (std::find(chains.begin(), chains.end(), vi) == chains.end()) chains.push_back(std::move(vi));
    }
  }
  t.resize_contact(m, nu, H, dt, nf_max, std::move(chains));
  const int ny_max = t.ny_max;
  second_order_nodes<FactoredScratch>(s, Q, V, U, threads, lfx, lfxx, costs, [&](int k, const Eigen::VectorXd& q,
                                      const Eigen::VectorXd& v, const ContactEval& ev, const Eigen::VectorXd& g,
                                      RowMat& Hs, ContactSecondWork& w, FactoredScratch& x) {
    const ContactNode& node = s.nodes[(size_t)k];
    const int ny = kkt_rows(s, node);
    node_factored(s, w, k, node, q, v, ev, x.points, x.kkt, t);
    x.Kinv = -kkt_matrix(x.kkt.M, x.kkt.Jw).partialPivLu().inverse();
    Eigen::Map<RowMat>(t.Yz.data() + (size_t)k * ny_max * nz, ny, nz) = x.kkt.Y1;
    t.ny[(size_t)k] = ny;
    t.impulse[(size_t)k] = node.impulse ? 1 : 0;
    contact_cost_curvature(s, w, k, q, v, &ev, nullptr, Hs);
    if (cone_weights(s, node, ev, x.wy)) {
      // the friction cone's barrier reads the force rows of y'' = Kinv rhs as sum_r wy_r y''_r =
      // sum_r mu_r rhs_r with mu = Kinv^T wy: the pass's contraction of this node's factors
      x.mu.noalias() = x.Kinv.transpose() * x.wy;
      x.S.setZero(nz, nz);
      contact_kkt_upper(t, k, x.mu.data(), x.S.data());
      for (int a = 0; a < nz; ++a)
        for (int b = a; b < nz; ++b) {
          Hs(a, b) += x.S(a, b);
          if (b != a) Hs(b, a) += x.S(a, b);
        }
    }
    store_node_expansion(k, n, nu, ev, g, Hs, Phi, B, lx, lu, lxx, lux, luu);
    Eigen::Map<RowMat>(t.Kt.data() + (size_t)k * nv * ny_max, nv, ny_max).leftCols(ny) = x.Kinv.topRows(nv);
    if (!node.impulse) {
      // the semi-implicit Euler step's chart factors, as the multibody expansion_contracted stores
      // them (dynamics/expansion.cpp)
      StepBlocks& st = x.step;
      st.at(w.groups, dt, ev);
      MatMap(t.F1.data() + (size_t)k * nv * nz, nv, nz) = st.W1;
      store_group_blocks(w.groups, t, k, st.Jr, st.A, st.JW, st.Dt, nv, nz);
    }
  });
}

void contact_node_second_at(const ContactSetup& s, int k, const Eigen::VectorXd& q, const Eigen::VectorXd& v,
                            const Eigen::VectorXd& u, RowMat& Y, RowMat& Hs) {
  // the dense expansion's first worker's work, kept between calls (the tests call this per node)
  typedef SecondOrderExtra<DenseScratch> Extra;
  std::shared_ptr<Extra> x = s.works->check_out<Extra>(s, 0);
  ContactWork& cw = x->node;
  ContactSecondWork& w = x->w;
  ContactEval ev;
  Eigen::VectorXd g;
  if (k == s.horizon()) {
    contact_node_cost(s, cw, k, q, v, Eigen::VectorXd::Zero(s.nu()), nullptr, true, g, Hs);
    contact_cost_curvature(s, w, k, q, v, nullptr, nullptr, Hs);
    Y.resize(0, 0);
  } else {
    contact_step(s, cw, k, q, v, u, true, ev, g, Hs);
    contact_node_second(s, w, s.nodes[(size_t)k], q, v, ev, Y, true);
    contact_cost_curvature(s, w, k, q, v, &ev, &Y, Hs);
  }
  s.works->check_in<Extra>(0, std::move(x));
}

}  // namespace dyn
}  // namespace geoddp
