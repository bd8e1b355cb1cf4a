// Where each dof sits in a kinematic tree, for the spatial-vector recursions (kinetic_hessian.*,
// rnea_hessian.*), whose pair terms depend only on whether one dof's joint is, supports or is
// supported by the other's. Pinocchio numbers joints depth-first, so a subtree's joints, hence its
// dofs, are contiguous.
#pragma once

#include <pinocchio/multibody.hpp>

#include <algorithm>
#include <utility>
#include <vector>

namespace geoddp {
namespace dyn {

struct TreeDofs {
  std::vector<int> joint;      // per dof: its joint
  std::vector<int> last;       // per joint: the last joint of its subtree
  std::vector<int> first_dof;  // per joint: its first dof (its subtree's first)
  std::vector<int> own_end;    // per joint: the end of its own dofs
  std::vector<int> end_dof;    // per joint: the end of its subtree's dofs
  // per joint: the dofs of the joints strictly supporting it, as runs [begin, end) of consecutive
  // dofs, root first
  std::vector<std::vector<std::pair<int, int>>> above;

  explicit TreeDofs(const pinocchio::Model& model)
      : joint(model.nv), last(model.njoints), first_dof(model.njoints), own_end(model.njoints),
        end_dof(model.njoints), above(model.njoints) {
    for (int j = 0; j < model.njoints; ++j) {
      last[j] = j;
      for (const auto s : model.subtrees[j]) last[j] = std::max(last[j], (int)s);
    }
    for (int j = 1; j < model.njoints; ++j) {
      for (int d = 0; d < model.nvs[j]; ++d) joint[model.idx_vs[j] + d] = j;
      first_dof[j] = model.idx_vs[j];
      own_end[j] = model.idx_vs[j] + model.nvs[j];
      end_dof[j] = model.idx_vs[last[j]] + model.nvs[last[j]];
      for (const auto s : model.supports[j]) {  // the universe, ..., j
        if (s == 0 || (int)s == j) continue;
        const int b0 = model.idx_vs[s], b1 = b0 + model.nvs[s];
        if (!above[j].empty() && above[j].back().second == b0) above[j].back().second = b1;
        else above[j].emplace_back(b0, b1);
      }
    }
  }
};

}  // namespace dyn
}  // namespace geoddp
