// Compiled cost terms: see costs/costs.hpp for the API and src/geoddp/multibody_costs.py for the
// Python oracle these kernels reproduce.
//
// Exact second-order parts (no finite differences). For a residual cost l = 1/2 r^T W r along the
// retraction curve q(s) = integrate(q, s dq):
//   d2l/ds2 = (J_r dq)^T W (J_r dq) + (W r)^T r''(0),
// so l_xx = J_r^T W J_r + sym(sum_k (W r)_k Hess r_k). The second-order part is assembled from
//   (a) the frame's kinematic Hessian: oMf(q(s)) = oMf exp(s J dq + s^2/2 H(dq, dq) + O(s^3)),
//       with H(dq, dq) = (dJ_LOCAL/dq[dq]) dq (Pinocchio's getFrameKinematicHessian, LOCAL:
//       H(r, i, k) = d J_LOCAL(r, i) / d q_k along q exp(s e_k)); the Lie-bracket term of the
//       exponential is antisymmetric and drops out of the symmetric second derivative;
//   (b) the second-order term of the logarithm: from exp(x + d) = exp(x) exp(Jr(x) d
//       + 1/2 dJr(x)[d] d + O(3)) (see geoddp.lie.product.second_order_tensors),
//       log(exp(x) exp(eta)) = x + Ji eta - 1/2 Ji dJr(x)[Ji eta] (Ji eta) + O(3), Ji = Jr(x)^-1.
// Contracted with w = W r and g = Ji^T w:
//   placement:   sum_r g_r H_r - A^T D_g A,   A = Ji J (= J_r),  D_g[a, b] = sum_p g_p dJr[p, a]/dx_b
//   rotation:    the same on SO(3) with the angular rows of J and H
//   translation: sum_r w_r H^LWA_r (LOCAL_WORLD_ALIGNED rows: the world position's Hessian)
//   state:       -Ji^T D_g Ji per non-commutative joint (free flyer, spherical); 0 elsewhere.
// dJr is exact: closed form on SO(3), forward-mode dual numbers through the closed form of Jr on SE(3)
// (lie/right_jacobians.hpp, shared with the dynamics kernels; Taylor branches included), so every term stays
// finite at the identity and up to a rotation angle of pi (Jr, Jr^-1 analytic below 2 pi).
#include "costs/costs.hpp"

#include "lie/right_jacobians.hpp"

#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/kinematics-derivatives.hpp>
#include <pinocchio/algorithm/kinematics.hpp>
#include <pinocchio/spatial.hpp>

#include <cmath>
#include <stdexcept>

namespace geoddp
{
  namespace costs
  {
    namespace
    {
      // Series of c(t) in Jr3(x)^-1 = I + hat(x)/2 + c(t) hat(x)^2 (geoddp.lie.so3's _C).
      const double JRINV_C[7] = {1.0 / 12,        1.0 / 720,      1.0 / 30240,           1.0 / 1209600,
                                 1.0 / 47900160,  691.0 / 1307674368000.0, 1.0 / 74724249600.0};

      // const char*: the messages are literals, and a std::string per check and call would be a
      // heap allocation on the hot path (formatted messages are built only on failure)
      void check(bool ok, const char * what)
      {
        if (!ok)
          throw std::invalid_argument(what);
      }

      // Row of a stack of K = 1 or N references used by node k.
      inline Eigen::Index pick(Eigen::Index K, Eigen::Index k)
      {
        return K == 1 ? 0 : k;
      }

      // lxx_k(0:n, 0:n) += (S + S^T) / 2 for the node's row-major (nx, nx) block.
      template<typename Mat>
      void add_sym(RowRef & lxx, Eigen::Index k, Eigen::Index nx, Eigen::Index i0, const Mat & S)
      {
        Eigen::Map<RowMat> L(lxx.row(k).data(), nx, nx);
        const Eigen::Index n = S.rows();
        L.block(i0, i0, n, n) += 0.5 * (S + S.transpose());
      }
    } // namespace

    // Argument checks shared with bindings/bind_cost_sum.cpp (costs/costs.hpp).
    void check_stack(Eigen::Index K, Eigen::Index N, const char * name)
    {
      if (!(K == 1 || K == N))
        throw std::invalid_argument(
          std::string(name) + ": a per-node reference of " + std::to_string(K)
          + " nodes cannot be evaluated on " + std::to_string(N) + " nodes");
    }

