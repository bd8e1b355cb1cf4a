// Compiled cost terms: see costs.hpp for the API and src/geoddp/multibody_costs.py for the
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
//       + 1/2 dJr(x)[d] d + O(3)) (see geoddp.configuration.second_order_tensors),
//       log(exp(x) exp(eta)) = x + Ji eta - 1/2 Ji dJr(x)[Ji eta] (Ji eta) + O(3), Ji = Jr(x)^-1.
// Contracted with w = W r and g = Ji^T w:
//   placement:   sum_r g_r H_r - A^T D_g A,   A = Ji J (= J_r),  D_g[a, b] = sum_p g_p dJr[p, a]/dx_b
//   rotation:    the same on SO(3) with the angular rows of J and H
//   translation: sum_r w_r H^LWA_r (LOCAL_WORLD_ALIGNED rows: the world position's Hessian)
//   state:       -Ji^T D_g Ji per non-commutative joint (free flyer, spherical); 0 elsewhere.
// dJr is differentiated exactly by forward-mode dual numbers through the closed form of Jr
// (Taylor branches included), so every term stays finite at the identity and up to a rotation
// angle of pi (Jr and Jr^-1 are analytic for angles below 2 pi).
#include "costs.hpp"

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
      // ---------------------------------------------------------------- dual numbers
      // value + eps * derivative, eps^2 = 0: one directional derivative per evaluation.
      struct Dual
      {
        double v, d;
        Dual(double v_ = 0.0, double d_ = 0.0)
        : v(v_)
        , d(d_)
        {
        }
      };
      inline Dual operator+(Dual a, Dual b)
      {
        return {a.v + b.v, a.d + b.d};
      }
      inline Dual operator-(Dual a, Dual b)
      {
        return {a.v - b.v, a.d - b.d};
      }
      inline Dual operator-(Dual a)
      {
        return {-a.v, -a.d};
      }
      inline Dual operator*(Dual a, Dual b)
      {
        return {a.v * b.v, a.v * b.d + a.d * b.v};
      }
      inline Dual operator/(Dual a, Dual b)
      {
        return {a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)};
      }
      inline Dual sin(Dual a)
      {
        return {std::sin(a.v), std::cos(a.v) * a.d};
      }
      inline Dual cos(Dual a)
      {
        return {std::cos(a.v), -std::sin(a.v) * a.d};
      }
      inline Dual sqrt(Dual a)
      {
        const double s = std::sqrt(a.v);  // only called away from 0 (Taylor branches there)
        return {s, 0.5 * a.d / s};
      }
      inline double value(double x)
      {
        return x;
      }
      inline double value(Dual x)
      {
        return x.v;
      }
      using std::cos;
      using std::sin;
      using std::sqrt;

      template<typename S>
      using M3 = S[3][3];

      template<typename S>
      S poly(const double * c, int n, S t2)
      {
        S out = S(c[n - 1]);
        for (int i = n - 2; i >= 0; --i)
          out = out * t2 + S(c[i]);
        return out;
      }

      double factorial(int n)
      {
        double f = 1.0;
        for (int i = 2; i <= n; ++i)
          f *= i;
        return f;
      }

      // Series coefficients (in t^2), 8 terms each: the truncation error of the values and of
      // their derivatives is below 1e-17 inside the branches (t < 0.25, t < 0.6).
      struct Series
      {
        double a[8], b[8];            // Jr3 = I - a K + b K^2
        double jrinv[7];              // Jr3^-1 = I + K/2 + c K^2 (geoddp.kernels._JRINV_C)
        double q1[8], q2[8], q3[8];   // Barfoot's Q coefficients
        Series()
        {
          for (int k = 0; k < 8; ++k)
          {
            const double sg = (k % 2 == 0) ? 1.0 : -1.0;
            a[k] = sg / factorial(2 * k + 2);
            b[k] = sg / factorial(2 * k + 3);
            q1[k] = sg / factorial(2 * k + 3);
            q2[k] = sg / factorial(2 * (k + 2));                        // k + 2 = 2..9
            q3[k] = sg * (k + 1) / factorial(2 * (k + 2) + 1);
          }
          const double c[7] = {1.0 / 12,          1.0 / 720,
                               1.0 / 30240,       1.0 / 1209600,
                               1.0 / 47900160,    691.0 / 1307674368000.0,
                               1.0 / 74724249600.0};
          for (int k = 0; k < 7; ++k)
            jrinv[k] = c[k];
        }
      };
      const Series & series()
      {
        static const Series s;
        return s;
      }

      template<typename S>
      void hat(const S * x, M3<S> & K)
      {
        K[0][0] = S(0.0);
        K[1][1] = S(0.0);
        K[2][2] = S(0.0);
        K[0][1] = -x[2];
        K[0][2] = x[1];
        K[1][0] = x[2];
        K[1][2] = -x[0];
        K[2][0] = -x[1];
        K[2][1] = x[0];
      }

      template<typename S>
      void mul(const M3<S> & A, const M3<S> & B, M3<S> & C)
      {
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            C[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
      }

      // Jr(x) = I - a(t) hat(x) + b(t) hat(x)^2 of SO(3).
      template<typename S>
      void so3_jr(const S * x, M3<S> & J)
      {
        const Series & c = series();
        const S t2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
        S a, b;
        if (value(t2) < 0.0625)  // t < 0.25
        {
          a = poly(c.a, 8, t2);
          b = poly(c.b, 8, t2);
        }
        else
        {
          const S t = sqrt(t2);
          const S h = sin(S(0.5) * t) / (S(0.5) * t);
          a = S(0.5) * h * h;
          b = (t - sin(t)) / (t2 * t);
        }
        M3<S> K, K2;
        hat(x, K);
        mul(K, K, K2);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            J[i][j] = S(i == j ? 1.0 : 0.0) - a * K[i][j] + b * K2[i][j];
      }

      // Barfoot's Q(rho, phi), the coupling block of the SE(3) left Jacobian
      // (geoddp.kernels._se3_coupling).
      template<typename S>
      void se3_coupling(const S * r, const S * p, M3<S> & Q)
      {
        const Series & c = series();
        const S t2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        S c1, c2, c3;
        if (value(t2) < 0.36)  // t < 0.6
        {
          c1 = poly(c.q1, 8, t2);
          c2 = poly(c.q2, 8, t2);
          c3 = poly(c.q3, 8, t2);
        }
        else
        {
          const S t = sqrt(t2);
          const S s = sin(t), co = cos(t);
          c1 = (t - s) / (t2 * t);
          c2 = (t2 + S(2.0) * co - S(2.0)) / (S(2.0) * t2 * t2);
          c3 = (S(2.0) * t - S(3.0) * s + t * co) / (S(2.0) * t2 * t2 * t);
        }
        M3<S> P, R, PR, RP, PRP, PPR, RPP, PRPP, PPRP;
        hat(p, P);
        hat(r, R);
        mul(P, R, PR);
        mul(R, P, RP);
        mul(PR, P, PRP);
        mul(P, PR, PPR);
        mul(RP, P, RPP);
        mul(PRP, P, PRPP);
        mul(P, PRP, PPRP);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            Q[i][j] = S(0.5) * R[i][j] + c1 * (PR[i][j] + RP[i][j] + PRP[i][j])
                      + c2 * (PPR[i][j] + RPP[i][j] - S(3.0) * PRP[i][j])
                      + c3 * (PRPP[i][j] + PPRP[i][j]);
      }

      // Jr(x) of SE(3) = [[Jr3(w), Q(-v, -w)], [0, Jr3(w)]], x = [v; w].
      template<typename S>
      void se3_jr(const S * x, S (&J)[6][6])
      {
        M3<S> J3, Q;
        so3_jr(x + 3, J3);
        const S mv[3] = {-x[0], -x[1], -x[2]};
        const S mw[3] = {-x[3], -x[4], -x[5]};
        se3_coupling(mv, mw, Q);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
          {
            J[i][j] = J3[i][j];
            J[i + 3][j + 3] = J3[i][j];
            J[i][j + 3] = Q[i][j];
            J[i + 3][j] = S(0.0);
          }
      }

      Matrix3 coupling(const Eigen::Vector3d & r, const Eigen::Vector3d & p)
      {
        M3<double> Q;
        se3_coupling(r.data(), p.data(), Q);
        Matrix3 out;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            out(i, j) = Q[i][j];
        return out;
      }

      void check(bool ok, const std::string & what)
      {
        if (!ok)
          throw std::invalid_argument(what);
      }

      // Row of a stack of K = 1 or N references used by node k.
      inline Eigen::Index pick(Eigen::Index K, Eigen::Index k)
      {
        return K == 1 ? 0 : k;
      }

      void check_stack(Eigen::Index K, Eigen::Index N, const char * name)
      {
        check(
          K == 1 || K == N, std::string(name) + ": a per-node reference of " + std::to_string(K)
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

      // lxx_k(0:n, 0:n) += (S + S^T) / 2 for the node's row-major (nx, nx) block.
      template<typename Mat>
      void add_sym(RowRef & lxx, Eigen::Index k, Eigen::Index nx, Eigen::Index i0, const Mat & S)
      {
        Eigen::Map<RowMatrixXd> L(lxx.row(k).data(), nx, nx);
        const Eigen::Index n = S.rows();
        L.block(i0, i0, n, n) += 0.5 * (S + S.transpose());
      }
    } // namespace

    // ------------------------------------------------------------------ closed forms
    Matrix3 so3_right_jacobian(const Eigen::Vector3d & x)
    {
      M3<double> J;
      so3_jr(x.data(), J);
      Matrix3 out;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          out(i, j) = J[i][j];
      return out;
    }

    Matrix3 so3_right_jacobian_inv(const Eigen::Vector3d & x)
    {
      // geoddp.kernels.so3_right_jacobian(x, inverse=True)
      const double t = x.norm();
      double c;
      if (t < 0.25)
        c = poly(series().jrinv, 7, t * t);
      else
        c = 1.0 / (t * t) - std::cos(0.5 * t) / (2.0 * t * std::sin(0.5 * t));
      Matrix3 K;
      K << 0.0, -x[2], x[1], x[2], 0.0, -x[0], -x[1], x[0], 0.0;
      return Matrix3::Identity() + 0.5 * K + c * (K * K);
    }

    Matrix6 se3_right_jacobian(const Vector6 & x)
    {
      double J[6][6];
      se3_jr(x.data(), J);
      Matrix6 out;
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j)
          out(i, j) = J[i][j];
      return out;
    }

    Matrix6 se3_right_jacobian_inv(const Vector6 & x)
    {
      // [[K, -K Q K], [0, K]], K = Jr3(w)^-1, Q = Q(-v, -w) (geoddp.kernels.se3_right_jacobian)
      const Matrix3 K = so3_right_jacobian_inv(x.tail<3>());
      const Matrix3 Q = coupling(-x.head<3>(), -x.tail<3>());
      Matrix6 out = Matrix6::Zero();
      out.topLeftCorner<3, 3>() = K;
      out.bottomRightCorner<3, 3>() = K;
      out.topRightCorner<3, 3>() = -(K * Q * K);
      return out;
    }

    Matrix3 so3_jr_derivative_contracted(const Eigen::Vector3d & x, const Eigen::Vector3d & g)
    {
      Matrix3 out;
      for (int l = 0; l < 3; ++l)
      {
        Dual xd[3];
        for (int i = 0; i < 3; ++i)
          xd[i] = Dual(x[i], i == l ? 1.0 : 0.0);
        M3<Dual> J;
        so3_jr(xd, J);
        for (int a = 0; a < 3; ++a)
          out(a, l) = g[0] * J[0][a].d + g[1] * J[1][a].d + g[2] * J[2][a].d;
      }
      return out;
    }

    Matrix6 se3_jr_derivative_contracted(const Vector6 & x, const Vector6 & g)
    {
      Matrix6 out;
      for (int l = 0; l < 6; ++l)
      {
        Dual xd[6];
        for (int i = 0; i < 6; ++i)
          xd[i] = Dual(x[i], i == l ? 1.0 : 0.0);
        Dual J[6][6];
        se3_jr(xd, J);
        for (int a = 0; a < 6; ++a)
        {
          double s = 0.0;
          for (int p = 0; p < 6; ++p)
            s += g[p] * J[p][a].d;
          out(a, l) = s;
        }
      }
      return out;
    }

    Eigen::VectorXd so3_jr_derivative(const Eigen::Vector3d & x)
    {
      Eigen::VectorXd D(27);
      for (int p = 0; p < 3; ++p)
      {
        const Matrix3 Dp = so3_jr_derivative_contracted(x, Eigen::Vector3d::Unit(p));
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            D[(p * 3 + a) * 3 + b] = Dp(a, b);
      }
      return D;
    }

    Eigen::VectorXd se3_jr_derivative(const Vector6 & x)
    {
      Eigen::VectorXd D(216);
      for (int p = 0; p < 6; ++p)
      {
        const Matrix6 Dp = se3_jr_derivative_contracted(x, Vector6::Unit(p));
        for (int a = 0; a < 6; ++a)
          for (int b = 0; b < 6; ++b)
            D[(p * 6 + a) * 6 + b] = Dp(a, b);
      }
      return D;
    }

    // ------------------------------------------------------------------ frame terms
    void frame_term(
      const pinocchio::Model & model,
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
      const int nref = kind == FrameResidual::Placement ? 16 : (kind == FrameResidual::Rotation ? 9 : 3);
      check(frame_id < model.frames.size(), "frame_id: not a frame of the model");
      check(Q.cols() == model.nq, "Q: expected shape (N, nq)");
      check(refs.cols() == nref && refs.rows() >= 1, "refs: expected shape (K, " + std::to_string(nref) + ")");
      check_stack(refs.rows(), N, "refs");
      check(W.rows() == nr && W.cols() == nr, "W: expected shape (nr, nr)");
      check_outputs(N, nx, derivatives, l, lx, lxx);

      pinocchio::Data data(model);
      pinocchio::Data::Matrix6x J = pinocchio::Data::Matrix6x::Zero(6, nv);
      pinocchio::Data::Tensor3x H(6, nv, nv);
      Eigen::MatrixXd Jr(nr, nv);
      Eigen::VectorXd r(nr), w(nr), q(model.nq);
      Eigen::MatrixXd S(nv, nv);
      const Eigen::MatrixXd Wm = W;

      for (Eigen::Index k = 0; k < N; ++k)
      {
        q = Q.row(k).transpose();
        if (derivatives)
          pinocchio::computeJointJacobians(model, data, q);  // also the forward kinematics
        else
          pinocchio::forwardKinematics(model, data, q);
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
        else if (kind == FrameResidual::Rotation)
        {
          Matrix3 Rref;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              Rref(i, j) = ref[3 * i + j];
          const Matrix3 E =
            oMf.rotation() == Rref ? Matrix3::Identity() : Matrix3(Rref.transpose() * oMf.rotation());
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
        pinocchio::computeJointKinematicHessians(model, data);
        H.setZero();
        const pinocchio::ReferenceFrame rf =
          kind == FrameResidual::Translation ? pinocchio::LOCAL_WORLD_ALIGNED : pinocchio::LOCAL;
        pinocchio::getFrameKinematicHessian(model, data, frame_id, rf, H);
        // H is column-major (6, nv, nv): as a (6, nv * nv) matrix, g^T H holds S(i, k) at i + k nv
        Eigen::Map<const Eigen::MatrixXd> Hm(H.data(), 6, nv * nv);
        Vector6 g6 = Vector6::Zero();
        if (kind == FrameResidual::Placement)
          g6 = Ji6.transpose() * w;
        else if (kind == FrameResidual::Rotation)
          g6.tail<3>() = Ji3.transpose() * w;
        else
          g6.head<3>() = w;
        Eigen::Map<Eigen::RowVectorXd>(S.data(), nv * nv).noalias() = g6.transpose() * Hm;
        if (kind == FrameResidual::Placement)
          S.noalias() -= Jr.transpose() * se3_jr_derivative_contracted(r, g6) * Jr;
        else if (kind == FrameResidual::Rotation)
          S.noalias() -= Jr.transpose() * so3_jr_derivative_contracted(r, g6.tail<3>()) * Jr;
        add_sym(lxx, k, nx, 0, S);
      }
    }

    // ------------------------------------------------------------------ state and control
    std::vector<JointGroup> joint_groups(const pinocchio::Model & model)
    {
      std::vector<JointGroup> out;
      for (pinocchio::JointIndex j = 1; j < (pinocchio::JointIndex)model.njoints; ++j)
      {
        const auto & jm = model.joints[j];
        const std::string s = jm.shortname();
        int kind;
        if (
          s == "JointModelRX" || s == "JointModelRY" || s == "JointModelRZ" || s == "JointModelPX"
          || s == "JointModelPY" || s == "JointModelPZ" || s == "JointModelRevoluteUnaligned"
          || s == "JointModelPrismaticUnaligned" || s == "JointModelTranslation"
          || s == "JointModelSphericalZYX")
          kind = 0;
        else if (
          s == "JointModelRUBX" || s == "JointModelRUBY" || s == "JointModelRUBZ"
          || s == "JointModelRevoluteUnboundedUnaligned")
          kind = 1;
        else if (s == "JointModelSpherical")
          kind = 2;
        else if (s == "JointModelFreeFlyer")
          kind = 3;
        else
          throw std::invalid_argument(
            "joint '" + model.names[j] + "' of type " + s
            + " is not supported (supported: revolute, continuous, prismatic, spherical, free-flyer)");
        out.push_back({kind, jm.idx_q(), jm.idx_v(), jm.nv()});
      }
      return out;
    }

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

      Eigen::VectorXd q(model.nq), q0(model.nq), r(nx), w(nx), wq(nv);
      Eigen::MatrixXd JW(nv, nx), G(nv, nv);
      std::vector<Eigen::MatrixXd> Ji(curved.size());
      for (Eigen::Index k = 0; k < N; ++k)
      {
        q = Q.row(k).transpose();
        q0 = q_ref.row(pick(q_ref.rows(), k)).transpose();
        auto dq = r.head(nv);
        pinocchio::difference(model, q0, q, dq);
        for (const auto & g : groups)
          if (g.kind == 1)
          {
            // exact SO(2) entries (geoddp.configuration.difference: Pinocchio 4.1's SO(2) log
            // returns 0 for some angles below ~1e-8)
            const double c0 = q0[g.idx_q], s0 = q0[g.idx_q + 1], c1 = q[g.idx_q], s1 = q[g.idx_q + 1];
            dq[g.idx_v] = std::atan2(c0 * s1 - s0 * c1, c0 * c1 + s0 * s1);
          }
        r.tail(nv) = V.row(k).transpose() - v_ref.row(pick(v_ref.rows(), k)).transpose();
        w.noalias() = Wm.transpose() * r;  // r @ W, as the oracle
        l[k] += 0.5 * r.dot(w);
        if (!derivatives)
          continue;
        Eigen::Map<RowMatrixXd> L(lxx.row(k).data(), nx, nx);
        lx.row(k).tail(nv) += w.tail(nv).transpose();
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
        JW = Wm.topRows(nv);
        for (size_t c = 0; c < curved.size(); ++c)
        {
          const JointGroup & g = curved[c];
          wq.segment(g.idx_v, g.nv) = Ji[c].transpose() * w.segment(g.idx_v, g.nv);
          JW.middleRows(g.idx_v, g.nv) = Ji[c].transpose() * Wm.middleRows(g.idx_v, g.nv);
        }
        lx.row(k).head(nv) += wq.transpose();
        G = JW.leftCols(nv);
        for (size_t c = 0; c < curved.size(); ++c)
        {
          const JointGroup & g = curved[c];
          G.middleCols(g.idx_v, g.nv) = JW.middleCols(g.idx_v, g.nv) * Ji[c];
        }
        L.topLeftCorner(nv, nv) += 0.5 * (G + G.transpose());
        L.topRightCorner(nv, nv) += JW.rightCols(nv);
        L.bottomLeftCorner(nv, nv) += JW.rightCols(nv).transpose();
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
        Eigen::Map<RowMatrixXd>(luu.row(k).data(), m, m) += W;
      }
    }

  } // namespace costs
} // namespace geoddp
