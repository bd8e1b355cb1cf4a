// A unity file: the Lie-level reconstruction blocks, the rigid-body recursions, and the explicit,
// semi-implicit and RKMK4 integrators with the trajectory kernels and expansions. Each of these
// files parses Pinocchio's joint-variant headers (about a minute of compile time per translation
// unit), so they share one; the variational and legged files have unity files of their own
// (variational_algorithms.cpp, contact_algorithms.cpp) that compile in parallel with this one.
// The files stay separate to read and share no file-local names; each includes what it uses.
#include "lie/joint_blocks.cpp"
#include "rigid_body/kinetic_hessian.cpp"
#include "rigid_body/rnea_hessian.cpp"
#include "dynamics/second_order_terms.cpp"
#include "dynamics/euler.cpp"
#include "dynamics/rkmk4.cpp"
#include "dynamics/expansion.cpp"
#include "dynamics/trajectory.cpp"
