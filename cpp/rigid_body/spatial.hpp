// Spatial products on plain 6-vectors ([linear; angular], Pinocchio's order), shared by the spatial-vector
// recursions (rigid_body/kinetic_hessian.cpp, rigid_body/rnea_hessian.cpp): a x b of motions and a x* f of a
// motion on a force, without Pinocchio's Motion/Force wrappers.
#pragma once

#include <Eigen/Core>

namespace geoddp {
namespace spatial {

typedef Eigen::Matrix<double, 6, 1> V6;

inline V6 motion_cross(const V6& a, const V6& b) {
  V6 r;
  r.head<3>() = a.tail<3>().cross(b.head<3>()) + a.head<3>().cross(b.tail<3>());
  r.tail<3>() = a.tail<3>().cross(b.tail<3>());
  return r;
}

inline V6 force_cross(const V6& a, const V6& f) {
  V6 r;
  r.head<3>() = a.tail<3>().cross(f.head<3>());
  r.tail<3>() = a.head<3>().cross(f.head<3>()) + a.tail<3>().cross(f.tail<3>());
  return r;
}

}  // namespace spatial
}  // namespace geoddp
