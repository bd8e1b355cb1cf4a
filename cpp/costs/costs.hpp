// Compiled cost terms of geoddp's multibody path: values, gradients and exact (0)-Hessians over
// N nodes in one call. Twin of src/geoddp/multibody_costs.py (the Python oracle the tests compare
// against); the conventions, shapes and formulas are documented there and in costs/costs.cpp.
//
// Arrays are row-major (numpy's C order). Every kernel ADDS into its outputs (like the Python
// terms' ``accumulate``), so several terms can share one set of arrays:
//   l   (N,)          cost values
//   lx  (N, 2 nv)     gradient along the retraction (integrate(q, dq), v + dv)
//   lxx (N, (2 nv)^2) (0)-Hessian, row-major (2 nv, 2 nv) per node, exactly symmetric
// Per-node references are stacks of K = 1 (one reference for every node) or K = N rows.
// Kernels throw std::invalid_argument on inconsistent sizes (the Python layer validates first).
#pragma once

#include <Eigen/Core>
#include <pinocchio/multibody.hpp>

#include <string>
#include <vector>

#include "runtime/arrays.hpp"
#include "lie/joint_groups.hpp"

namespace geoddp
{
  namespace costs
  {
    using ConstRowRef = Eigen::Ref<const RowMat>;
    using RowRef = Eigen::Ref<RowMat>;
    using VecRef = Eigen::Ref<Eigen::VectorXd>;
    using Matrix3 = Eigen::Matrix3d;
    using Matrix6 = Eigen::Matrix<double, 6, 6>;
    using Vector6 = Eigen::Matrix<double, 6, 1>;

    // ------------------------------------------------------------------ Lie-group closed forms
    // Right Jacobians of SO(3) and SE(3) (twists [linear; angular]) and their inverses: the
    // closed forms of geoddp.kernels.so3_right_jacobian / se3_right_jacobian, with the same
    // Taylor branches (exact to round-off, where Pinocchio 4.1's Jlog6 loses up to 3e-5 in the
    // coupling block for small rotations). Jr itself is lie/right_jacobians.hpp's.
    Matrix3 so3_right_jacobian(const Eigen::Vector3d & x);
    Matrix3 so3_right_jacobian_inv(const Eigen::Vector3d & x);
    Matrix6 se3_right_jacobian(const Vector6 & x);
    Matrix6 se3_right_jacobian_inv(const Vector6 & x);

    // sum_p g_p dJr[p, a] / dx_b -> (d, d) matrix, d = 3 (SO(3)) or 6 (SE(3)); exact (lie/right_jacobians.hpp:
    // closed form on SO(3), dual numbers through the closed form of Jr on SE(3)).
    Matrix3 so3_jr_derivative_contracted(const Eigen::Vector3d & x, const Eigen::Vector3d & g);
    Matrix6 se3_jr_derivative_contracted(const Vector6 & x, const Vector6 & g);
    // The full tensor D[p][a][b] = dJr[p, a] / dx_b, row-major (d, d, d) flattened (tests).
    Eigen::VectorXd so3_jr_derivative(const Eigen::Vector3d & x);
    Eigen::VectorXd se3_jr_derivative(const Vector6 & x);

    // ------------------------------------------------------------------ argument checks
    // (std::invalid_argument, ValueError in Python)
    /// A stack of K per-node references serves N nodes: K = 1 or K = N.
    void check_stack(Eigen::Index K, Eigen::Index N, const char * name);
    /// l (N,) and, with derivatives, lx (N, nx) and lxx (N, nx * nx).
    void check_outputs(
      Eigen::Index N, Eigen::Index nx, bool derivatives, const VecRef & l, const RowRef & lx, const RowRef & lxx);
    /// Whether `data` was built for `model` (its joints and frames).
    inline bool data_fits(const pinocchio::Model & model, const pinocchio::Data & data)
    {
      return (int)data.joints.size() == model.njoints && data.oMf.size() == model.frames.size();
    }

    // ------------------------------------------------------------------ frame terms
    enum class FrameResidual
    {
      Placement,   // r = log6(M_ref^-1 oMf(q)) (6,), refs (K, 16): homogeneous 4x4, row-major
      Rotation,    // r = log3(R_ref^T R_f(q)) (3,), refs (K, 9): 3x3 row-major
      Translation,  // r = p_f(q) - p_ref (3,),      refs (K, 3)
      // not a residual: 1/2 tr[(I - E)^T W (I - E)], E = R_ref^T R_f(q) (the paper's chordal
      // attitude cost, eq. costR, on any frame), refs (K, 9) as Rotation, W (3, 3)
      RotationChordal
    };

    /// 1/2 r^T W r of a frame residual on N nodes: Q (N, nq), W (nr, nr) symmetric PSD. With
    /// derivatives=false only l is touched (lx, lxx may be empty). gauss_newton=true drops the residual's
    /// second-order part from lxx. data: a pinocchio::Data built for `model`, the caller's
    /// (bindings/bind_cost_sum.cpp keeps one per worker: building a Data costs more than a node's
    /// kinematics).
    void frame_term(
      const pinocchio::Model & model,
      pinocchio::Data & data,
      pinocchio::FrameIndex frame_id,
      FrameResidual kind,
      const ConstRowRef & Q,
      const ConstRowRef & refs,
      const ConstRowRef & W,
      bool gauss_newton,
      bool derivatives,
      VecRef l,
      RowRef lx,
      RowRef lxx);

    // ------------------------------------------------------------------ state and control

    /// 1/2 r^T W r with r = (difference(q_ref, q), v - v_ref) (2 nv,): Q (N, nq), V (N, nv),
    /// q_ref (K, nq), v_ref (K', nv), W (2 nv, 2 nv).
    void state_regularisation(
      const pinocchio::Model & model,
      const ConstRowRef & Q,
      const ConstRowRef & V,
      const ConstRowRef & q_ref,
      const ConstRowRef & v_ref,
      const ConstRowRef & W,
      bool gauss_newton,
      bool derivatives,
      VecRef l,
      RowRef lx,
      RowRef lxx);

    /// 1/2 (u - u_ref)^T W (u - u_ref): U (N, m), u_ref (K, m), W (m, m); lu (N, m), luu (N, m*m).
    void control_regularisation(
      const ConstRowRef & U,
      const ConstRowRef & u_ref,
      const ConstRowRef & W,
      bool derivatives,
      VecRef l,
      RowRef lu,
      RowRef luu);

  } // namespace costs
} // namespace geoddp
