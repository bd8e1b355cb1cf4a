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

// The group of one joint model, by its type (a visitor: no string per joint and call, as
// shortname() would make on every cost call).
// -1 for a joint whose configuration space is none of R^k, SO(2), SO(3), SE(3).
struct GroupKindOf : boost::static_visitor<int> {
  template <typename JointModel>
  int operator()(const JointModel&) const { return -1; }  // planar, composite, mimic, helical, ...
  // (spherical ZYX too: its motion subspace moves with q, and Pinocchio's analytic derivatives of
  // RNEA and ABA do not hold for it, as differences show; every joint accepted here has a
  // motion subspace constant in its own frame, which rigid_body/kinetic_hessian.hpp also relies on)
  template <int axis>
  int operator()(const pinocchio::JointModelRevoluteTpl<double, 0, axis>&) const { return VECTOR; }
  template <int axis>
  int operator()(const pinocchio::JointModelPrismaticTpl<double, 0, axis>&) const { return VECTOR; }
  int operator()(const pinocchio::JointModelRevoluteUnalignedTpl<double, 0>&) const { return VECTOR; }
  int operator()(const pinocchio::JointModelPrismaticUnalignedTpl<double, 0>&) const { return VECTOR; }
  int operator()(const pinocchio::JointModelTranslationTpl<double, 0>&) const { return VECTOR; }
  template <int axis>
  int operator()(const pinocchio::JointModelRevoluteUnboundedTpl<double, 0, axis>&) const { return SO2; }
  int operator()(const pinocchio::JointModelRevoluteUnboundedUnalignedTpl<double, 0>&) const { return SO2; }
  int operator()(const pinocchio::JointModelSphericalTpl<double, 0>&) const { return SO3; }
  int operator()(const pinocchio::JointModelFreeFlyerTpl<double, 0>&) const { return SE3; }
};

// The joint groups of `model` (the universe joint 0 skipped); throws std::invalid_argument naming
// a joint whose configuration space is none of R^k, SO(2), SO(3), SE(3) (planar, composite, ...).
inline std::vector<JointGroup> joint_groups(const pinocchio::Model& model) {
  std::vector<JointGroup> out;
  out.reserve((size_t)model.njoints);
  for (pinocchio::JointIndex j = 1; j < (pinocchio::JointIndex)model.njoints; ++j) {
    const auto& jm = model.joints[j];
    const int kind = boost::apply_visitor(GroupKindOf(), jm.toVariant());
    if (kind < 0)
      throw std::invalid_argument("joint '" + model.names[j] + "' of type " + jm.shortname() +
                                  " is not supported (supported: revolute, continuous, prismatic, spherical, "
                                  "free-flyer)");
    out.push_back({kind, jm.idx_q(), jm.idx_v(), jm.nv()});
  }
  return out;
}

}  // namespace geoddp