    void check_outputs(
      Eigen::Index N, Eigen::Index nx, bool derivatives, const VecRef & l, const RowRef & lx,
      const RowRef & lxx)
    {
      check(l.size() == N, "l: expected N entries");
      if (derivatives)
      {
        check(lx.rows() == N && lx.cols() == nx, "lx: expected shape (N, nx)");
        check(lxx.rows() == N && lxx.cols() == nx * nx, "lxx: expected shape (N, nx * nx)");
      }
    }

    // ------------------------------------------------------------------ closed forms
    // Jr and dJr come from lie/right_jacobians.hpp (shared with the dynamics kernels); the inverses live here.
    Matrix3 so3_right_jacobian(const Eigen::Vector3d & x)
    {
      return lie::so3_jr(x);
    }

    Matrix3 so3_right_jacobian_inv(const Eigen::Vector3d & x)
    {
      // geoddp.kernels.so3_right_jacobian(x, inverse=True)
      const double t = x.norm();
      double c;
      if (t < 0.25)
        c = lie::poly(JRINV_C, 7, t * t);
      else
        c = 1.0 / (t * t) - std::cos(0.5 * t) / (2.0 * t * std::sin(0.5 * t));
      const Matrix3 K = lie::hat(x);
      return Matrix3::Identity() + 0.5 * K + c * (K * K);
    }

    Matrix6 se3_right_jacobian(const Vector6 & x)
    {
      return lie::se3_jr(x);
    }

    Matrix6 se3_right_jacobian_inv(const Vector6 & x)
    {
      // [[K, -K Q K], [0, K]], K = Jr3(w)^-1, Q = Q(-v, -w) (geoddp.kernels.se3_right_jacobian)
      const Matrix3 K = so3_right_jacobian_inv(x.tail<3>());
      double r[3], p[3];
      for (int i = 0; i < 3; ++i)
      {
        r[i] = -x[i];
        p[i] = -x[3 + i];
      }
      const lie::M3<double> Qm = lie::se3_coupling<double>(r, p);
      Matrix3 Q;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          Q(i, j) = Qm.m[i][j];
      Matrix6 out = Matrix6::Zero();
      out.topLeftCorner<3, 3>() = K;
      out.bottomRightCorner<3, 3>() = K;
      out.topRightCorner<3, 3>() = -(K * Q * K);
      return out;
    }

    Matrix3 so3_jr_derivative_contracted(const Eigen::Vector3d & x, const Eigen::Vector3d & g)
    {
      lie::Mat3 D[3];
      lie::so3_djr(x, D);
      Matrix3 out;
      for (int b = 0; b < 3; ++b)
        out.col(b) = D[b].transpose() * g;  // out(a, b) = sum_p g_p dJr(p, a) / dx_b
      return out;
    }

    Matrix6 se3_jr_derivative_contracted(const Vector6 & x, const Vector6 & g)
    {
      lie::Mat6 D[6];
      lie::se3_djr(x, D);
      Matrix6 out;
      for (int b = 0; b < 6; ++b)
        out.col(b) = D[b].transpose() * g;
      return out;
    }

    Eigen::VectorXd so3_jr_derivative(const Eigen::Vector3d & x)
    {
      lie::Mat3 D[3];
      lie::so3_djr(x, D);
      Eigen::VectorXd out(27);
      for (int p = 0; p < 3; ++p)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            out[(p * 3 + a) * 3 + b] = D[b](p, a);
      return out;
    }

    Eigen::VectorXd se3_jr_derivative(const Vector6 & x)
    {
      lie::Mat6 D[6];
      lie::se3_djr(x, D);
      Eigen::VectorXd out(216);
      for (int p = 0; p < 6; ++p)
        for (int a = 0; a < 6; ++a)
          for (int b = 0; b < 6; ++b)
            out[(p * 6 + a) * 6 + b] = D[b](p, a);
      return out;
    }

