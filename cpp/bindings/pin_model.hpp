// Passing a Python pin.Model to C++ without a copy: the one place the conversion lives.
//
// pin's Python bindings are Boost.Python classes registered in the Boost.Python registry of the
// libboost_python shared library that the `pin` wheel ships (cmeel.prefix/lib). This extension
// links that same library, so boost::python::extract<const pinocchio::Model&> finds the
// registration and returns a reference to the C++ object held by the Python pin.Model (the way
// Pinocchio's own pybind11 helper, pinocchio/bindings/python/pybind11.hpp, does it; that header
// itself also pulls in eigenpy, which we do not need).
//
// Requirements, all enforced by the build (CMakeLists.txt) and at import (bindings/module.cpp):
// * the extension is compiled against the headers of the very pin it runs with (same
//   PINOCCHIO_VERSION): pinocchio::Model's layout must match the object pin created;
// * `import pinocchio` happens before the first extraction (bindings/module.cpp imports it at init).
//
// Usage (costs kernels too):  const pinocchio::Model& model = geoddp::model_from_python(obj);
// The reference is valid while the Python object lives: keep the py::handle alive (it is, for
// the duration of a bound call).
#pragma once

#include <pybind11/pybind11.h>

#include <pinocchio/multibody.hpp>

#include <boost/python/extract.hpp>

namespace geoddp {

inline const pinocchio::Model& model_from_python(pybind11::handle obj, const char* name = "model") {
  boost::python::extract<const pinocchio::Model&> ex(obj.ptr());
  if (!ex.check()) {
    if (PyErr_Occurred()) PyErr_Clear();
    throw pybind11::type_error(std::string(name) + ": expected a pinocchio.Model, got " +
                               std::string(pybind11::str(pybind11::type::handle_of(obj).attr("__name__"))));
  }
  return ex();
}

}  // namespace geoddp
