// For the tests: the rigid-body recursions (rigid_body/kinetic_hessian.hpp, rigid_body/rnea_hessian.hpp)
// called alone, in the testing submodule.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <vector>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "bindings/pin_model.hpp"
#include "lie/joint_groups.hpp"
#include "rigid_body/kinetic_hessian.hpp"
#include "rigid_body/rnea_hessian.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_shape;

namespace {

// The kinetic-energy recursions' bindings (tests): q (nq) and y (nv) checked, the model's joints
// checked (std::invalid_argument, i.e. ValueError, naming one the core does not take), then
// fill(model, data, work, q, y) builds what the binding returns.
template <typename Fill>
py::object kinetic_call(py::handle pm, const Arr& q, const Arr& y, Fill&& fill) {
  const pinocchio::Model& model = geoddp::model_from_python(pm);
  check_shape(q, {model.nq}, "q");
  check_shape(y, {model.nv}, "y");
  geoddp::joint_groups(model);
  pinocchio::Data data(model);
  geoddp::dyn::KineticHessianWork w(model);
  const Eigen::VectorXd qv = Eigen::Map<const Eigen::VectorXd>(q.data(), model.nq);
  const Eigen::VectorXd yv = Eigen::Map<const Eigen::VectorXd>(y.data(), model.nv);
  return fill(model, data, w, qv, yv);
}

// An (nv, nv) Eigen matrix as a new row-major numpy array (the kinetic bindings' matrix results).
py::object row_major_array(const Eigen::MatrixXd& X) {
  Arr out({(py::ssize_t)X.rows(), (py::ssize_t)X.cols()});
  Eigen::Map<Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(out.mutable_data(), X.rows(), X.cols()) = X;
  return py::object(out);
}

}  // namespace

void bind_rigid_body(py::module_& t) {
  t.def(
      "rnea_hessian",
      [](py::handle pm, const Arr& q, const Arr& v, const Arr& a, const Arr& mu) {
        // For the tests: RNEA's second derivatives contracted with mu by the recursion the
        // contracted pass runs (cpp/rigid_body/rnea_hessian.hpp)
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        check_shape(q, {model.nq}, "q");
        check_shape(v, {model.nv}, "v");
        check_shape(a, {model.nv}, "a");
        check_shape(mu, {model.nv}, "mu");
        geoddp::joint_groups(model);  // refuses, by name, a joint whose motion subspace moves
        const py::ssize_t nv = model.nv;
        // each (nv, nv) column-major, entry (j, l) at j + nv l: numpy's Fortran order
        std::vector<py::ssize_t> shape{nv, nv}, strides{8, 8 * nv};
        py::array_t<double> Hqq(shape, strides), Hvv(shape, strides), Hqv(shape, strides), Dm(shape, strides);
        {
          py::gil_scoped_release release;
          geoddp::dyn::RneaHessianWork w(model);
          geoddp::dyn::rnea_hessian(model, w, q.data(), v.data(), a.data(), mu.data(), Hqq.mutable_data(),
                                    Hvv.mutable_data(), Hqv.mutable_data(), Dm.mutable_data());
        }
        return py::make_tuple(Hqq, Hvv, Hqv, Dm);
      },
      py::arg("model"), py::arg("q"), py::arg("v"), py::arg("a"), py::arg("mu"),
      "(Hqq, Hvv, Hqv, Dm), each (nv, nv): sum_i mu_i X(i, j, l) for Pinocchio's second-order RNEA tensors\n"
      "X = d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq at (q, v, a), by the recursion of cpp/rigid_body/rnea_hessian.hpp.");
  t.def(
      "kinetic_gradient",
      [](py::handle pm, const Arr& q, const Arr& y) {
        return kinetic_call(pm, q, y, [](const auto& model, auto& data, auto& w, const auto& qv, const auto& yv) {
          Eigen::VectorXd g(model.nv);
          geoddp::dyn::kinetic_gradient(model, data, w, qv, yv, g);
          Arr out({(py::ssize_t)model.nv});
          Eigen::Map<Eigen::VectorXd>(out.mutable_data(), model.nv) = g;
          return py::object(out);
        });
      },
      py::arg("model"), py::arg("q"), py::arg("y"),
      "g (nv,) = 1/2 d/dq (y^T M(q) y) = 1/2 D(q, y)^T y, trivialised (cpp/rigid_body/kinetic_hessian.hpp); gravity plays no part.");
  t.def(
      "kinetic_hessian",
      [](py::handle pm, const Arr& q, const Arr& y) {
        return kinetic_call(pm, q, y, [](const auto& model, auto& data, auto& w, const auto& qv, const auto& yv) {
          Eigen::MatrixXd H(model.nv, model.nv);
          geoddp::dyn::kinetic_hessian(model, data, w, qv, yv, H);
          return row_major_array(H);
        });
      },
      py::arg("model"), py::arg("q"), py::arg("y"),
      "H (nv, nv) = 1/2 d2/dq2 (y^T M(q) y), trivialised: H[k, l] the gradient's k-th entry differenced along\n"
      "q exp(eps e_l) (cpp/rigid_body/kinetic_hessian.hpp); gravity plays no part.");
  t.def(
      "mass_velocity_derivative",
      [](py::handle pm, const Arr& q, const Arr& y) {
        return kinetic_call(pm, q, y, [](const auto& model, auto& data, auto& w, const auto& qv, const auto& yv) {
          Eigen::MatrixXd D(model.nv, model.nv);
          geoddp::dyn::mass_velocity_derivative(model, data, w, qv, yv, D);
          return row_major_array(D);
        });
      },
      py::arg("model"), py::arg("q"), py::arg("y"),
      "D (nv, nv) = d(M(q) y)/dq, trivialised as Pinocchio's dtau_dq at (q, 0, y) without gravity, by the\n"
      "spatial-vector recursion of cpp/rigid_body/kinetic_hessian.hpp; gravity plays no part.");
  t.def(
      "mass_tensors",
      [](py::handle pm, const Arr& q, const Arr& y) {
        return kinetic_call(pm, q, y, [](const auto& model, auto& data, auto& w, const auto& qv, const auto& yv) {
          const py::ssize_t nv = model.nv;
          // column-major (i, j, k) as Pinocchio's tensors: numpy's Fortran order
          std::vector<py::ssize_t> shape{nv, nv, nv}, strides{8, 8 * nv, 8 * nv * nv};
          py::array_t<double> dM(shape, strides), T(shape, strides);
          geoddp::dyn::mass_tensors(model, data, w, qv, yv, dM.mutable_data(), T.mutable_data());
          return py::object(py::make_tuple(dM, T));
        });
      },
      py::arg("model"), py::arg("q"), py::arg("y"),
      "(dM, T), each (nv, nv, nv) indexed (i, j, k) as Pinocchio's: dM[i, j, k] = dM(i, j)/dq_k (d2tau_dadq) and\n"
      "T[i, j, k] = d_k D(q, y)(i, j), D = d(M(q) y)/dq (d2tau_dqdq at (q, 0, y) without gravity), by the\n"
      "spatial-vector recursion of cpp/rigid_body/kinetic_hessian.hpp; gravity plays no part.");
}

}  // namespace geoddp
