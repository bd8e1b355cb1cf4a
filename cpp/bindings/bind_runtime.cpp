// Bindings of the runtime (the worker pool, the node split) and of the Riccati products' build.
#include <pybind11/pybind11.h>

#include <string>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "linalg/small_gemm.hpp"
#include "runtime/parallel.hpp"
#include "runtime/pool.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;

void bind_runtime(py::module_& m, py::module_& t) {
  m.def("default_threads", &geoddp::default_threads, "Worker threads used when threads <= 0.");
  m.def(
      "spin_microseconds", []() { return geoddp::spin_microseconds(); },
      "How long an idle worker of the pool polls for the next task before it sleeps (us; cpp/runtime/pool.hpp).");
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
  t.def("has_avx2_fma", &geoddp::gemm::has_avx2_fma, "Whether the CPU runs the AVX2/FMA build of the products.");
  t.def(
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
}

}  // namespace geoddp
