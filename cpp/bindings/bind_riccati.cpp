// Bindings of the backward passes over formed tensors (riccati/riccati.hpp): the unconstrained and
// box-constrained passes and the cost gradient's costate recursion; for the tests, one box QP.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <vector>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "riccati/riccati.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_shape;
using bind::empty;

void bind_riccati(py::module_& m, py::module_& t) {
  m.def(
      "backward_pass",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const Arr& Theta, const Arr& Gamma, const Arr& Xi,
         bool second_order, double reg, py::array_t<double> k_ff, py::array_t<double> K_fb,
         py::array_t<double> quu_eig) -> py::tuple {
        const auto z = geoddp::bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        const long H = z.H, n = z.n, mm = z.m;
        if (second_order) {
          check_shape(Theta, {H, n, n, n}, "Theta");
          check_shape(Gamma, {H, n, n, mm}, "Gamma");
          check_shape(Xi, {H, n, mm, mm}, "Xi");
        }
        geoddp::bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = geoddp::ric::backward_pass((int)H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(),
                                              lxx.data(), lux.data(), luu.data(), Vx_final.data(), Vxx_final.data(),
                                              second_order ? Theta.data() : nullptr, second_order ? Gamma.data() : nullptr,
                                              second_order ? Xi.data() : nullptr, second_order, reg,
                                              k_ff.mutable_data(), K_fb.mutable_data(), quu_eig.mutable_data(), &d1, &d2);
        }
        return py::make_tuple(failed, d1, d2);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("Theta"), py::arg("Gamma"), py::arg("Xi"),
      py::arg("second_order"), py::arg("reg"), py::arg("k_ff").noconvert(), py::arg("K_fb").noconvert(),
      py::arg("quu_eig").noconvert(),
      "Backward Riccati pass (geoddp.kernels.backward_pass): gains into k_ff (H, m), K_fb (H, m, n), "
      "quu_eig (H,); returns (failed node or -1, d1, d2).");
  m.def(
      "gradient",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lx_final, py::array_t<double> out) {
        const auto z = geoddp::bind::check_first_order_inputs(Phi, B, lx, lu);
        const long H = z.H, n = z.n, mm = z.m;
        check_shape(lx_final, {n}, "lx_final");
        geoddp::bind::check_output(out, {H, mm}, "out");
        py::gil_scoped_release nogil;
        geoddp::ric::gradient((int)H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(), lx_final.data(),
                              out.mutable_data());
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lx_final"), py::arg("out").noconvert(),
      "dJ/du_k = l_u^k + B_k^T psi^{k+1}, psi^k = l_x^k + Phi_k^T psi^{k+1}, psi^H = l_x^H (Lemma lemm:psi), "
      "into out (H, m).");

  m.def(
      "backward_pass_box",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const Arr& Theta, const Arr& Gamma, const Arr& Xi,
         bool second_order, double reg, const Arr& u_bar, const Arr& lower, const Arr& upper,
         py::array_t<double> k_ff, py::array_t<double> K_fb, py::array_t<double> quu_eig,
         py::array_t<signed char> active, py::array_t<double> Vx0, py::array_t<double> Vxx0) -> py::tuple {
        const auto z = geoddp::bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        const long H = z.H, n = z.n, mm = z.m;
        if (second_order) {
          check_shape(Theta, {H, n, n, n}, "Theta");
          check_shape(Gamma, {H, n, n, mm}, "Gamma");
          check_shape(Xi, {H, n, mm, mm}, "Xi");
        }
        geoddp::bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        geoddp::bind::check_box_arrays(u_bar, lower, upper, active, Vx0, Vxx0, z);
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = geoddp::ric::backward_pass_box(
              (int)H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(), lxx.data(), lux.data(), luu.data(),
              Vx_final.data(), Vxx_final.data(), second_order ? Theta.data() : nullptr,
              second_order ? Gamma.data() : nullptr, second_order ? Xi.data() : nullptr, second_order, reg,
              u_bar.data(), lower.data(), upper.data(), k_ff.mutable_data(), K_fb.mutable_data(),
              quu_eig.mutable_data(), active.mutable_data(), Vx0.mutable_data(), Vxx0.mutable_data(), &d1, &d2);
        }
        return py::make_tuple(failed, d1, d2);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("Theta"), py::arg("Gamma"), py::arg("Xi"),
      py::arg("second_order"), py::arg("reg"), py::arg("u_bar"), py::arg("lower"), py::arg("upper"),
      py::arg("k_ff").noconvert(), py::arg("K_fb").noconvert(), py::arg("quu_eig").noconvert(),
      py::arg("active").noconvert(), py::arg("Vx0").noconvert(), py::arg("Vxx0").noconvert(),
      "Box-constrained backward pass (control limits; see cpp/riccati/riccati.hpp): controls u = u_bar - k - K zeta kept in "
      "[lower, upper] (H, m); k_ff (H, m) is read as the warm start and overwritten; writes K_fb (H, m, n), "
      "quu_eig (H,), active (H, m) int8 (-1 lower, +1 upper, 0 free), Vx0 (n,), Vxx0 (n, n) (value function at "
      "node 0); returns (failed node or -1, d1, d2).");

  t.def(
      "box_qp",
      [](const Arr& Hq, const Arr& q, const Arr& lo, const Arr& hi, const Arr& x0) -> py::tuple {
        if (q.ndim() != 1) throw py::value_error("q: expected (m,)");
        const long mm = q.shape(0);
        check_shape(Hq, {mm, mm}, "H");
        check_shape(lo, {mm}, "lower");
        check_shape(hi, {mm}, "upper");
        check_shape(x0, {mm}, "x0");
        Arr x = empty({mm});
        std::copy(x0.data(), x0.data() + mm, x.mutable_data());
        py::array_t<signed char> cl(std::vector<py::ssize_t>{mm});
        const int it = geoddp::ric::box_qp((int)mm, Hq.data(), q.data(), lo.data(), hi.data(), x.mutable_data(),
                                           cl.mutable_data());
        return py::make_tuple(x, cl, it);
      },
      py::arg("H"), py::arg("q"), py::arg("lower"), py::arg("upper"), py::arg("x0"),
      "min 1/2 x^T H x - q^T x over lower <= x <= upper by projected Newton from x0: returns (x (m,), clamped (m,) "
      "int8: -1 lower, +1 upper, 0 free, iterations or -1 if H is not positive definite on a free set).");
}

}  // namespace geoddp
