// geoddp._core: the compiled multibody kernels (arrays in, arrays out).
//
// Names, shapes, dtypes: every array is float64, C-contiguous; see dynamics.hpp. Argument
// checking for users happens on the Python side (geoddp.models.compiled); the checks here only
// guard memory safety. The GIL is released while a kernel runs.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <pinocchio/config.hpp>

#include <string>

#include "binding_checks.hpp"
#include "contracted.hpp"
#include "dynamics.hpp"
#include "kinetic_hessian.hpp"
#include "rnea_hessian.hpp"
#include "lie.hpp"
#include "pin_model.hpp"
#include "pool.hpp"
#include "riccati.hpp"
#include "small_gemm.hpp"
#include "variational.hpp"

namespace geoddp {
void bind_costs(pybind11::module_& m);  // costs_bindings.cpp
void bind_contracted(pybind11::module_& m);  // contracted_bindings.cpp
void bind_cost_sum(pybind11::module_& m);  // cost_sum.cpp
void bind_tso3(pybind11::module_& m);  // tso3_bindings.cpp
}

namespace py = pybind11;
using geoddp::dyn::Setup;
using geoddp::bind::Arr;
using geoddp::bind::check_shape;

static Setup make_setup(const pinocchio::Model& model, const Arr& H, double dt, int integrator) {
  check_shape(H, {model.nv, -1}, "actuation");
  if (integrator < 0 || integrator > 3)
    throw py::value_error("integrator: expected 0 (euler), 1 (semi_implicit), 2 (rk4) or 3 (variational)");
  return Setup{&model, H.data(), (int)H.shape(1), dt, (geoddp::dyn::Integrator)integrator};
}

static Arr empty(std::vector<py::ssize_t> shape) { return Arr(shape); }

