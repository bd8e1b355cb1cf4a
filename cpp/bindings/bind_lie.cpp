// For the tests: the Lie-level closed forms (lie/right_jacobians.hpp, lie/joint_blocks.hpp)
// called alone, in the testing submodule.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "bindings/pin_model.hpp"
#include "lie/joint_blocks.hpp"
#include "lie/joint_groups.hpp"
#include "lie/right_jacobians.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_shape;
using bind::empty;

void bind_lie(py::module_& t) {
  t.def(
      "block_ad_jr",
      [](py::handle pm, const Arr& omega) {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        const int nv = model.nv;
        check_shape(omega, {nv}, "omega");
        const auto groups = geoddp::joint_groups(model);
        Arr A = empty({nv, nv}), J = empty({nv, nv}), D = empty({nv, nv, nv});
        geoddp::lie::block_ad_jr(groups, nv, omega.data(), A.mutable_data(), J.mutable_data(), D.mutable_data());
        return py::make_tuple(A, J, D);
      },
      py::arg("model"), py::arg("omega"),
      "Ad_exp(-omega) (nv, nv), Jr(omega) (nv, nv) and D (nv, nv, nv), D[i, j, l] = d Jr[i, j] / d omega_l.");

  t.def(
      "se3_djr_transpose_apply",
      [](const Arr& x, const Arr& s) {
        check_shape(x, {6}, "x");
        check_shape(s, {6}, "s");
        geoddp::lie::Mat6 N;
        geoddp::lie::se3_djr_transpose_apply(Eigen::Map<const Eigen::Matrix<double, 6, 1>>(x.data()),
                                             Eigen::Map<const Eigen::Matrix<double, 6, 1>>(s.data()), N);
        Arr out = empty({6, 6});
        Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(out.mutable_data()) = N;
        return out;
      },
      py::arg("x"), py::arg("s"),
      "N (6, 6), N[:, l] = (d Jr(x) / d x_l)^T s for an SE(3) twist x = [linear; angular] (the variational\n"
      "step's dK^T terms; cpp/lie/right_jacobians.hpp).");

  t.def(
      "jr_transpose_hessian",
      [](const Arr& x, const Arr& u) {
        const py::ssize_t n = x.ndim() == 1 ? x.shape(0) : -1;
        if (n != 3 && n != 6) throw py::value_error("x: expected shape (3,) (SO(3)) or (6,) (SE(3))");
        check_shape(u, {(long)n}, "u");
        Arr out = empty({n, n, n});
        double* E = out.mutable_data();
        if (n == 3) {
          const geoddp::lie::Vec3 xv = Eigen::Map<const geoddp::lie::Vec3>(x.data());
          double a, b, al, be;
          geoddp::lie::so3_coefficients(xv.norm(), a, b, al, be);
          geoddp::lie::Mat3 H[3];
          geoddp::lie::so3_jr_transpose_hessian(xv, Eigen::Map<const geoddp::lie::Vec3>(u.data()), b, al, be, H);
          for (int i = 0; i < 3; ++i)
            for (int l = 0; l < 3; ++l)
              for (int c = 0; c < 3; ++c) E[(i * 3 + l) * 3 + c] = H[c](i, l);
        } else {
          const Eigen::Matrix<double, 6, 1> xv = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(x.data());
          geoddp::lie::Mat6 H[6];
          geoddp::lie::se3_jr_transpose_hessian(xv, Eigen::Map<const Eigen::Matrix<double, 6, 1>>(u.data()),
                                                geoddp::lie::se3_jr_coefficients(xv), H);
          for (int i = 0; i < 6; ++i)
            for (int l = 0; l < 6; ++l)
              for (int c = 0; c < 6; ++c) E[(i * 6 + l) * 6 + c] = H[c](i, l);
        }
        return out;
      },
      py::arg("x"), py::arg("u"),
      "E (n, n, n), E[i, a, b] = d^2 (Jr(x)^T u)_i / dx_a dx_b for an SO(3) (n = 3) or SE(3) (n = 6,\n"
      "[linear; angular]) tangent x: the second derivatives of the right Jacobian the variational\n"
      "step's exact second order contracts (cpp/lie/right_jacobians.hpp).");
}

}  // namespace geoddp