    // ------------------------------------------------------------------ frame terms
    // E = R_ref^T R_f, R_ref from a row-major 3 x 3 reference row; exactly I when R_f is R_ref
    // (R_ref^T R would leave round-off: the cost and its gradient are exactly 0 at the reference,
    // as the oracle's)
    template<typename Row>
    Matrix3 relative_rotation(const Row & ref, const Matrix3 & Rf)
    {
      Matrix3 Rref;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          Rref(i, j) = ref[3 * i + j];
      return Rf == Rref ? Matrix3(Matrix3::Identity()) : Matrix3(Rref.transpose() * Rf);
    }

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
      RowRef lxx)
    {
      const Eigen::Index N = Q.rows(), nv = model.nv, nx = 2 * model.nv;
      const int nr = kind == FrameResidual::Placement ? 6 : 3;
      const int nref = kind == FrameResidual::Placement ? 16 : (kind == FrameResidual::Translation ? 3 : 9);
      check(frame_id < model.frames.size(), "frame_id: not a frame of the model");
      check(data_fits(model, data), "data: expected a pinocchio::Data built for this model");
      check(Q.cols() == model.nq, "Q: expected shape (N, nq)");
      if (!(refs.cols() == nref && refs.rows() >= 1))
        throw std::invalid_argument("refs: expected shape (K, " + std::to_string(nref) + ")");
      check_stack(refs.rows(), N, "refs");
      check(W.rows() == nr && W.cols() == nr, "W: expected shape (nr, nr)");
      check_outputs(N, nx, derivatives, l, lx, lxx);

      pinocchio::Data::Matrix6x J = pinocchio::Data::Matrix6x::Zero(6, nv);
      pinocchio::Data::Tensor3x H(6, nv, nv);
      Eigen::MatrixXd Jr(nr, nv);
      Eigen::VectorXd r(nr), w(nr), q(model.nq);
      Eigen::MatrixXd S(nv, nv);
      const Eigen::MatrixXd Wm = W;
      // S = sum_p g6_p Hess_p: the frame's kinematic Hessian (Pinocchio's, in frame rf) contracted
      // with g6. H is column-major (6, nv, nv): as a (6, nv * nv) matrix, g6^T H holds S(i, k) at
      // i + k nv.
      const auto kinematic_hessian = [&](const Vector6 & g6, pinocchio::ReferenceFrame rf, Eigen::MatrixXd & out)
      {
        pinocchio::computeJointKinematicHessians(model, data);
        H.setZero();
        pinocchio::getFrameKinematicHessian(model, data, frame_id, rf, H);
        Eigen::Map<const Eigen::MatrixXd> Hm(H.data(), 6, nv * nv);
        Eigen::Map<Eigen::RowVectorXd>(out.data(), nv * nv).noalias() = g6.transpose() * Hm;
      };

      for (Eigen::Index k = 0; k < N; ++k)
      {
        q = Q.row(k).transpose();
        // through Eigen::Ref: the wheel's compiled instantiations (rigid_body/pinocchio_compiled.hpp)
        const Eigen::Ref<const Eigen::VectorXd> q_arg(q);
        if (derivatives)
          pinocchio::computeJointJacobians(model, data, q_arg);  // also the forward kinematics
        else
          pinocchio::forwardKinematics(model, data, q_arg);
        const pinocchio::SE3 & oMf = pinocchio::updateFramePlacement(model, data, frame_id);
        if (derivatives)
        {
          J.setZero();
          pinocchio::getFrameJacobian(model, data, frame_id, pinocchio::LOCAL, J);
        }
        const auto ref = refs.row(pick(refs.rows(), k));
        Matrix6 Ji6;
        Matrix3 Ji3;
        if (kind == FrameResidual::Placement)
        {
          Matrix3 Rref;
          Eigen::Vector3d pref;
          for (int i = 0; i < 3; ++i)
          {
            for (int j = 0; j < 3; ++j)
              Rref(i, j) = ref[4 * i + j];
            pref[i] = ref[4 * i + 3];
          }
          pinocchio::SE3 E;
          if (oMf.rotation() == Rref)
            // reference orientation reached exactly: R_ref^T R would leave round-off in r; the
            // identity makes the cost and its gradient exactly 0 at the reference (as the oracle)
            E = pinocchio::SE3(Matrix3::Identity(), Rref.transpose() * (oMf.translation() - pref));
          else
            E = pinocchio::SE3(Rref, pref).inverse() * oMf;
          r = pinocchio::log6(E).toVector();
          if (derivatives)
          {
            Ji6 = se3_right_jacobian_inv(r);
            Jr.noalias() = Ji6 * J;
          }
        }
        else if (kind == FrameResidual::RotationChordal)
        {
          // 1/2 tr[(I - E)^T W (I - E)] along R_f(q exp(dq)) = R_f exp(J_ang dq + O(dq^2)): in the
          // rotation's local coordinates theta the cost is const - tr(W E exp(theta)), with
          // gradient g = vee(W E - (W E)^T) (paper eq. gradF) and (0)-Hessian
          // tr(W E) I - sym(W E) (eq. hessF); the chain rule through the frame's Jacobian and
          // kinematic Hessian gives l_x = J^T g, l_xx = J^T Hth J + sum_p g_p Hess_p.
          // (W is 3 x 3 here: Wm is the weight of each column of I - E.)
          const Matrix3 E = relative_rotation(ref, oMf.rotation());
          const Matrix3 D = Matrix3::Identity() - E;
          l[k] += 0.5 * (D.transpose() * Wm * D).trace();
          if (!derivatives)
            continue;
          const Matrix3 WE = Wm * E;
          const Eigen::Vector3d g(WE(2, 1) - WE(1, 2), WE(0, 2) - WE(2, 0), WE(1, 0) - WE(0, 1));
          const auto Ja = J.bottomRows<3>();
          lx.row(k).head(nv) += (Ja.transpose() * g).transpose();
          Matrix3 Hth;
          if (gauss_newton)
          {
            // the Gauss-Newton form of the residual r = vec(I - E exp(theta)), weight W on each
            // column: dr/dtheta_a = -vec(E hat(e_a)), so Hth(a, b) = <E hat(e_a), W E hat(e_b)>
            // (positive semidefinite; no kinematic Hessian)
            Matrix3 A[3];
            for (int a = 0; a < 3; ++a)
              A[a] = E * lie::hat(Eigen::Vector3d::Unit(a));
            for (int a = 0; a < 3; ++a)
              for (int b = 0; b < 3; ++b)
                Hth(a, b) = A[a].cwiseProduct(Wm * A[b]).sum();
          }
          else
            Hth = WE.trace() * Matrix3::Identity() - 0.5 * (WE + WE.transpose());
          S.noalias() = Ja.transpose() * (Hth * Ja);
          add_sym(lxx, k, nx, 0, S);
          // exactly zero at the reference (g = 0): the kinematic Hessians only where g is not
          if (!gauss_newton && !g.isZero(0.0))
          {
            Vector6 g6 = Vector6::Zero();
            g6.tail<3>() = g;
            kinematic_hessian(g6, pinocchio::LOCAL, S);
            add_sym(lxx, k, nx, 0, S);
          }
          continue;
        }
        else if (kind == FrameResidual::Rotation)
        {
          const Matrix3 E = relative_rotation(ref, oMf.rotation());
          r = pinocchio::log3(E);
          if (derivatives)
          {
            Ji3 = so3_right_jacobian_inv(r);
            Jr.noalias() = Ji3 * J.bottomRows<3>();
          }
        }
        else
        {
          r = oMf.translation() - ref.transpose();
          if (derivatives)
            Jr.noalias() = oMf.rotation() * J.topRows<3>();
        }
        w.noalias() = Wm * r;
        l[k] += 0.5 * r.dot(w);
        if (!derivatives)
          continue;
        lx.row(k).head(nv) += (Jr.transpose() * w).transpose();
        S.noalias() = Jr.transpose() * (Wm * Jr);
        add_sym(lxx, k, nx, 0, S);
        // exactly zero at r = 0 (as the oracle): skip the kinematic Hessians there
        if (gauss_newton || w.isZero(0.0))
          continue;
        Vector6 g6 = Vector6::Zero();
        if (kind == FrameResidual::Placement)
          g6 = Ji6.transpose() * w;
        else if (kind == FrameResidual::Rotation)
          g6.tail<3>() = Ji3.transpose() * w;
        else
          g6.head<3>() = w;
        kinematic_hessian(
          g6, kind == FrameResidual::Translation ? pinocchio::LOCAL_WORLD_ALIGNED : pinocchio::LOCAL, S);
        if (kind == FrameResidual::Placement)
          S.noalias() -= Jr.transpose() * se3_jr_derivative_contracted(r, g6) * Jr;
        else if (kind == FrameResidual::Rotation)
          S.noalias() -= Jr.transpose() * so3_jr_derivative_contracted(r, g6.tail<3>()) * Jr;
        add_sym(lxx, k, nx, 0, S);
      }
    }

