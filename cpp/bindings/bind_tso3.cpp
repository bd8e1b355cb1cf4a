// Python bindings of the TSO(3) closed forms (tso3/tso3.hpp): the satellite's rollout and expansion, SO(3)'s
// exp and log, and the geodesic attitude cost's derivatives. Outputs are caller-owned arrays written in place
// (checked writeable and C-contiguous, never converted: a converted copy would drop the writes); the Python
// callers validate first.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "bindings/bindings.hpp"
#include "bindings/checks.hpp"
#include "tso3/tso3.hpp"

namespace geoddp {

namespace py = pybind11;
using bind::Arr;
using bind::check_output;
using bind::check_shape;
using bind::Out;

namespace {

// The body's constants, checked: inertia, inertia_inv (3, 3), actuation (3, m).
tso3::Body body_of(const Arr& inertia, const Arr& inertia_inv, const Arr& actuation, double dt, bool semi_implicit) {
  check_shape(inertia, {3, 3}, "inertia");
  check_shape(inertia_inv, {3, 3}, "inertia_inv");
  check_shape(actuation, {3, -1}, "actuation");
  return tso3::Body{inertia.data(), inertia_inv.data(), actuation.data(), (int)actuation.shape(1), dt, semi_implicit};
}

// Shared by satellite_rollout and satellite_rollout_box; lower/upper null without limits.
bool rollout(const Arr& R0, const Arr& Om0, const Arr& R_bar, const Arr& Om_bar, const Arr& u_bar, const Arr& k_ff,
             const Arr& K_fb, double gamma, bool use_feedback, const Arr* lower, const Arr* upper, const Arr& inertia,
             const Arr& inertia_inv, const Arr& actuation, double dt, bool semi_implicit, Out R_out, Out Om_out,
             Out u_out) {
  const tso3::Body b = body_of(inertia, inertia_inv, actuation, dt, semi_implicit);
  if (u_bar.ndim() != 2 || u_bar.shape(1) != b.m) throw py::value_error("u_bar: expected (H, m)");
  const long H = u_bar.shape(0), m = b.m;
  check_shape(R0, {3, 3}, "R0");
  check_shape(Om0, {3}, "Om0");
  if (use_feedback) {
    check_shape(R_bar, {H + 1, 3, 3}, "R_bar");
    check_shape(Om_bar, {H + 1, 3}, "Om_bar");
    check_shape(k_ff, {H, m}, "k_ff");
    check_shape(K_fb, {H, m, 6}, "K_fb");
  }
  if (lower) {
    check_shape(*lower, {H, m}, "lower");
    check_shape(*upper, {H, m}, "upper");
  }
  check_output(R_out, {H + 1, 3, 3}, "R_out");
  check_output(Om_out, {H + 1, 3}, "Om_out");
  check_output(u_out, {H, m}, "u_out");
  py::gil_scoped_release nogil;
  return tso3::rollout(b, (int)H, R0.data(), Om0.data(), R_bar.data(), Om_bar.data(), u_bar.data(), k_ff.data(),
                       use_feedback ? K_fb.data() : nullptr, gamma, lower ? lower->data() : nullptr,
                       upper ? upper->data() : nullptr, R_out.mutable_data(), Om_out.mutable_data(),
                       u_out.mutable_data());
}

}  // namespace

void bind_tso3(py::module_& m) {
  m.def(
      "satellite_rollout",
      [](const Arr& R0, const Arr& Om0, const Arr& R_bar, const Arr& Om_bar, const Arr& u_bar, const Arr& k_ff,
         const Arr& K_fb, double gamma, bool use_feedback, const Arr& inertia, const Arr& inertia_inv,
         const Arr& actuation, double dt, bool semi_implicit, Out R_out, Out Om_out, Out u_out) {
        return rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, use_feedback, nullptr, nullptr, inertia,
                       inertia_inv, actuation, dt, semi_implicit, R_out, Om_out, u_out);
      },
      py::arg("R0"), py::arg("Om0"), py::arg("R_bar"), py::arg("Om_bar"), py::arg("u_bar"), py::arg("k_ff"),
      py::arg("K_fb"), py::arg("gamma"), py::arg("use_feedback"), py::arg("inertia"), py::arg("inertia_inv"),
      py::arg("actuation"), py::arg("dt"), py::arg("semi_implicit"), py::arg("R_out").noconvert(),
      py::arg("Om_out").noconvert(), py::arg("u_out").noconvert(),
      "Roll the satellite forward under u_k = u_bar_k - gamma k_k - K_k zeta_k (paper eq. dustar), zeta_k = "
      "(log(R_bar_k^T R_k), Om_k - Om_bar_k); without feedback u = u_bar. Explicit Euler (R+ = R exp(dt Om), paper "
      "eq. disceqs) or semi-implicit (R+ = R exp(dt Om+)). Writes R_out (H+1, 3, 3), Om_out (H+1, 3), u_out (H, m); "
      "returns False once a state became non-finite.");
  m.def(
      "satellite_rollout_box",
      [](const Arr& R0, const Arr& Om0, const Arr& R_bar, const Arr& Om_bar, const Arr& u_bar, const Arr& k_ff,
         const Arr& K_fb, double gamma, const Arr& lower, const Arr& upper, const Arr& inertia, const Arr& inertia_inv,
         const Arr& actuation, double dt, bool semi_implicit, Out R_out, Out Om_out, Out u_out) {
        return rollout(R0, Om0, R_bar, Om_bar, u_bar, k_ff, K_fb, gamma, true, &lower, &upper, inertia, inertia_inv,
                       actuation, dt, semi_implicit, R_out, Om_out, u_out);
      },
      py::arg("R0"), py::arg("Om0"), py::arg("R_bar"), py::arg("Om_bar"), py::arg("u_bar"), py::arg("k_ff"),
      py::arg("K_fb"), py::arg("gamma"), py::arg("lower"), py::arg("upper"), py::arg("inertia"),
      py::arg("inertia_inv"), py::arg("actuation"), py::arg("dt"), py::arg("semi_implicit"),
      py::arg("R_out").noconvert(), py::arg("Om_out").noconvert(), py::arg("u_out").noconvert(),
      "satellite_rollout with feedback and control limits: u_k = clamp(u_bar_k - gamma k_k - K_k zeta_k, "
      "lower_k, upper_k), lower/upper (H, m); the clamped u_k is applied and stored (a NaN stays NaN).");
  m.def(
      "satellite_linearise",
      [](const Arr& Om, double dt, const Arr& inertia, const Arr& inertia_inv, const Arr& actuation,
         bool semi_implicit, bool second_order, Out Phi, Out B, Out Theta, Out Gamma, Out Xi) {
        const tso3::Body b = body_of(inertia, inertia_inv, actuation, dt, semi_implicit);
        if (Om.ndim() != 2 || Om.shape(0) < 1) throw py::value_error("Om: expected (H+1, 3)");
        const long H = Om.shape(0) - 1, m = b.m;
        check_shape(Om, {H + 1, 3}, "Om");
        check_output(Phi, {H, 6, 6}, "Phi");
        check_output(B, {H, 6, m}, "B");
        if (second_order) {
          check_output(Theta, {H, 6, 6, 6}, "Theta");
          check_output(Gamma, {H, 6, 6, m}, "Gamma");
          check_output(Xi, {H, 6, m, m}, "Xi");
        }
        py::gil_scoped_release nogil;
        tso3::linearise(b, (int)H, Om.data(), second_order, Phi.mutable_data(), B.mutable_data(),
                        second_order ? Theta.mutable_data() : nullptr, second_order ? Gamma.mutable_data() : nullptr,
                        second_order ? Xi.mutable_data() : nullptr);
      },
      py::arg("Om"), py::arg("dt"), py::arg("inertia"), py::arg("inertia_inv"), py::arg("actuation"),
      py::arg("semi_implicit"), py::arg("second_order"), py::arg("Phi").noconvert(), py::arg("B").noconvert(),
      py::arg("Theta").noconvert(), py::arg("Gamma").noconvert(), py::arg("Xi").noconvert(),
      "The satellite's exact expansion along body rates Om (H+1, 3): Phi (H, 6, 6), B (H, 6, m) and, when "
      "second_order, Theta (H, 6, 6, 6), Gamma (H, 6, 6, m), Xi (H, 6, m, m), written in place.");
  m.def(
      "so3_exp",
      [](double x0, double x1, double x2, Out out) {
        check_output(out, {3, 3}, "out");
        tso3::so3_exp(x0, x1, x2, out.mutable_data());
      },
      py::arg("x0"), py::arg("x1"), py::arg("x2"), py::arg("out").noconvert(),
      "Rodrigues' formula exp(hat(x)) into out (3, 3), NaN-free at 0.");
  m.def(
      "so3_log",
      [](const Arr& R, Out out) {
        check_shape(R, {3, 3}, "R");
        check_output(out, {3}, "out");
        tso3::so3_log(R.data(), out.mutable_data());
      },
      py::arg("R"), py::arg("out").noconvert(),
      "The rotation vector of R (3, 3) into out (3,), angle in [0, pi]; robust near 0 and near pi.");
  m.def(
      "so3_log_batch",
      [](const Arr& R, Out out) {
        if (R.ndim() != 3) throw py::value_error("R: expected (N, 3, 3)");
        const long N = R.shape(0);
        check_shape(R, {N, 3, 3}, "R");
        check_output(out, {N, 3}, "out");
        const double* r = R.data();
        double* o = out.mutable_data();
        py::gil_scoped_release nogil;
        for (long n = 0; n < N; ++n) tso3::so3_log(r + 9 * n, o + 3 * n);
      },
      py::arg("R"), py::arg("out").noconvert(),
      "so3_log over R (N, 3, 3) into out (N, 3): accurate to ~1e-15 up to pi, where pin.log3 loses up to ~1e-10 "
      "between 150 and 180 degrees.");
  m.def(
      "geodesic_attitude_derivatives",
      [](const Arr& E, const Arr& W, Out l, Out g, Out Hs) {
        if (E.ndim() != 3) throw py::value_error("E: expected (N, 3, 3)");
        const long N = E.shape(0);
        check_shape(E, {N, 3, 3}, "E");
        check_shape(W, {3, 3}, "W");
        check_output(l, {N}, "l");
        check_output(g, {N, 3}, "g");
        check_output(Hs, {N, 3, 3}, "Hs");
        py::gil_scoped_release nogil;
        tso3::geodesic_attitude_derivatives((int)N, E.data(), W.data(), l.mutable_data(), g.mutable_data(),
                                            Hs.mutable_data());
      },
      py::arg("E"), py::arg("W"), py::arg("l").noconvert(), py::arg("g").noconvert(), py::arg("Hs").noconvert(),
      "Add 1/2 r^T W r, r = log(E_n), its trivialised gradient Jr(r)^-T W r and (0)-Hessian into l (N,), g (N, 3), "
      "Hs (N, 3, 3).");
}

}  // namespace geoddp
