// Bindings of the multibody trajectory kernels (dynamics/trajectory.hpp): rollouts and expansions
// for the four integrators; for the tests, the velocity updates' derivatives and the second-order
// switches.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <vector>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "bindings/pin_model.hpp"
#include "dynamics/euler.hpp"
#include "dynamics/trajectory.hpp"
#include "dynamics/variational.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_shape;
using bind::empty;
using dyn::Setup;

namespace {

Setup make_setup(const pinocchio::Model& model, const Arr& H, double dt, int integrator) {
  check_shape(H, {model.nv, -1}, "actuation");
  if (integrator < 0 || integrator > 3)
    throw py::value_error("integrator: expected 0 (euler), 1 (semi_implicit), 2 (rk4) or 3 (variational)");
  return Setup{&model, H.data(), (int)H.shape(1), dt, (geoddp::dyn::Integrator)integrator};
}

}  // namespace

void bind_dynamics(py::module_& m, py::module_& t) {
  m.attr("EULER") = 0;
  m.attr("SEMI_IMPLICIT") = 1;
  m.attr("RK4") = 2;
  m.attr("VARIATIONAL") = 3;
  // the variational step's Newton iteration did not converge; the message is |v| at the step
  // (geoddp.models.multibody re-raises geoddp.variational.StepDidNotConverge naming dt)
  py::register_exception<geoddp::dyn::StepNotConverged>(m, "StepDidNotConverge", PyExc_ArithmeticError);

  m.def(
      "rollout",
      [](py::handle pm, const Arr& H, double dt, int integrator, const Arr& q0, const Arr& v0, const Arr& U) {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        Setup s = make_setup(model, H, dt, integrator);
        check_shape(q0, {model.nq}, "q0");
        check_shape(v0, {model.nv}, "v0");
        check_shape(U, {-1, s.m}, "U");
        const int N = (int)U.shape(0);
        Arr Q = empty({N + 1, model.nq}), V = empty({N + 1, model.nv});
        {
          py::gil_scoped_release nogil;
          geoddp::dyn::rollout(s, q0.data(), v0.data(), U.data(), N, Q.mutable_data(), V.mutable_data());
        }
        return py::make_tuple(Q, V);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("integrator"), py::arg("q0"), py::arg("v0"),
      py::arg("U"),
      "Open-loop rollout: q0 (nq,), v0 (nv,), U (N, m) -> Q (N+1, nq), V (N+1, nv).");

  m.def(
      "rollout_closed_loop",
      [](py::handle pm, const Arr& H, double dt, int integrator, const Arr& q0, const Arr& v0, const Arr& Qbar,
         const Arr& Vbar, const Arr& Ubar, const Arr& kff, const Arr& K, double gamma, py::array_t<double> Qout,
         py::array_t<double> Vout, py::array_t<double> Uout, py::object lower, py::object upper) {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        Setup s = make_setup(model, H, dt, integrator);
        const int N = (int)Ubar.shape(0), nq = model.nq, nv = model.nv;
        check_shape(q0, {nq}, "q0");
        check_shape(v0, {nv}, "v0");
        check_shape(Qbar, {N + 1, nq}, "Q_bar");
        check_shape(Vbar, {N + 1, nv}, "V_bar");
        check_shape(Ubar, {N, s.m}, "u_bar");
        check_shape(kff, {N, s.m}, "k");
        check_shape(K, {N, s.m, 2 * nv}, "K");
        for (auto* o : {&Qout, &Vout, &Uout})
          if (!(o->flags() & py::array::c_style) || !o->writeable()) throw py::value_error("outputs: expected writeable C-contiguous float64 arrays");
        if (Qout.ndim() != 2 || Qout.shape(0) != N + 1 || Qout.shape(1) != nq) throw py::value_error("Q_out: wrong shape");
        if (Vout.ndim() != 2 || Vout.shape(0) != N + 1 || Vout.shape(1) != nv) throw py::value_error("V_out: wrong shape");
        if (Uout.ndim() != 2 || Uout.shape(0) != N || Uout.shape(1) != s.m) throw py::value_error("u_out: wrong shape");
        if (lower.is_none() != upper.is_none()) throw py::value_error("lower, upper: give both or neither");
        Arr lo, hi;
        if (!lower.is_none()) {
          lo = lower.cast<Arr>();
          hi = upper.cast<Arr>();
          check_shape(lo, {N, s.m}, "lower");
          check_shape(hi, {N, s.m}, "upper");
        }
        const double* lop = lower.is_none() ? nullptr : lo.data();
        const double* hip = lower.is_none() ? nullptr : hi.data();
        bool ok;
        {
          py::gil_scoped_release nogil;
          ok = geoddp::dyn::rollout_closed_loop(s, q0.data(), v0.data(), Qbar.data(), Vbar.data(), Ubar.data(),
                                                kff.data(), K.data(), gamma, N, Qout.mutable_data(),
                                                Vout.mutable_data(), Uout.mutable_data(), lop, hip);
        }
        return ok;
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("integrator"), py::arg("q0"), py::arg("v0"),
      py::arg("Q_bar"), py::arg("V_bar"), py::arg("u_bar"), py::arg("k"), py::arg("K"), py::arg("gamma"),
      py::arg("Q_out").noconvert(), py::arg("V_out").noconvert(), py::arg("u_out").noconvert(),
      py::arg("lower") = py::none(), py::arg("upper") = py::none(),
      "Forward pass u = u_bar - gamma k - K zeta into Q_out (N+1, nq), V_out (N+1, nv), u_out (N, m); "
      "with lower, upper (N, m) u is clamped into the box after the feedback law. "
      "False if a state became non-finite.");

  m.def(
      "expansion",
      [](py::handle pm, const Arr& H, double dt, int integrator, const Arr& Q, const Arr& V, const Arr& U, int order,
         int threads) -> py::tuple {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        Setup s = make_setup(model, H, dt, integrator);
        const int N = (int)U.shape(0), nv = model.nv, n = 2 * nv, mm = s.m;
        check_shape(Q, {N + 1, model.nq}, "Q");
        check_shape(V, {N + 1, nv}, "V");
        check_shape(U, {N, mm}, "U");
        Arr Phi = empty({N, n, n}), B = empty({N, n, mm});
        Arr Th = order >= 2 ? empty({N, n, n, n}) : empty({0});
        Arr Ga = order >= 2 ? empty({N, n, n, mm}) : empty({0});
        Arr Xi = order >= 2 ? empty({N, n, mm, mm}) : empty({0});
        {
          py::gil_scoped_release nogil;
          geoddp::dyn::expansion(s, Q.data(), V.data(), U.data(), N, order, threads, Phi.mutable_data(),
                                 B.mutable_data(), Th.mutable_data(), Ga.mutable_data(), Xi.mutable_data());
        }
        if (order < 2) return py::make_tuple(Phi, B, py::none(), py::none(), py::none());
        return py::make_tuple(Phi, B, Th, Ga, Xi);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("integrator"), py::arg("Q"), py::arg("V"),
      py::arg("U"), py::arg("order") = 1, py::arg("threads") = 0,
      "Phi (N, n, n), B (N, n, m), and for order 2 Theta (N, n, n, n), Gamma (N, n, n, m), Xi (N, n, m, m).");

  t.def(
      "velocity_derivatives",
      [](py::handle pm, const Arr& H, double dt, const Arr& Q, const Arr& V, const Arr& U, int order, int threads) -> py::tuple {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        Setup s = make_setup(model, H, dt, 0);
        const int N = (int)U.shape(0), nv = model.nv, nz = 2 * nv + s.m;
        check_shape(Q, {N, model.nq}, "Q");
        check_shape(V, {N, nv}, "V");
        check_shape(U, {N, s.m}, "U");
        Arr F1 = empty({N, nv, nz});
        Arr F2 = order >= 2 ? empty({N, nv, nz, nz}) : empty({0});
        {
          py::gil_scoped_release nogil;
          geoddp::dyn::velocity_derivatives(s, Q.data(), V.data(), U.data(), N, order, threads, F1.mutable_data(),
                                            order >= 2 ? F2.mutable_data() : nullptr);
        }
        if (order < 2) return py::make_tuple(F1, py::none());
        return py::make_tuple(F1, F2);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("Q"), py::arg("V"), py::arg("U"),
      py::arg("order") = 1, py::arg("threads") = 0,
      "Derivatives of v+ = v + dt aba(q, v, H u) at N nodes: F1 (N, nv, nz), F2 (N, nv, nz, nz) or None.");

  t.def(
      "variational_velocity_derivatives",
      [](py::handle pm, const Arr& H, double dt, const Arr& Q, const Arr& V, const Arr& Vnext, int order,
         int threads) -> py::tuple {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        Setup s = make_setup(model, H, dt, 3);
        const int N = (int)Q.shape(0), nv = model.nv, nz = 2 * nv + s.m;
        check_shape(Q, {N, model.nq}, "Q");
        check_shape(V, {N, nv}, "V");
        check_shape(Vnext, {N, nv}, "V_next");
        Arr F1 = empty({N, nv, nz});
        Arr F2 = order >= 2 ? empty({N, nv, nz, nz}) : empty({0});
        {
          py::gil_scoped_release nogil;
          const geoddp::dyn::VariationalModel vm(model, H.data(), s.m, dt);
          geoddp::dyn::variational_velocity_derivatives(vm, Q.data(), V.data(), Vnext.data(), N, order, threads,
                                                        F1.mutable_data(), order >= 2 ? F2.mutable_data() : nullptr);
        }
        if (order < 2) return py::make_tuple(F1, py::none());
        return py::make_tuple(F1, F2);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("Q"), py::arg("V"), py::arg("V_next"),
      py::arg("order") = 1, py::arg("threads") = 0,
      "Derivatives of the variational Euler step's v+ (solved: V_next) at N nodes by implicit differentiation: "
      "F1 (N, nv, nz), F2 (N, nv, nz, nz) or None (the tests' oracle: tests/oracle_variational.py, VariationalEuler.velocity_derivatives).");

  m.def(
      "rnea_second_order",
      [](py::handle pm, const Arr& q, const Arr& v, const Arr& a, bool one_body) {
        // Pinocchio's second-order RNEA tensors, or the one-body shortcut's (the contact dynamics' exact second order reads them; the tests compare the two)
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        check_shape(q, {model.nq}, "q");
        check_shape(v, {model.nv}, "v");
        check_shape(a, {model.nv}, "a");
        const py::ssize_t nv = model.nv;
        // Pinocchio's column-major (i, j, k) is numpy's Fortran order
        std::vector<py::ssize_t> shape{nv, nv, nv}, strides{8, 8 * nv, 8 * nv * nv};
        py::array_t<double> Iqq(shape, strides), Ivv(shape, strides), Iqv(shape, strides), dM(shape, strides);
        geoddp::dyn::rnea_second_order(model, q.data(), v.data(), a.data(), one_body, Iqq.mutable_data(),
                                       Ivv.mutable_data(), Iqv.mutable_data(), dM.mutable_data());
        return py::make_tuple(Iqq, Ivv, Iqv, dM);  // std::invalid_argument (ValueError) for a model it does not fit
      },
      py::arg("model"), py::arg("q"), py::arg("v"), py::arg("a"), py::arg("one_body"),
      "(d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq), each (nv, nv, nv) indexed (i, j, k) as Pinocchio's;\n"
      "with one_body, from the one-body shortcut the expansions use (cpp/rigid_body/one_body.hpp).");
  t.def("set_rnea_hessian_recursion", &geoddp::dyn::set_rnea_hessian_recursion, py::arg("on"),
        "Whether the contracted pass takes RNEA's second order from the recursion (True, the default) or from\n"
        "Pinocchio's tensors stored per node (False): for tests and benchmarks; the two agree to round-off.");
  t.def("rnea_hessian_recursion", &geoddp::dyn::rnea_hessian_recursion,
        "Whether the contracted pass takes RNEA's second order from the recursion (cpp/rigid_body/rnea_hessian.hpp).");
  t.def("one_body_applies", [](py::handle pm) { return geoddp::dyn::one_body_applies(geoddp::model_from_python(pm)); },
        py::arg("model"), "Whether the expansions take RNEA's second-order tensors from the one-body shortcut.");
}

}  // namespace geoddp
