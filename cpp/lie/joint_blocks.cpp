// Reconstruction blocks in the expansions' row-major layout (see lie/joint_blocks.hpp). Compiled
// inside dynamics/core_algorithms.cpp: lie/joint_groups.hpp parses Pinocchio's joint headers.
#include "lie/joint_blocks.hpp"

#include <algorithm>

#include "runtime/arrays.hpp"

namespace geoddp {
namespace lie {

void block_ad_jr(const std::vector<JointGroup>& groups, int nv, const double* omega, double* A, double* Jr,
                 double* D) {
  MatMap Am(A, nv, nv), Jm(Jr, nv, nv);
  Am.setIdentity();
  Jm.setIdentity();
  if (D != nullptr) std::fill(D, D + (size_t)nv * nv * nv, 0.0);
  for (const JointGroup& g : groups) {
    const int o = g.idx_v;
    if (g.kind == SO3) {
      const Vec3 w = CVecMap(omega + o, 3);
      Am.block<3, 3>(o, o) = pinocchio::exp3(w).transpose();
      Jm.block<3, 3>(o, o) = so3_jr(w);
      if (D != nullptr) {
        Mat3 Dl[3];
        so3_djr(w, Dl);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            for (int l = 0; l < 3; ++l) D[((size_t)(o + i) * nv + (o + j)) * nv + (o + l)] = Dl[l](i, j);
      }
    } else if (g.kind == SE3) {
      const Eigen::Matrix<double, 6, 1> w = CVecMap(omega + o, 6);
      Am.block<6, 6>(o, o) = pinocchio::exp6(pinocchio::Motion(-w)).toActionMatrix();
      Jm.block<6, 6>(o, o) = se3_jr(w);
      if (D != nullptr) {
        Mat6 Dl[6];
        se3_djr(w, Dl);
        for (int i = 0; i < 6; ++i)
          for (int j = 0; j < 6; ++j)
            for (int l = 0; l < 6; ++l) D[((size_t)(o + i) * nv + (o + j)) * nv + (o + l)] = Dl[l](i, j);
      }
    }
  }
}

}  // namespace lie
}  // namespace geoddp
