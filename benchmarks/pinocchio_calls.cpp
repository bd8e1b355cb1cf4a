// Per-call cost of the Pinocchio algorithms the compiled core runs per node (issue 12): ABA as
// instantiated in this program at -O2 (what cpp/ did before cpp/rigid_body/aba_compiled.hpp) against the
// instantiation inside the pin wheel's libpinocchio_default (called through Eigen::Ref arguments),
// computeABADerivatives (the first-order expansion) and ComputeRNEASecondOrderDerivatives (the
// exact second-order expansion), and geoddp's kinetic-energy Hessian (cpp/rigid_body/kinetic_hessian.cpp, the
// variational step's second order) against the second-order RNEA it replaces at (q, 0, y), and
// RNEA's second order contracted with mu by the recursion (cpp/rigid_body/rnea_hessian.cpp, the contracted
// pass's, since 2026-12-01) against that RNEA, whole and its part in the pass. Built and run by
// benchmarks/pinocchio_calls.py.
//
// Models are built here, with random inertias and joint placements (seeded), in the shapes of the
// benchmark cases: a single free-flying body (nv 6: the docking spacecraft, the quadrotors), a
// 6-joint fixed-base arm (the UR5), a free-flying base with 3 revolute joints (the space
// manipulator, nv 9) and with 12 (Solo12, nv 18). Each algorithm is timed in 7 interleaved
// rounds; the median per call is printed.
#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea-second-order-derivatives.hpp>
#include <pinocchio/multibody.hpp>

#include "rigid_body/kinetic_hessian.cpp"
#include "rigid_body/rnea_hessian.cpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

using namespace pinocchio;
typedef Eigen::Ref<const Eigen::VectorXd> CRef;

static Model build(bool free_flyer, int joints) {
  Model model;
  JointIndex parent = 0;
  if (free_flyer) {
    parent = model.addJoint(0, JointModelFreeFlyer(), SE3::Identity(), "root");
    model.appendBodyToJoint(parent, Inertia::Random(), SE3::Identity());
  }
  for (int i = 0; i < joints; ++i) {
    const std::string name = "j" + std::to_string(i);
    const SE3 M = SE3::Random();
    if (i % 3 == 0) parent = model.addJoint(parent, JointModelRZ(), M, name);
    else if (i % 3 == 1) parent = model.addJoint(parent, JointModelRY(), M, name);
    else parent = model.addJoint(parent, JointModelRX(), M, name);
    model.appendBodyToJoint(parent, Inertia::Random(), SE3::Identity());
  }
  return model;
}

static double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

int main() {
  std::srand(7);
  struct Case {
    const char* name;
    bool ff;
    int joints;
  };
  const Case cases[] = {{"free body (nv 6)", true, 0}, {"6-joint arm (nv 6)", false, 6},
                        {"free base + 3 joints (nv 9)", true, 3}, {"free base + 12 joints (nv 18)", true, 12}};
  std::printf("| model | aba, this program -O2 (us) | aba, the wheel's (us) | wheel / -O2 | computeABADerivatives (us) | "
              "ComputeRNEASecondOrderDerivatives (us) | RNEA second order / ABA derivatives | "
              "kinetic_hessian (us) | RNEA second order at (q, 0, y) / kinetic_hessian | mass_tensors (us) | "
              "RNEA second order at (q, 0, y) / mass_tensors | rnea_hessian (us) | RNEA second order / rnea_hessian | "
              "of which in the pass: rnea_hessian_contract (us) |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Case& c : cases) {
    const Model model = build(c.ff, c.joints);
    Data data(model);
    const Eigen::VectorXd q = randomConfiguration(model, -Eigen::VectorXd::Ones(model.nq), Eigen::VectorXd::Ones(model.nq));
    const Eigen::VectorXd v = Eigen::VectorXd::Random(model.nv), tau = Eigen::VectorXd::Random(model.nv);
    const Eigen::VectorXd a = Eigen::VectorXd::Random(model.nv);
    const CRef qr(q), vr(v), tr(tau);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(model.nv);
    geoddp::dyn::KineticHessianWork kw(model);
    Eigen::MatrixXd H(model.nv, model.nv);
    std::vector<double> dM((size_t)model.nv * model.nv * model.nv), T(dM.size());
    geoddp::dyn::RneaHessianWork rw(model);
    const Eigen::VectorXd mu = Eigen::VectorXd::Random(model.nv);
    std::vector<double> r4(4 * (size_t)model.nv * model.nv);
    const size_t nn = (size_t)model.nv * model.nv;
    const int reps = model.nv > 10 ? 2000 : 10000;
    std::vector<std::function<void()>> calls = {
        [&] { aba(model, data, q, v, tau); },                          // instantiated here (plain VectorXd)
        [&] { aba(model, data, qr, vr, tr, Convention::LOCAL); },      // the wheel's (extern template)
        [&] { computeABADerivatives(model, data, qr, vr, tr); },
        [&] { ComputeRNEASecondOrderDerivatives(model, data, q, v, a); },
        [&] { ComputeRNEASecondOrderDerivatives(model, data, q, zero, v); },  // what the variational step ran
        [&] { geoddp::dyn::kinetic_hessian(model, data, kw, q, v, H); },
        [&] { geoddp::dyn::mass_tensors(model, data, kw, q, v, dM.data(), T.data()); },  // its tensors
        // RNEA's second order contracted with mu (cpp/rigid_body/rnea_hessian.hpp), what the contracted pass runs
        [&] { geoddp::dyn::rnea_hessian(model, rw, q.data(), v.data(), a.data(), mu.data(), r4.data(), r4.data() + nn,
                                        r4.data() + 2 * nn, r4.data() + 3 * nn); },
        // its part that needs mu, which the pass runs (the rest runs in the expansion, node-parallel)
        [&] { geoddp::dyn::rnea_hessian_contract(model, rw, rw.node.data(), mu.data(), r4.data(), r4.data() + nn,
                                                 r4.data() + 2 * nn, r4.data() + 3 * nn); },
    };
    std::vector<std::vector<double>> t(calls.size());
    for (int round = 0; round < 8; ++round)
      for (size_t i = 0; i < calls.size(); ++i) {
        const int n = i == 3 || i == 4 ? reps / 5 : reps;
        const auto t0 = std::chrono::steady_clock::now();
        for (int r = 0; r < n; ++r) calls[i]();
        const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / n;
        if (round > 0) t[i].push_back(us);  // round 0 warms up
      }
    const double a_here = median(t[0]), a_lib = median(t[1]), dab = median(t[2]), so = median(t[3]);
    const double so_y = median(t[4]), kh = median(t[5]), mt = median(t[6]), rh = median(t[7]), rc = median(t[8]);
    std::printf("| %s | %.2f | %.2f | %.2fx | %.2f | %.2f | %.1fx | %.2f | %.1fx | %.2f | %.1fx | %.2f | %.1fx | %.2f |\n",
                c.name, a_here, a_lib, a_lib / a_here, dab, so, so / dab, kh, so_y / kh, mt, so_y / mt, rh, so / rh, rc);
  }
  return 0;
}
