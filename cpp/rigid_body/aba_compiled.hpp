// Pinocchio's ABA through the instantiation compiled inside the pin wheel's libpinocchio_default.
//
// With PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, aba.hxx declares aba() `extern template` for
// Eigen::Ref<const VectorXd> arguments. Called with plain VectorXd (or expressions) the template
// is instantiated again here, at this module's -O2; called through these Refs the wheel's copy
// runs, which is faster (benchmarks/pinocchio_calls.py times both). Same algorithm and arithmetic;
// only the compiler's code generation differs.
#pragma once

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/multibody.hpp>

#include <Eigen/Core>

namespace geoddp {

// data.ddq = ABA(q, v, tau) (local convention, as pinocchio::aba's default); returns data.ddq.
inline const Eigen::VectorXd& aba(const pinocchio::Model& model, pinocchio::Data& data,
                                  Eigen::Ref<const Eigen::VectorXd> q, Eigen::Ref<const Eigen::VectorXd> v,
                                  Eigen::Ref<const Eigen::VectorXd> tau) {
  return pinocchio::aba(model, data, q, v, tau, pinocchio::Convention::LOCAL);
}

}  // namespace geoddp
