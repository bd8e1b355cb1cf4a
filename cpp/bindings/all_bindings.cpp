// The one translation unit of the bind_* files: each parses pybind11 and most parse Boost.Python
// and Pinocchio's headers too (bindings/pin_model.hpp), which cost more CPU than their own code;
// compiled together they are parsed once. The files stay separate to read; names they keep to
// themselves sit in anonymous namespaces and differ between files. module.cpp, which defines the
// module, compiles apart.
#include "bindings/bind_runtime.cpp"
#include "bindings/bind_lie.cpp"
#include "bindings/bind_rigid_body.cpp"
#include "bindings/bind_dynamics.cpp"
#include "bindings/bind_contact.cpp"
#include "bindings/bind_riccati.cpp"
#include "bindings/bind_contracted.cpp"
#include "bindings/bind_costs.cpp"
#include "bindings/bind_cost_sum.cpp"
#include "bindings/bind_tso3.cpp"