    // ------------------------------------------------------------------ state and control
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
      RowRef lxx)
    {
      const Eigen::Index N = Q.rows(), nv = model.nv, nx = 2 * model.nv;
      check(Q.cols() == model.nq, "Q: expected shape (N, nq)");
      check(V.rows() == N && V.cols() == nv, "V: expected shape (N, nv)");
      check(q_ref.cols() == model.nq && q_ref.rows() >= 1, "q_ref: expected shape (K, nq)");
      check(v_ref.cols() == nv && v_ref.rows() >= 1, "v_ref: expected shape (K, nv)");
      check_stack(q_ref.rows(), N, "q_ref");
      check_stack(v_ref.rows(), N, "v_ref");
      check(W.rows() == nx && W.cols() == nx, "W: expected shape (2 nv, 2 nv)");
      check_outputs(N, nx, derivatives, l, lx, lxx);
      const std::vector<JointGroup> groups = joint_groups(model);
      std::vector<JointGroup> curved;  // non-commutative joints: Jr != I
      for (const auto & g : groups)
        if (g.kind >= 2)
          curved.push_back(g);
      const Eigen::MatrixXd Wm = W;
      // no weight on dq (a velocity penalty): every dq term of the derivatives is exactly zero
      const bool weighs_q = !Wm.topRows(nv).isZero(0.0);
      // per-coordinate weights (the usual case): J^T W J touches only the curved blocks, and
      // every product with W is a scaling (the same values as the dense products, whose other
      // terms are exact zeros)
      const bool diagonal = Wm.isDiagonal(0.0);
      const Eigen::VectorXd d = Wm.diagonal();
      std::vector<char> on_curved(nv, 0);
      for (const auto & g : curved)
        for (int i = 0; i < g.nv; ++i)
          on_curved[g.idx_v + i] = 1;

      Eigen::VectorXd q(model.nq), q0(model.nq), r(nx), w(nx), wq(nv), dq_full(nv);
      Eigen::MatrixXd JW(nv, nx), G(nv, nv), JD, Gs;  // JD, Gs: a curved block's (diagonal path)
      std::vector<Eigen::MatrixXd> Ji(curved.size());
      for (Eigen::Index k = 0; k < N; ++k)
      {
        q = Q.row(k).transpose();
        q0 = q_ref.row(pick(q_ref.rows(), k)).transpose();
        auto dq = r.head(nv);
        // into a VectorXd: the types of the wheel's compiled instantiation (rigid_body/pinocchio_compiled.hpp)
        pinocchio::difference(model, q0, q, dq_full);
        dq = dq_full;
        for (const auto & g : groups)
          if (g.kind == 1)
          {
            // exact SO(2) entries (geoddp.lie.product.difference: Pinocchio 4.1's SO(2) log
            // returns 0 for some angles below ~1e-8)
            const double c0 = q0[g.idx_q], s0 = q0[g.idx_q + 1], c1 = q[g.idx_q], s1 = q[g.idx_q + 1];
            dq[g.idx_v] = std::atan2(c0 * s1 - s0 * c1, c0 * c1 + s0 * s1);
          }
        r.tail(nv) = V.row(k).transpose() - v_ref.row(pick(v_ref.rows(), k)).transpose();
        if (diagonal)
          w = d.cwiseProduct(r);
        else
          w.noalias() = Wm.transpose() * r;  // r @ W, as the oracle
        l[k] += 0.5 * r.dot(w);
        if (!derivatives)
          continue;
        Eigen::Map<RowMat> L(lxx.row(k).data(), nx, nx);
        lx.row(k).tail(nv) += w.tail(nv).transpose();
        if (diagonal)
          L.diagonal().tail(nv) += d.tail(nv);
        else
          L.bottomRightCorner(nv, nv) += Wm.bottomRightCorner(nv, nv);
        if (!weighs_q)
          continue;
        // J = d difference / d dq: block-diagonal, Jr^-1 of the joint's difference on the curved
        // joints and the identity elsewhere; products with J touch only the curved blocks.
        for (size_t c = 0; c < curved.size(); ++c)
        {
          const JointGroup & g = curved[c];
          if (g.kind == 2)
            Ji[c] = so3_right_jacobian_inv(dq.segment<3>(g.idx_v));
          else
            Ji[c] = se3_right_jacobian_inv(dq.segment<6>(g.idx_v));
        }
        wq = w.head(nv);
        for (size_t c = 0; c < curved.size(); ++c)
        {
          const JointGroup & g = curved[c];
          wq.segment(g.idx_v, g.nv) = Ji[c].transpose() * w.segment(g.idx_v, g.nv);
        }
        lx.row(k).head(nv) += wq.transpose();
        if (diagonal)
        {
          // L_qq += J^T diag(d_q) J (L_qv = 0): the diagonal off the curved blocks, and
          // Ji^T diag(d_s) Ji on each curved block s
          for (Eigen::Index i = 0; i < nv; ++i)
            if (!on_curved[i])
              L(i, i) += d[i];
          for (size_t c = 0; c < curved.size(); ++c)
          {
            const JointGroup & g = curved[c];
            JD.noalias() = Ji[c].transpose() * d.segment(g.idx_v, g.nv).asDiagonal();
            Gs.noalias() = JD * Ji[c];
            L.block(g.idx_v, g.idx_v, g.nv, g.nv) += 0.5 * (Gs + Gs.transpose());
          }
        }
        else
        {
          JW = Wm.topRows(nv);
          for (size_t c = 0; c < curved.size(); ++c)
          {
            const JointGroup & g = curved[c];
            JW.middleRows(g.idx_v, g.nv) = Ji[c].transpose() * Wm.middleRows(g.idx_v, g.nv);
          }
          G = JW.leftCols(nv);
          for (size_t c = 0; c < curved.size(); ++c)
          {
            const JointGroup & g = curved[c];
            G.middleCols(g.idx_v, g.nv) = JW.middleCols(g.idx_v, g.nv) * Ji[c];
          }
          L.topLeftCorner(nv, nv) += 0.5 * (G + G.transpose());
          L.topRightCorner(nv, nv) += JW.rightCols(nv);
          L.bottomLeftCorner(nv, nv) += JW.rightCols(nv).transpose();
        }
        if (gauss_newton || w.head(nv).isZero(0.0))
          continue;
        for (size_t c = 0; c < curved.size(); ++c)
        {
          const JointGroup & g = curved[c];
          const Eigen::VectorXd gv = wq.segment(g.idx_v, g.nv);  // Ji^T w_j
          Eigen::MatrixXd S;
          if (g.kind == 2)
            S = -(Ji[c].transpose() * so3_jr_derivative_contracted(dq.segment<3>(g.idx_v), gv) * Ji[c]);
          else
            S = -(Ji[c].transpose() * se3_jr_derivative_contracted(dq.segment<6>(g.idx_v), gv) * Ji[c]);
          L.block(g.idx_v, g.idx_v, g.nv, g.nv) += 0.5 * (S + S.transpose());
        }
      }
    }

    void control_regularisation(
      const ConstRowRef & U,
      const ConstRowRef & u_ref,
      const ConstRowRef & W,
      bool derivatives,
      VecRef l,
      RowRef lu,
      RowRef luu)
    {
      const Eigen::Index N = U.rows(), m = U.cols();
      check(u_ref.cols() == m && u_ref.rows() >= 1, "u_ref: expected shape (K, m)");
      check_stack(u_ref.rows(), N, "u_ref");
      check(W.rows() == m && W.cols() == m, "W: expected shape (m, m)");
      check_outputs(N, m, derivatives, l, lu, luu);
      const Eigen::MatrixXd Wm = W;
      Eigen::VectorXd e(m), We(m);
      for (Eigen::Index k = 0; k < N; ++k)
      {
        e = U.row(k).transpose() - u_ref.row(pick(u_ref.rows(), k)).transpose();
        We.noalias() = Wm.transpose() * e;  // e @ W, as the oracle
        l[k] += 0.5 * e.dot(We);
        if (!derivatives)
          continue;
        lu.row(k) += We.transpose();
        Eigen::Map<RowMat>(luu.row(k).data(), m, m) += W;
      }
    }

  } // namespace costs
} // namespace geoddp
