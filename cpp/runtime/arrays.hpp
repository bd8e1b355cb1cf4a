// The array types every kernel shares: float64, row-major (numpy's C order, which the bindings
// hand over without a copy), dynamic size, and maps over raw pointers into such arrays.
#pragma once

#include <Eigen/Core>

namespace geoddp {

typedef Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> RowMat;
typedef Eigen::Map<const RowMat> CMatMap;
typedef Eigen::Map<RowMat> MatMap;
typedef Eigen::Map<const Eigen::VectorXd> CVecMap;
typedef Eigen::Map<Eigen::VectorXd> VecMap;

}  // namespace geoddp
