// The one translation unit that instantiates Pinocchio's algorithm templates: the Euler schemes'
// kernels (dynamics.cpp), the kinetic-energy Hessian (kinetic_hessian.cpp), RNEA's contracted Hessian
// (rnea_hessian.cpp), RKMK4 (rkmk4.cpp) and the
// variational step (variational.cpp). Compiled
// apart, each re-parsed Pinocchio's joint-variant headers and re-instantiated its algorithms
// (RNEA's second-order derivatives twice), which cost more CPU than the rest of the build; the
// files stay separate to read, and share no file-local names.
#include "dynamics.cpp"
#include "kinetic_hessian.cpp"
#include "rnea_hessian.cpp"
#include "rkmk4.cpp"
#include "variational.cpp"