// The kinetic-energy recursions' bindings (tests): q (nq) and y (nv) checked, the model's joints
// checked (std::invalid_argument, i.e. ValueError, naming one the core does not take), then
// fill(model, data, work, q, y) builds what the binding returns.
template <typename Fill>
static py::object kinetic_call(py::handle pm, const Arr& q, const Arr& y, Fill&& fill) {
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
static py::object row_major_array(const Eigen::MatrixXd& X) {
  Arr out({(py::ssize_t)X.rows(), (py::ssize_t)X.cols()});
  Eigen::Map<Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(out.mutable_data(), X.rows(), X.cols()) = X;
  return py::object(out);
}

PYBIND11_MODULE(_core, m) {
  m.doc() = "geoddp's compiled kernels: the multibody core over Pinocchio, the satellite's TSO(3) closed forms, the backward passes (C++17)";
  // The extension must run with the pin it was compiled against (pinocchio::Model's layout).
  py::module_ pin = py::module_::import("pinocchio");
  const std::string runtime = py::str(pin.attr("__version__"));
  if (runtime != PINOCCHIO_VERSION)
    throw py::import_error("geoddp._core was built against pin " + std::string(PINOCCHIO_VERSION) +
                           " but pin " + runtime +
                           " is installed; rebuild it against that pin: pip install --no-build-isolation --force-reinstall --no-deps -e . "
                           "(after pip install scikit-build-core pybind11 cmeel-eigen cmake ninja)");
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;
  m.attr("EULER") = 0;
  m.attr("SEMI_IMPLICIT") = 1;
  m.attr("RK4") = 2;
  m.attr("VARIATIONAL") = 3;
  // the variational step's Newton iteration did not converge; the message is |v| at the step
  // (geoddp.models.multibody re-raises geoddp.variational.StepDidNotConverge naming dt)
  py::register_exception<geoddp::dyn::StepNotConverged>(m, "StepDidNotConverge", PyExc_ArithmeticError);

  m.def("default_threads", &geoddp::dyn::default_threads, "Worker threads used when threads <= 0.");
  m.def(
      "spin_microseconds", []() { return geoddp::spin_microseconds(); },
      "How long an idle worker of the pool polls for the next task before it sleeps (us; cpp/pool.hpp).");
  m.attr("SPIN_US_MAX") = geoddp::SPIN_US_MAX;
  m.def(
      "set_spin_microseconds",
      [](int us) {
        if (us < 0 || us > geoddp::SPIN_US_MAX)
          throw py::value_error("us: expected 0.." + std::to_string(geoddp::SPIN_US_MAX) + " microseconds");
        geoddp::set_spin_microseconds(us);
      },
      py::arg("us"), "Sets how long an idle worker of the pool polls before it sleeps (us, 0..SPIN_US_MAX).");
  m.def("gemm_isa", &geoddp::gemm::isa, "Which build of the Riccati products runs: 'avx2+fma', 'x86-64' or 'generic'.");
  m.def("has_avx2_fma", &geoddp::gemm::has_avx2_fma, "Whether the CPU runs the AVX2/FMA build of the products.");
  m.def(
      "gemm",
      [](int variant, bool trans_a, double alpha, const Arr& A, const Arr& B, bool accumulate, py::array C) {
        // For the tests: C = [C +] alpha op(A) B with one of the two builds (0 baseline, 1 AVX2/FMA)
        if (A.ndim() != 2 || B.ndim() != 2 || C.ndim() != 2) throw py::value_error("gemm: 2-d arrays expected");
        // C is written in place: refuse anything pybind11 would have to copy
        if (!C.dtype().is(py::dtype::of<double>()) || !(C.flags() & py::array::c_style) || !C.writeable())
          throw py::type_error("gemm: C must be a writeable C-contiguous float64 array");
        const int M = (int)(trans_a ? A.shape(1) : A.shape(0)), K = (int)(trans_a ? A.shape(0) : A.shape(1));
        const int N = (int)B.shape(1);
        if (B.shape(0) != K || C.shape(0) != M || C.shape(1) != N) throw py::value_error("gemm: shapes do not match");
        geoddp::gemm::gemm_variant(variant, trans_a, M, N, K, alpha, A.data(), (int)A.shape(1), B.data(), N,
                                   accumulate, static_cast<double*>(C.mutable_data()), N);
      },
      py::arg("variant"), py::arg("trans_a"), py::arg("alpha"), py::arg("A"), py::arg("B"), py::arg("accumulate"),
      py::arg("C"));

  m.def(
      "rnea_second_order",
      [](py::handle pm, const Arr& q, const Arr& v, const Arr& a, bool one_body) {
        // For the tests: Pinocchio's second-order RNEA tensors, or the one-body shortcut's
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
      "with one_body, from the one-body shortcut the expansions use (cpp/one_body.hpp).");
  m.def(
      "rnea_hessian",
      [](py::handle pm, const Arr& q, const Arr& v, const Arr& a, const Arr& mu) {
        // For the tests: RNEA's second derivatives contracted with mu by the recursion the
        // contracted pass runs (cpp/rnea_hessian.hpp)
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
      "X = d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq at (q, v, a), by the recursion of cpp/rnea_hessian.hpp.");
  m.def("set_rnea_hessian_recursion", &geoddp::dyn::set_rnea_hessian_recursion, py::arg("on"),
        "Whether the contracted pass takes RNEA's second order from the recursion (True, the default) or from\n"
        "Pinocchio's tensors stored per node (False): for tests and benchmarks; the two agree to round-off.");
  m.def("rnea_hessian_recursion", &geoddp::dyn::rnea_hessian_recursion,
        "Whether the contracted pass takes RNEA's second order from the recursion (cpp/rnea_hessian.hpp).");
  m.def("one_body_applies", [](py::handle pm) { return geoddp::dyn::one_body_applies(geoddp::model_from_python(pm)); },
        py::arg("model"), "Whether the expansions take RNEA's second-order tensors from the one-body shortcut.");
  m.def(
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
      "g (nv,) = 1/2 d/dq (y^T M(q) y) = 1/2 D(q, y)^T y, trivialised (cpp/kinetic_hessian.hpp); gravity plays no part.");
  m.def(
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
      "q exp(eps e_l) (cpp/kinetic_hessian.hpp); gravity plays no part.");
  m.def(
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
      "spatial-vector recursion of cpp/kinetic_hessian.hpp; gravity plays no part.");
  m.def(
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
      "spatial-vector recursion of cpp/kinetic_hessian.hpp; gravity plays no part.");

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

  m.def(
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

  m.def(
      "block_ad_jr",
      [](py::handle pm, const Arr& omega) {
        const pinocchio::Model& model = geoddp::model_from_python(pm);
        const int nv = model.nv;
        check_shape(omega, {nv}, "omega");
        const auto groups = geoddp::joint_groups(model);
        Arr A = empty({nv, nv}), J = empty({nv, nv}), D = empty({nv, nv, nv});
        geoddp::dyn::block_ad_jr(groups, nv, omega.data(), A.mutable_data(), J.mutable_data(), D.mutable_data());
        return py::make_tuple(A, J, D);
      },
      py::arg("model"), py::arg("omega"),
      "Ad_exp(-omega) (nv, nv), Jr(omega) (nv, nv) and D (nv, nv, nv), D[i, j, l] = d Jr[i, j] / d omega_l.");

  m.def(
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
      "step's dK^T terms; cpp/lie.hpp).");

  m.def(
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
      "step's exact second order contracts (cpp/lie.hpp).");

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
      "Box-constrained backward pass (issue 15; see cpp/riccati.hpp): controls u = u_bar - k - K zeta kept in "
      "[lower, upper] (H, m); k_ff (H, m) is read as the warm start and overwritten; writes K_fb (H, m, n), "
      "quu_eig (H,), active (H, m) int8 (-1 lower, +1 upper, 0 free), Vx0 (n,), Vxx0 (n, n) (value function at "
      "node 0); returns (failed node or -1, d1, d2).");

  m.def(
      "backward_pass_box_contracted",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const geoddp::dyn::SecondOrderTerms& terms, double reg,
         const Arr& u_bar, const Arr& lower, const Arr& upper, py::array_t<double> k_ff, py::array_t<double> K_fb,
         py::array_t<double> quu_eig, py::array_t<signed char> active, py::array_t<double> Vx0,
         py::array_t<double> Vxx0, int workers) -> py::tuple {
        const auto z = geoddp::bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        const long n = z.n, mm = z.m;
        if (terms.N != z.H || 2 * terms.nv != n || terms.m != mm) throw py::value_error("terms: wrong sizes");
        geoddp::bind::check_workers(workers);
        geoddp::bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        geoddp::bind::check_box_arrays(u_bar, lower, upper, active, Vx0, Vxx0, z);
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = geoddp::ctr::box_pass_contracted(
              (int)z.H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(), lxx.data(), lux.data(),
              luu.data(), Vx_final.data(), Vxx_final.data(), terms, reg, u_bar.data(), lower.data(), upper.data(),
              workers, k_ff.mutable_data(), K_fb.mutable_data(), quu_eig.mutable_data(), active.mutable_data(),
              Vx0.mutable_data(), Vxx0.mutable_data(), &d1, &d2);
        }
        return py::make_tuple(failed, d1, d2);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("terms"), py::arg("reg"), py::arg("u_bar"),
      py::arg("lower"), py::arg("upper"), py::arg("k_ff").noconvert(), py::arg("K_fb").noconvert(),
      py::arg("quu_eig").noconvert(), py::arg("active").noconvert(), py::arg("Vx0").noconvert(),
      py::arg("Vxx0").noconvert(), py::arg("workers") = 1,
      "backward_pass_box with the second order factored (SecondOrderTerms, contracted with V_x' at each node, "
      "as backward_pass_contracted does, workers too); same outputs.");

  m.def(
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

  geoddp::bind_costs(m);  // cost terms: cost_frame_term, cost_state_regularisation, ...
  geoddp::bind_cost_sum(m);  // a whole cost sum in one call: cost_sum, CostWorkspace
  geoddp::bind_tso3(m);  // the satellite's TSO(3) closed forms: satellite_rollout, satellite_linearise, ...
  geoddp::bind_contracted(m);  // SecondOrderTerms, expansion_contracted, backward_pass_contracted
}
