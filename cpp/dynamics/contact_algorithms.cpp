// The legged robots' translation unit: the contact node models, the gait costs and a schedule's
// trajectory kernels (contact.hpp). Apart from core_algorithms.cpp, not inside it: these files
// instantiate Pinocchio's forward and impulse dynamics and their derivatives, which the rest of the
// core does not use, so apart little is instantiated twice, and on two cores the two units compile
// side by side (this one alone: about 3 minutes, g++ 12 -O2).
#include "dynamics/contact_node.cpp"
#include "dynamics/contact_costs.cpp"
#include "dynamics/contact_trajectory.cpp"
