// A unity file: the legged robots' contact and impulse nodes, their costs, rollouts and first- and
// second-order expansions (dynamics/contact.hpp). One translation unit for the four files
// (Pinocchio's headers parsed once), compiled in parallel with core_algorithms.cpp and
// variational_algorithms.cpp.
#include "dynamics/contact_node.cpp"
#include "dynamics/contact_costs.cpp"
#include "dynamics/contact_trajectory.cpp"
#include "dynamics/contact_second.cpp"
