// Pinocchio's second-order RNEA derivatives (ComputeRNEASecondOrderDerivatives), instantiated once,
// in rigid_body/pinocchio_second_order.cpp.
//
// The pin wheel compiles no instantiation of this algorithm, so every call with new argument types
// instantiated its recursion again over every joint type (its backward step alone was a quarter of
// the core's machine code, twice: once for Data's own tensors, once for maps of ours). Here it has
// one signature, compiled in a file of its own that builds beside the others.
#pragma once

#include <pinocchio/multibody.hpp>

#include <Eigen/Core>

namespace geoddp {
namespace libpin {

// The tensors d2tau/dq2, d2tau/dv2, d2tau/dqdv and d2tau/dadq = dM/dq at (q (nq), v (nv), a (nv))
// into Iqq, Ivv, Iqv, dM: nv^3 doubles each, column-major as Pinocchio stores them ((i, j, k) at
// i + nv (j + nv k)), zeroed first (the recursion writes only the entries the kinematic tree
// couples). The outputs may be data's own tensors (data.d2tau_dqdq.data(), ...). data is scratch.
void rnea_second_order_tensors(const pinocchio::Model& model, pinocchio::Data& data,
                               const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& v,
                               const Eigen::Ref<const Eigen::VectorXd>& a, double* Iqq, double* Ivv, double* Iqv,
                               double* dM);

// The same into data's own tensors (data.d2tau_dqdq, d2tau_dvdv, d2tau_dqdv, d2tau_dadq), as
// Pinocchio's five-argument overload.
inline void rnea_second_order_tensors(const pinocchio::Model& model, pinocchio::Data& data,
                                      const Eigen::Ref<const Eigen::VectorXd>& q,
                                      const Eigen::Ref<const Eigen::VectorXd>& v,
                                      const Eigen::Ref<const Eigen::VectorXd>& a) {
  rnea_second_order_tensors(model, data, q, v, a, data.d2tau_dqdq.data(), data.d2tau_dvdv.data(),
                            data.d2tau_dqdv.data(), data.d2tau_dadq.data());
}

}  // namespace libpin
}  // namespace geoddp
