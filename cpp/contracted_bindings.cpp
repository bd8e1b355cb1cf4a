// Python bindings of the factored second-order terms and the contracted backward pass
// (contracted.hpp). Called from the module definition: bind_contracted(m).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>

#include "contracted.hpp"
#include "pin_model.hpp"

namespace py = pybind11;

namespace geoddp {

typedef py::array_t<double, py::array::c_style | py::array::forcecast> Arr;
typedef py::array_t<double> Out;

static void need(const Arr& a, std::initializer_list<long> shape, const char* name) {
  bool ok = a.ndim() == (py::ssize_t)shape.size();
  int i = 0;
  for (long s : shape) {
    if (ok && a.shape(i) != s) ok = false;
    ++i;
  }
  if (!ok) throw py::value_error(std::string(name) + ": wrong shape");
}

static void need_out(const Out& a, std::initializer_list<long> shape, const char* name) {
  if (!(a.flags() & py::array::c_style) || !a.writeable())
    throw py::value_error(std::string(name) + ": expected a writeable C-contiguous float64 array");
  bool ok = a.ndim() == (py::ssize_t)shape.size();
  int i = 0;
  for (long s : shape) {
    if (ok && a.shape(i) != s) ok = false;
    ++i;
  }
  if (!ok) throw py::value_error(std::string(name) + ": wrong shape");
}

void bind_contracted(py::module_& m) {
  using dyn::SecondOrderTerms;
  py::class_<SecondOrderTerms, std::shared_ptr<SecondOrderTerms>>(
      m, "SecondOrderTerms",
      "The second-order terms of a multibody expansion in factored form (dynamics.hpp), contracted with\n"
      "V_x' on demand instead of forming Theta, Gamma, Xi.",
      // local to this module: a second build of _core in the same process (benchmarks/speed_vs_main.py
      // loads another checkout's as geoddp_ref._core) would otherwise fail to register it again
      py::module_local())
      .def_readonly("N", &SecondOrderTerms::N)
      .def_readonly("nv", &SecondOrderTerms::nv)
      .def_readonly("m", &SecondOrderTerms::m)
      .def(
          "contract",
          [](const SecondOrderTerms& t, int k, const Arr& Vx) {
            if (k < 0 || k >= t.N) throw py::index_error("k: expected 0 <= k < N");
            need(Vx, {2 * t.nv}, "Vx");
            ctr::RowMat S;
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
        if (integrator != 0 && integrator != 1) throw py::value_error("integrator: expected 0 (euler) or 1 (semi_implicit)");
        const int mm = (int)H.shape(1), N = (int)U.shape(0), nv = model.nv, n = 2 * nv;
        need(Q, {N + 1, model.nq}, "Q");
        need(V, {N + 1, nv}, "V");
        need(U, {N, mm}, "U");
        dyn::Setup s{&model, H.data(), mm, dt, (dyn::Integrator)integrator};
        Arr Phi({N, n, n}), B({N, n, mm});
        auto terms = std::make_shared<SecondOrderTerms>();
        {
          py::gil_scoped_release nogil;
          dyn::expansion_contracted(s, Q.data(), V.data(), U.data(), N, threads, Phi.mutable_data(), B.mutable_data(),
                                    *terms);
        }
        return py::make_tuple(Phi, B, terms);
      },
      py::arg("model"), py::arg("actuation"), py::arg("dt"), py::arg("integrator"), py::arg("Q"), py::arg("V"),
      py::arg("U"), py::arg("threads") = 0,
      "Phi (N, n, n), B (N, n, m) (bitwise those of expansion(order=1)) and the SecondOrderTerms.");

  m.def(
      "backward_pass_contracted",
      [](const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx, const Arr& lux, const Arr& luu,
         const Arr& Vx_final, const Arr& Vxx_final, const SecondOrderTerms& t, double reg, Out k_ff, Out K_fb,
         Out quu_eig) {
        if (Phi.ndim() != 3 || B.ndim() != 3) throw py::value_error("Phi, B: expected (H, n, n), (H, n, m)");
        const long H = Phi.shape(0), n = Phi.shape(1), mm = B.shape(2);
        if (H != t.N || n != 2 * t.nv || mm != t.m) throw py::value_error("terms: sizes differ from Phi, B");
        need(Phi, {H, n, n}, "Phi");
        need(B, {H, n, mm}, "B");
        need(lx, {H, n}, "lx");
        need(lu, {H, mm}, "lu");
        need(lxx, {H, n, n}, "lxx");
        need(lux, {H, mm, n}, "lux");
        need(luu, {H, mm, mm}, "luu");
        need(Vx_final, {n}, "Vx_final");
        need(Vxx_final, {n, n}, "Vxx_final");
        need_out(k_ff, {H, mm}, "k_ff");
        need_out(K_fb, {H, mm, n}, "K_fb");
        need_out(quu_eig, {H}, "quu_eig");
        double d1 = 0.0, d2 = 0.0;
        int failed;
        {
          py::gil_scoped_release nogil;
          failed = ctr::backward_pass_contracted((int)H, (int)n, (int)mm, Phi.data(), B.data(), lx.data(), lu.data(),
                                                 lxx.data(), lux.data(), luu.data(), Vx_final.data(),
                                                 Vxx_final.data(), t, reg, k_ff.mutable_data(), K_fb.mutable_data(),
                                                 quu_eig.mutable_data(), &d1, &d2);
        }
        return py::make_tuple(failed, d1, d2);
      },
      py::arg("Phi"), py::arg("B"), py::arg("lx"), py::arg("lu"), py::arg("lxx"), py::arg("lux"), py::arg("luu"),
      py::arg("Vx_final"), py::arg("Vxx_final"), py::arg("terms"), py::arg("reg"), py::arg("k_ff").noconvert(),
      py::arg("K_fb").noconvert(), py::arg("quu_eig").noconvert(),
      "backward_pass with the second-order terms contracted from `terms`: (failed node or -1, d1, d2).");
}

}  // namespace geoddp
