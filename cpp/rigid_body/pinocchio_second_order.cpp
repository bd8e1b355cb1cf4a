// The one instantiation of Pinocchio's second-order RNEA (see pinocchio_second_order.hpp). A
// translation unit of its own (not in a unity file): it is the largest single
// instantiation of the core and compiles in parallel with the rest.
#include "rigid_body/pinocchio_second_order.hpp"

#include <pinocchio/algorithm/rnea-second-order-derivatives.hpp>

#include <unsupported/Eigen/CXX11/Tensor>

#include <algorithm>

namespace geoddp {
namespace libpin {

void rnea_second_order_tensors(const pinocchio::Model& model, pinocchio::Data& data,
                               const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& v,
                               const Eigen::Ref<const Eigen::VectorXd>& a, double* Iqq, double* Ivv, double* Iqv,
                               double* dM) {
  typedef Eigen::TensorMap<Eigen::Tensor<double, 3>> TensorMap;
  const Eigen::Index nv = model.nv;
  const size_t n3 = (size_t)nv * nv * nv;
  for (double* X : {Iqq, Ivv, Iqv, dM}) std::fill(X, X + n3, 0.0);
  TensorMap tqq(Iqq, nv, nv, nv), tvv(Ivv, nv, nv, nv), tqv(Iqv, nv, nv, nv), tdm(dM, nv, nv, nv);
  pinocchio::ComputeRNEASecondOrderDerivatives(model, data, q, v, a, tqq, tvv, tqv, tdm);
}

}  // namespace libpin
}  // namespace geoddp
