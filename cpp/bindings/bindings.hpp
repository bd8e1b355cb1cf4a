// The areas of the Python module geoddp._core, one bind_* per area (bindings/bind_<area>.cpp),
// called in order by bindings/module.cpp. Each registers what geoddp calls into `m` and what exists only so
// that the tests can reach the core's internals into `t`, the submodule geoddp._core.testing.
#pragma once

#include <pybind11/pybind11.h>

namespace geoddp {

void bind_runtime(pybind11::module_& m, pybind11::module_& t);    // workers, spin, the products' build
void bind_lie(pybind11::module_& t);                              // Jr's derivatives, block operators
void bind_rigid_body(pybind11::module_& t);                       // kinetic and RNEA Hessians
void bind_dynamics(pybind11::module_& m, pybind11::module_& t);   // rollouts, expansions
void bind_contact(pybind11::module_& m);                          // contact schedules: rollouts, costs, expansion
void bind_riccati(pybind11::module_& m, pybind11::module_& t);    // backward passes over tensors
void bind_contracted(pybind11::module_& m, pybind11::module_& t); // the factored second order
void bind_costs(pybind11::module_& m, pybind11::module_& t);      // cost terms, right Jacobians
void bind_cost_sum(pybind11::module_& m);                         // a whole cost sum in one call
void bind_tso3(pybind11::module_& m);                             // the satellite's closed forms

}  // namespace geoddp
