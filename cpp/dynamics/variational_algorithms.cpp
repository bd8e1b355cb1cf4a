// A unity file: the forward variational Euler step (dynamics/variational.hpp), its residual, Newton
// iteration, exact second derivatives and node derivatives. One translation unit for the four
// files (Pinocchio's headers parsed once), compiled in parallel with core_algorithms.cpp and
// contact_algorithms.cpp.
#include "dynamics/variational_residual.cpp"
#include "dynamics/variational_step.cpp"
#include "dynamics/variational_hessian.cpp"
#include "dynamics/variational_derivatives.cpp"
