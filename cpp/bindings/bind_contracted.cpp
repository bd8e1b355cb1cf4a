// Bindings of the factored second order: the terms (dynamics/second_order_terms.hpp), the expansion
// that makes them, and the backward passes that contract them with V_x' (riccati/contracted.hpp);
// for the tests, the regularisation ladder's search alone.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <memory>
#include <string>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "dynamics/trajectory.hpp"
#include "riccati/contracted.hpp"
#include "riccati/ladder.hpp"
#include "bindings/pin_model.hpp"

namespace py = pybind11;

namespace geoddp {

using bind::Arr;
using bind::Out;

void bind_contracted(py::module_& m, py::module_& t) {
  using dyn::SecondOrderTerms;
  py::class_<SecondOrderTerms, std::shared_ptr<SecondOrderTerms>>(
      m, "SecondOrderTerms",
      "The second-order terms of a multibody expansion in factored form (dynamics/second_order_terms.hpp), contracted with\n"
      "V_x' on demand instead of forming Theta, Gamma, Xi.",
      // local to this module: a second build of _core in the same process (benchmarks/speed_vs_main.py
      // loads another checkout's as geoddp_ref._core) would otherwise fail to register it again
      py::module_local(),
      // the terms hold a pointer to the model (the recursion reads it in the pass,
      // rigid_body/rnea_hessian.hpp): their Python object keeps the model's alive as its attribute _model
      py::dynamic_attr())
      .def_readonly("N", &SecondOrderTerms::N)
      .def_readonly("recursion", &SecondOrderTerms::recursion,
                    "Whether RNEA's second order is contracted in the pass by the recursion (cpp/rigid_body/rnea_hessian.hpp)\n"
                    "instead of read from Pinocchio's tensors stored per node.")
      .def_readonly("nv", &SecondOrderTerms::nv)
      .def_readonly("m", &SecondOrderTerms::m)
      .def(
          "contract",
          [](const SecondOrderTerms& t, int k, const Arr& Vx) {
            if (k < 0 || k >= t.N) throw py::index_error("k: expected 0 <= k < N");
            bind::check_shape(Vx, {2 * t.nv}, "Vx");
            RowMat S;
            ctr::contract(t, k, Vx.data(), S);
            Arr out({(py::ssize_t)S.rows(), (py::ssize_t)S.cols()});
            std::copy(S.data(), S.data() + S.size(), out.mutable_data());
            return out;
          },
          py::arg("k"), py::arg("Vx"),
          "S (nz, nz) = sum_i Vx_i [[Theta_i, Gamma_i], [Gamma_i^T, Xi_i]] at node k; Vx (2 nv,).");

  m.def(
      "expansion_contracted",
      [](py::handle pm, const Arr& H, double dt, int integrator, const Arr& Q, const Arr& V, const Arr& U,
         int threads) {
        const pinocchio::Model& model = model_from_python(pm);
        if (H.ndim() != 2 || H.shape(0) != model.nv) throw py::value_error("actuation: wrong shape");
        if (integrator != 0 && integrator != 1 && integrator != 3)
          throw py::value_error("integrator: expected 0 (euler), 1 (semi_implicit) or 3 (variational)");
        const int mm = (int)H.shape(1), N = (int)U.shape(0), nv = model.nv, n = 2 * nv;
        bind::check_shape(Q, {N + 1, model.nq}, "Q");
        bind::check_shape(V, {N + 1, nv}, "V");
        bind::check_shape(U, {N, mm}, "U");
        dyn::Setup s{&model, H.data(), mm, dt, (dyn::Integrator)integrator};
        Arr Phi({N, n, n}), B({N, n, mm});
        auto terms = std::make_shared<SecondOrderTerms>();
        {
          py::gil_scoped_release nogil;
          dyn::expansion_contracted(s, Q.data(), V.data(), U.data(), N, threads, Phi.mutable_data(), B.mutable_data(),
                                    *terms);
        }
        py::object out = py::cast(terms);
        out.attr("_model") = pm;
        return py::make_tuple(Phi, B, out);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("integrator"), py::arg("Q"), py::arg("V"),
      py::arg("U"), py::arg("threads") = 0,
      "Phi (N, n, n), B (N, n, m) (bitwise those of expansion(order=1)) and the SecondOrderTerms.");

  m.def(
      "backward_pass_contracted",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const SecondOrderTerms& t, double reg, Out k_ff, Out K_fb,
         Out quu_eig, int workers) {
        const auto z = bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        if (z.H != t.N || z.n != 2 * t.nv || z.m != t.m) throw py::value_error("terms: sizes differ from Phi, B");
        bind::check_workers(workers);
        const long H = z.H, n = z.n, mm = z.m;
        bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = ctr::backward_pass_contracted((int)H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(),
                                                 lxx.data(), lux.data(), luu.data(), Vx_final.data(),
                                                 Vxx_final.data(), t, reg, workers, k_ff.mutable_data(),
                                                 K_fb.mutable_data(),
                                                 quu_eig.mutable_data(), &d1, &d2);
        }
        return py::make_tuple(failed, d1, d2);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("terms"), py::arg("reg"), py::arg("k_ff").noconvert(),
      py::arg("K_fb").noconvert(), py::arg("quu_eig").noconvert(), py::arg("workers") = 1,
      "backward_pass with the second-order terms contracted from `terms`: (failed node or -1, d1, d2).\n"
      "workers: 1, 2 (each node's contraction on the core's second worker) or 0 (whichever has been faster\n"
      "here for passes of this shape); bitwise the same results.");

  m.def(
      "backward_pass_box_contracted",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const SecondOrderTerms& terms, double reg,
         const Arr& u_bar, const Arr& lower, const Arr& upper, py::array_t<double> k_ff, py::array_t<double> K_fb,
         py::array_t<double> quu_eig, py::array_t<signed char> active, py::array_t<double> Vx0,
         py::array_t<double> Vxx0, int workers) -> py::tuple {
        const auto z = bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        const long n = z.n, mm = z.m;
        if (terms.N != z.H || 2 * terms.nv != n || terms.m != mm) throw py::value_error("terms: wrong sizes");
        bind::check_workers(workers);
        bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        bind::check_box_arrays(u_bar, lower, upper, active, Vx0, Vxx0, z);
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = ctr::box_pass_contracted(
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
      "regularised_contracted",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const SecondOrderTerms& t, double lam, double reg_increase,
         double reg_min, double reg_max, bool speculate, Out k_ff, Out K_fb, Out quu_eig, Out spare_k, Out spare_K,
         Out spare_eig) {
        const auto z = bind::check_pass_inputs(Phi, B, lx, lu, lxx, lux, luu, Vx_final, Vxx_final);
        if (z.H != t.N || z.n != 2 * t.nv || z.m != t.m) throw py::value_error("terms: sizes differ from Phi, B");
        // the ladder must end: a finite lam >= 0, a factor > 1, a floor > 0, a finite ceiling
        if (!(reg_increase > 1.0)) throw py::value_error("reg_increase: expected a factor > 1");
        if (!(std::isfinite(lam) && lam >= 0.0)) throw py::value_error("lam: expected a finite number >= 0");
        if (!(std::isfinite(reg_min) && reg_min > 0.0)) throw py::value_error("reg_min: expected a finite number > 0");
        if (!std::isfinite(reg_max)) throw py::value_error("reg_max: expected a finite number");
        bind::check_gain_outputs(k_ff, K_fb, quu_eig, z);
        bind::check_gain_outputs(spare_k, spare_K, spare_eig, z);
        double d1 = 0.0, d2 = 0.0;
        int failed, restarts;
        {
          py::gil_scoped_release nogil;
          failed = ctr::regularised_contracted((int)z.H, (int)z.n, (int)z.m, Phi.data(), B.data(), lx.data(),
                                               lu.data(), lxx.data(), lux.data(), luu.data(), Vx_final.data(),
                                               Vxx_final.data(), t, reg_increase, reg_min, reg_max, speculate,
                                               k_ff.mutable_data(), K_fb.mutable_data(), quu_eig.mutable_data(),
                                               spare_k.mutable_data(), spare_K.mutable_data(),
                                               spare_eig.mutable_data(), &lam, &d1, &d2, &restarts);
        }
        return py::make_tuple(lam, failed, d1, d2, restarts);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("terms"), py::arg("lam"), py::arg("reg_increase"),
      py::arg("reg_min"), py::arg("reg_max"), py::arg("speculate"), py::arg("k_ff").noconvert(),
      py::arg("K_fb").noconvert(), py::arg("quu_eig").noconvert(), py::arg("spare_k").noconvert(),
      py::arg("spare_K").noconvert(), py::arg("spare_eig").noconvert(),
      "geoddp.solver.backward.regularised_backward's ladder search around backward_pass_contracted in one\n"
      "call (speculate: two rungs a round side by side; spare_* the second pass's buffers):\n"
      "(lambda, failed node of the last pass kept or -1, d1, d2, rungs climbed).");

  t.def(
      "ladder_search",
      [](int top, bool two, const py::sequence& factorises) {
        if (top < 1 || (int)py::len(factorises) != top) throw py::value_error("factorises: expected top >= 1 entries");
        ctr::LadderSearch s(top, two);
        py::list rounds;
        int probe[2];
        while (const int count = s.probes(probe)) {
          py::tuple round(count);
          bool ok[2];
          for (int i = 0; i < count; ++i) {
            round[i] = probe[i];
            ok[i] = factorises[(size_t)probe[i]].cast<bool>();
          }
          rounds.append(round);
          s.record(probe, ok, count);
        }
        return py::make_tuple(rounds, s.hi, s.found);
      },
      py::arg("top"), py::arg("two"), py::arg("factorises"),
      "The C++ ladder search (regularised_contracted's) against a table of outcomes, for tests:\n"
      "factorises[j] whether rung j's pass factorises (j < top; rung 0 must fail). Returns (rounds, hi, found).");
}

}  // namespace geoddp
