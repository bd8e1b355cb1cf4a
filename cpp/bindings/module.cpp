// geoddp._core: the compiled kernels (arrays in, arrays out), one bind_* call per area.
//
// Every array is float64, C-contiguous; shapes are documented per function. Argument checking for
// users happens on the Python side (geoddp.models.compiled, geoddp.kernels); the checks here only
// guard memory safety. The GIL is released while a kernel runs. What exists only for the tests
// lives in the submodule geoddp._core.testing.
#include <pybind11/pybind11.h>

#include <pinocchio/config.hpp>

#include <string>

#include "bindings/bindings.hpp"

namespace py = pybind11;

PYBIND11_MODULE(_core, m) {
  m.doc() = "geoddp's compiled kernels: the multibody core over Pinocchio, the satellite's TSO(3) closed forms, "
            "the backward passes (C++17)";
  // The extension must run with the pin it was compiled against (pinocchio::Model's layout).
  py::module_ pin = py::module_::import("pinocchio");
  const std::string runtime = py::str(pin.attr("__version__"));
  if (runtime != PINOCCHIO_VERSION)
    throw py::import_error("geoddp._core was built against pin " + std::string(PINOCCHIO_VERSION) +
                           " but pin " + runtime +
                           " is installed; rebuild it against that pin: pip install --no-build-isolation --force-reinstall --no-deps -e . "
                           "(after pip install scikit-build-core pybind11 cmeel-eigen cmake ninja)");
  m.attr("PINOCCHIO_VERSION") = PINOCCHIO_VERSION;

  py::module_ testing = m.def_submodule(
      "testing", "The core's internals, reachable for the tests and benchmarks only; geoddp never calls them.");
  geoddp::bind_runtime(m, testing);
  geoddp::bind_lie(testing);
  geoddp::bind_rigid_body(testing);
  geoddp::bind_dynamics(m, testing);
  geoddp::bind_contact(m);
  geoddp::bind_riccati(m, testing);
  geoddp::bind_contracted(m, testing);
  geoddp::bind_costs(m, testing);
  geoddp::bind_cost_sum(m);
  geoddp::bind_tso3(m);
}
