// One joint's Lie group and a model's groups in tangent order: the one classification the
// kernels share (dynamics, costs, contraction), the same as geoddp.lie.product.joint_groups.
#pragma once

#include <pinocchio/multibody.hpp>

#include <stdexcept>
#include <string>
#include <vector>

namespace geoddp {

enum GroupKind { VECTOR = 0, SO2 = 1, SO3 = 2, SE3 = 3 };

// kind (GroupKind), the first configuration coordinate, the tangent slice [idx_v, idx_v + nv).
struct JointGroup {
  int kind, idx_q, idx_v, nv;
};

// The joint groups of `model` (the universe joint 0 skipped); throws std::invalid_argument naming
// a joint whose configuration space is none of R^k, SO(2), SO(3), SE(3) (planar, composite, ...).
inline std::vector<JointGroup> joint_groups(const pinocchio::Model& model) {
  std::vector<JointGroup> out;
  for (pinocchio::JointIndex j = 1; j < (pinocchio::JointIndex)model.njoints; ++j) {
    const auto& jm = model.joints[j];
    const std::string s = jm.shortname();
    int kind;
    if (s == "JointModelRX" || s == "JointModelRY" || s == "JointModelRZ" || s == "JointModelPX" ||
        s == "JointModelPY" || s == "JointModelPZ" || s == "JointModelRevoluteUnaligned" ||
        s == "JointModelPrismaticUnaligned" || s == "JointModelTranslation" || s == "JointModelSphericalZYX")
      kind = VECTOR;
    else if (s == "JointModelRUBX" || s == "JointModelRUBY" || s == "JointModelRUBZ" ||
             s == "JointModelRevoluteUnboundedUnaligned")
      kind = SO2;
    else if (s == "JointModelSpherical")
      kind = SO3;
    else if (s == "JointModelFreeFlyer")
      kind = SE3;
    else
      throw std::invalid_argument("joint '" + model.names[j] + "' of type " + s +
                                  " is not supported (supported: revolute, continuous, prismatic, spherical, "
                                  "free-flyer)");
    out.push_back({kind, jm.idx_q(), jm.idx_v(), jm.nv()});
  }
  return out;
}

}  // namespace geoddp
