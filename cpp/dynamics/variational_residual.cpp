// The variational step's residual Jacobian and its building blocks (see variational_residual.hpp;
// twin of the tests' oracle tests/oracle_variational.py, whose names and order of operations this
// follows). Compiled inside dynamics/variational_algorithms.cpp.
#include "dynamics/variational_residual.hpp"

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>

#include "lie/joint_blocks.hpp"
#include "rigid_body/pinocchio_compiled.hpp"

namespace geoddp {
namespace dyn {

void KtMap::set(const std::vector<JointGroup>& groups, const Eigen::VectorXd& x, const Eigen::MatrixXd& K) {
  blocks.clear();
  for (const JointGroup& g : groups) {
    if (g.kind != SO3 && g.kind != SE3) continue;
    Block b;
    b.o = g.idx_v;
    b.n = g.kind == SE3 ? 6 : 3;
    if (b.n == 6) {
      lie::se3_djr(x.segment<6>(b.o), b.D);
      const lie::Mat6 Kt = K.block<6, 6>(b.o, b.o).transpose();
      for (int c = 0; c < 6; ++c) b.C[c] = -(Kt * b.D[c].transpose()) * Kt;
    } else {
      lie::Mat3 D[3];
      lie::so3_djr(x.segment<3>(b.o), D);
      const lie::Mat3 Kt = K.block<3, 3>(b.o, b.o).transpose();
      for (int c = 0; c < 3; ++c) {
        b.D[c].topLeftCorner<3, 3>() = D[c];
        b.C[c].topLeftCorner<3, 3>() = -(Kt * D[c].transpose()) * Kt;
      }
    }
    blocks.push_back(b);
  }
}

void KtMap::apply(const Eigen::VectorXd& p, Eigen::MatrixXd& out) const {
  out.setZero();
  for (const Block& b : blocks) {
    if (b.n == 6) {
      const Eigen::Matrix<double, 6, 1> pg = p.segment<6>(b.o);
      for (int c = 0; c < 6; ++c) out.block<6, 1>(b.o, b.o + c).noalias() = b.C[c] * pg;
    } else {
      const lie::Vec3 pg = p.segment<3>(b.o);
      for (int c = 0; c < 3; ++c) out.block<3, 1>(b.o, b.o + c).noalias() = b.C[c].topLeftCorner<3, 3>() * pg;
    }
  }
}

namespace var {

// the block-diagonal reconstruction operators (lie/joint_blocks.hpp)
using lie::block_jacobians;
using lie::block_transpose_times;
using lie::djr_transpose_apply;
using lie::times_block;

void Kmat(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, Eigen::MatrixXd& K) {
  block_jacobians(vm.groups, x, nullptr, w.Jr, K);
}

void dKT(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& x, const Eigen::MatrixXd& K,
         const Eigen::VectorXd& p, Eigen::MatrixXd& out) {
  w.s.noalias() = K.transpose() * p;
  djr_transpose_apply(vm.groups, x, w.s, w.N);
  block_transpose_times(vm.groups, K, w.N, out);
  out = -out;
}

void lagrangian_hessian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                        const Eigen::VectorXd& v, bool save_tensors) {
  const int nv = vm.model->nv;
  if (vm.configuration_free) {
    w.Hkin.setZero();
  } else {
    kinetic_hessian(vm.free_model, w.fdata, w.kh, q, v, w.Hkin);
    if (save_tensors) {
      mass_tensors(vm.free_model, w.fdata, w.kh, q, v, w.dMdq.data(), w.d2q.data());
    }
  }
  if (vm.gravity_free) {  // no gravity: its derivative is zero (no Pinocchio call)
    w.Hk = w.Hkin;
    return;
  }
  w.T.resize(nv, nv);  // reuse as the gravity derivative's buffer
  w.T.setZero();
  libpin::computeGeneralizedGravityDerivatives(*vm.model, w.data, q, w.T);
  w.Hk = w.Hkin - w.T;
}

void velocity_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::MatrixXd& K1,
                       const Eigen::MatrixXd& D1, const Eigen::VectorXd& y, Eigen::MatrixXd& out) {
  const double dt = vm.dt;
  w.tmp.noalias() = w.M1 * y;
  w.x = -dt * y;
  dKT(vm, w, w.x, K1, w.tmp, w.S);
  block_transpose_times(vm.groups, K1, w.M1, out);
  out -= dt * w.S;
  out.noalias() -= dt * D1.transpose();
}

void residual_jacobian(const VariationalModel& vm, VariationalWork& w, const Eigen::VectorXd& q,
                       const Eigen::VectorXd& v, const Eigen::VectorXd& y, Eigen::MatrixXd& J,
                       const Keep& keep) {
  const Model& model = *vm.model;
  const int nv = model.nv;
  const double dt = vm.dt;
  const bool keep_v = keep.v_terms && keep.M0;
  // one body without gravity: Sq = 0 and R_y fixed, so q+ and Ad_exp(-dt v) are not needed
  const bool fixed = keep.lin && keep.lin->fixed, Sq_zero = fixed && keep.lin->Sq_zero;
  w.omega = dt * v;
  if (!fixed) libpin::integrate(model, q, w.omega, w.qn);
  if (!keep_v) block_jacobians(vm.groups, w.omega, Sq_zero ? nullptr : &w.A, w.Jv, w.K0);  // Ad_exp(-dt v), Jr(dt v), K(dt v)
  if (keep.lin) {
    const QplusLinear& L = *keep.lin;
    w.Sq = L.Sq0;
    w.Ry = L.Ry0;
    if (!fixed) {
      libpin::difference(model, L.qn, w.qn, w.xi);
      for (int k = 0; k < nv; ++k) {
        if (!L.dSq_zero[k]) w.Sq += w.xi[k] * L.dSq[k];
        if (!L.dRy_zero[k]) w.Ry += w.xi[k] * L.dRy[k];
      }
    }
  } else {
    w.x = -dt * y;
    Kmat(vm, w, w.x, w.K1);
    mass(vm, w, w.qn, w.M1);
    Dmat(vm, w, w.qn, y, w.D1);
    lagrangian_hessian(vm, w, w.qn, y, keep.tensors);  // the tensors residual_hessians reads
    block_transpose_times(vm.groups, w.K1, w.D1, w.Sq);  // dR/deta+
    w.Sq -= dt * w.Hk;
  }
  if (!keep.M0) mass(vm, w, q, w.M0);
  if (!keep.D0) Dmat(vm, w, q, v, w.D0);
  block_transpose_times(vm.groups, w.K0, w.D0, w.P2);
  if (Sq_zero) {
    J.leftCols(nv) = -w.P2;
  } else {
    times_block(vm.groups, w.Sq, w.A, w.P1);
    J.leftCols(nv) = w.P1 - w.P2;
  }
  if (!keep_v) {
    w.tmp.noalias() = w.M0 * v;
    dKT(vm, w, w.omega, w.K0, w.tmp, w.Kt);
  }
  block_transpose_times(vm.groups, w.K0, w.M0, w.P2);
  if (Sq_zero) {
    J.middleCols(nv, nv) = -w.P2;
  } else {
    times_block(vm.groups, w.Sq, w.Jv, w.P1);
    J.middleCols(nv, nv) = dt * w.P1 - w.P2;
  }
  J.middleCols(nv, nv) -= dt * w.Kt;
  if (!keep.lin) velocity_jacobian(vm, w, w.K1, w.D1, y, w.Ry);
  J.rightCols(nv) = w.Ry;
}

}  // namespace var
}  // namespace dyn
}  // namespace geoddp
