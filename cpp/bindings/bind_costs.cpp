// Bindings of the cost kernels (costs/costs.hpp): the SO(3)/SE(3) right Jacobians the Python side
// uses; for the tests, each cost term alone (arrays accumulated in place; geoddp's solves run them
// through cost_sum, bind_cost_sum.cpp) and the Jacobians' exact derivatives.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>

#include "bindings/bindings.hpp"
#include "costs/costs.hpp"
#include "bindings/pin_model.hpp"

namespace py = pybind11;

namespace geoddp
{

  void bind_costs(py::module_ & m, py::module_ & t)
  {
    using namespace costs;
    t.def(
      "cost_frame_term",
      [](
        py::handle model, int frame_id, int kind, const ConstRowRef & Q, const ConstRowRef & refs,
        const ConstRowRef & W, bool gauss_newton, bool derivatives, VecRef l, RowRef lx, RowRef lxx) {
        const pinocchio::Model & mdl = model_from_python(model);
        if (kind < 0 || kind > 3)
          throw std::invalid_argument("kind: expected 0 (placement), 1 (rotation), 2 (translation) or 3 (chordal rotation)");
        if (frame_id < 0)
          throw std::invalid_argument("frame_id: expected a frame index");
        py::gil_scoped_release release;
        pinocchio::Data data(mdl);
        frame_term(
          mdl, data, (pinocchio::FrameIndex)frame_id, static_cast<FrameResidual>(kind), Q, refs, W, gauss_newton,
          derivatives, l, lx, lxx);
      },
      py::arg("model"), py::arg("frame_id"), py::arg("kind"), py::arg("Q"), py::arg("refs"), py::arg("W"),
      py::arg("gauss_newton"), py::arg("derivatives"), py::arg("l"), py::arg("lx"), py::arg("lxx"),
      "Add 1/2 r^T W r of a frame residual (kind 0 placement log6, 1 rotation log3, 2 translation; 3: the chordal\n"
      "rotation cost 1/2 tr[(I - E)^T W (I - E)], E = R_ref^T R_f) and,\n"
      "with derivatives, its gradient and exact (0)-Hessian into l (N,), lx (N, 2 nv), lxx (N, 4 nv^2).\n"
      "Q (N, nq); refs (K, 16 | 9 | 3) row-major, K = 1 or N; W (nr, nr). float64, C-contiguous.");
    t.def(
      "cost_state_regularisation",
      [](
        py::handle model, const ConstRowRef & Q, const ConstRowRef & V, const ConstRowRef & q_ref,
        const ConstRowRef & v_ref, const ConstRowRef & W, bool gauss_newton, bool derivatives, VecRef l,
        RowRef lx, RowRef lxx) {
        const pinocchio::Model & mdl = model_from_python(model);
        py::gil_scoped_release release;
        state_regularisation(mdl, Q, V, q_ref, v_ref, W, gauss_newton, derivatives, l, lx, lxx);
      },
      py::arg("model"), py::arg("Q"), py::arg("V"), py::arg("q_ref"), py::arg("v_ref"), py::arg("W"),
      py::arg("gauss_newton"), py::arg("derivatives"), py::arg("l"), py::arg("lx"), py::arg("lxx"),
      "Add 1/2 r^T W r, r = (difference(q_ref, q), v - v_ref), and its derivatives (exact Hessian).\n"
      "Q (N, nq), V (N, nv), q_ref (K, nq), v_ref (K', nv), W (2 nv, 2 nv); outputs as cost_frame_term.");
    t.def(
      "cost_control_regularisation",
      [](
        const ConstRowRef & U, const ConstRowRef & u_ref, const ConstRowRef & W, bool derivatives, VecRef l,
        RowRef lu, RowRef luu) {
        py::gil_scoped_release release;
        control_regularisation(U, u_ref, W, derivatives, l, lu, luu);
      },
      py::arg("U"), py::arg("u_ref"), py::arg("W"), py::arg("derivatives"), py::arg("l"), py::arg("lu"),
      py::arg("luu"),
      "Add 1/2 (u - u_ref)^T W (u - u_ref) into l (N,), lu (N, m), luu (N, m^2): U (N, m), u_ref (K, m).");
    m.def(
      "so3_right_jacobian", [](const Eigen::Vector3d & x) { return so3_right_jacobian(x); }, py::arg("x"),
      "Jr(x) (3, 3) of SO(3), exact to round-off (Taylor branches near 0).");
    m.def(
      "so3_right_jacobian_inv", [](const Eigen::Vector3d & x) { return so3_right_jacobian_inv(x); },
      py::arg("x"), "Jr(x)^-1 (3, 3) of SO(3).");
    m.def(
      "se3_right_jacobian", [](const Vector6 & x) { return se3_right_jacobian(x); }, py::arg("x"),
      "Jr(x) (6, 6) of SE(3), x = [linear; angular].");
    m.def(
      "se3_right_jacobian_inv", [](const Vector6 & x) { return se3_right_jacobian_inv(x); }, py::arg("x"),
      "Jr(x)^-1 (6, 6) of SE(3).");
    m.def(
      "so3_jr_derivative", [](const Eigen::Vector3d & x) { return so3_jr_derivative(x); }, py::arg("x"),
      "D (27,) = row-major (3, 3, 3), D[p, a, b] = d Jr(x)[p, a] / d x_b, SO(3), exact.");
    m.def(
      "se3_jr_derivative", [](const Vector6 & x) { return se3_jr_derivative(x); }, py::arg("x"),
      "D (216,) = row-major (6, 6, 6), D[p, a, b] = d Jr(x)[p, a] / d x_b, SE(3), exact.");
  }
} // namespace geoddp
