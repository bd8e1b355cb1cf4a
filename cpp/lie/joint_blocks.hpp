// Block-diagonal reconstruction operators over a model's joint groups (the identity on vector and SO(2)
// joints; lie/right_jacobians.hpp's closed forms on SO(3), SE(3)): Jr, Jr^-1, Ad_exp(-theta), and dJr applied
// to a vector. Shared by the RKMK4 step and the variational Euler step (dynamics/). Twins of
// geoddp.lie.product.block_Ad_Jr, block_Jr_inv and second_order_tensors.
#pragma once

#include <pinocchio/spatial.hpp>

#include <Eigen/Core>
#include <vector>

#include "lie/joint_groups.hpp"
#include "lie/right_jacobians.hpp"

namespace geoddp {
namespace lie {

// Jr(theta), Jr(theta)^-1 and, if A != nullptr, Ad_exp(-theta): block-diagonal over the joint
// groups, the identity on vector and SO(2) joints (geoddp.lie.product.block_Ad_Jr / block_Jr_inv).
inline void block_jacobians(const std::vector<JointGroup>& groups, const Eigen::VectorXd& theta, Eigen::MatrixXd* A,
            Eigen::MatrixXd& Jr, Eigen::MatrixXd& Jinv) {
  if (A != nullptr) A->setIdentity();
  Jr.setIdentity();
  Jinv.setIdentity();
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3) {
      const Vec3 x = theta.segment<3>(o);
      if (A != nullptr) A->block<3, 3>(o, o) = pinocchio::exp3(x).transpose();
      const Mat3 J = so3_jr(x);
      Jr.block<3, 3>(o, o) = J;
      Jinv.block<3, 3>(o, o) = J.inverse();
    } else if (g.kind == SE3) {
      const Eigen::Matrix<double, 6, 1> x = theta.segment<6>(o);
      if (A != nullptr) A->block<6, 6>(o, o) = pinocchio::exp6(pinocchio::Motion(-x)).toActionMatrix();
      const Mat6 J = se3_jr(x);
      Jr.block<6, 6>(o, o) = J;
      Jinv.block<6, 6>(o, o) = se3_jr_inverse(J);
    }
  }
}

// Out(:, l) on each group's block = dJr(theta)/dtheta_l y, or with transpose its transpose times y
// (out of the groups: zero). The two uses:
// * Mdj = dJr(theta)[.] y: Mdj(a, l) = sum_b d Jr(a, b) / d theta_l y_b, so that
//   d(Jr^-1 v) = Jr^-1 (dv - Mdj dtheta) (rkmk4's module docstring);
// * N = dJr(theta)[.]^T s: N(i, l) = sum_j d Jr(j, i) / d theta_l s_j, so that
//   d/dtheta [Jr(theta)^-T p] = -Jr^-T N with s = Jr^-T p (variational.py's _dKT).
template <bool Transpose>
inline void djr_columns(const std::vector<JointGroup>& groups, const Eigen::VectorXd& theta, const Eigen::VectorXd& y,
                        Eigen::MatrixXd& out) {
  out.setZero();
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3) {
      if constexpr (Transpose) {
        const Vec3 x = theta.segment<3>(o);
        double a, b, al, be;
        so3_coefficients(x.norm(), a, b, al, be);
        Mat3 Nt;
        so3_djr_transpose_apply(x, y.segment<3>(o), a, b, al, be, Nt);
        out.block<3, 3>(o, o) = Nt;
      } else {
        Mat3 Dl[3];
        so3_djr(theta.segment<3>(o), Dl);
        for (int l = 0; l < 3; ++l) out.block<3, 1>(o, o + l) = Dl[l] * y.segment<3>(o);
      }
    } else if (g.kind == SE3) {
      if constexpr (Transpose) {
        Mat6 N;
        se3_djr_transpose_apply(theta.segment<6>(o), y.segment<6>(o), N);
        out.block<6, 6>(o, o) = N;
      } else {
        Mat6 Dl[6];
        se3_djr(theta.segment<6>(o), Dl);
        for (int l = 0; l < 6; ++l) out.block<6, 1>(o, o + l) = Dl[l] * y.segment<6>(o);
      }
    }
  }
}

// Products with a block-diagonal B over the joint groups (B the identity outside the SO(3) and
// SE(3) blocks, as block_jacobians() makes Jr, Jr^-1 and Ad_exp(-theta)): out = B^T X and
// out = X B, X of nv rows (columns). As dense nv x nv products they would run Eigen's general
// matrix product (packing and cache blocking for 9 x 9); on a fixed-base arm every block is the
// identity and the products are copies. out must not alias X.
template <typename XT, typename OutT>
inline void block_transpose_times(const std::vector<JointGroup>& groups, const Eigen::MatrixXd& B, const XT& X,
                                  OutT&& out) {
  out = X;
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3)
      out.template middleRows<3>(o).noalias() = B.block<3, 3>(o, o).transpose().lazyProduct(X.template middleRows<3>(o));
    else if (g.kind == SE3)
      out.template middleRows<6>(o).noalias() = B.block<6, 6>(o, o).transpose().lazyProduct(X.template middleRows<6>(o));
  }
}

template <typename XT, typename OutT>
inline void times_block(const std::vector<JointGroup>& groups, const XT& X, const Eigen::MatrixXd& B, OutT&& out) {
  out = X;
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3)
      out.template middleCols<3>(o).noalias() = X.template middleCols<3>(o).lazyProduct(B.block<3, 3>(o, o));
    else if (g.kind == SE3)
      out.template middleCols<6>(o).noalias() = X.template middleCols<6>(o).lazyProduct(B.block<6, 6>(o, o));
  }
}

inline void djr_apply(const std::vector<JointGroup>& groups, const Eigen::VectorXd& theta, const Eigen::VectorXd& y,
                      Eigen::MatrixXd& Mdj) {
  djr_columns<false>(groups, theta, y, Mdj);
}

inline void djr_transpose_apply(const std::vector<JointGroup>& groups, const Eigen::VectorXd& theta,
                                const Eigen::VectorXd& s, Eigen::MatrixXd& N) {
  djr_columns<true>(groups, theta, s, N);
}

// Reconstruction blocks at omega (nv): Ad_exp(-omega) and Jr(omega), each (nv, nv) row-major
// (geoddp.lie.product.block_Ad_Jr), and if D != nullptr D (nv, nv, nv) row-major with
// D[i, j, l] = d Jr[i, j] / d omega_l (geoddp.lie.product.second_order_tensors' D, exact): the
// expansions' layout (dynamics/expansion.cpp). Defined in lie/joint_blocks.cpp.
void block_ad_jr(const std::vector<JointGroup>& groups, int nv, const double* omega, double* A, double* Jr,
                 double* D);

}  // namespace lie
}  // namespace geoddp
