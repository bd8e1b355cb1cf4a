// The one translation unit of every file that instantiates Pinocchio's algorithm templates (or
// parses its joint-variant headers): the Lie-level reconstruction blocks, the rigid-body recursions,
// and the four integrators with the trajectory kernels. Compiled apart, each file re-parsed
// Pinocchio's joint-variant headers and re-instantiated its algorithms (RNEA's second-order
// derivatives several times), which cost more CPU than the rest of the build together. The files
// stay separate to read and share no file-local names; each includes what it uses.
#include "lie/joint_blocks.cpp"
#include "rigid_body/kinetic_hessian.cpp"
#include "rigid_body/rnea_hessian.cpp"
#include "dynamics/second_order_terms.cpp"
#include "dynamics/euler.cpp"
#include "dynamics/rkmk4.cpp"
#include "dynamics/variational_residual.cpp"
#include "dynamics/variational_step.cpp"
#include "dynamics/variational_hessian.cpp"
#include "dynamics/variational_derivatives.cpp"
#include "dynamics/expansion.cpp"
#include "dynamics/trajectory.cpp"
#include "dynamics/contact_node.cpp"
#include "dynamics/contact_costs.cpp"
#include "dynamics/contact_trajectory.cpp"
#include "dynamics/contact_second.cpp"
