// Argument checks shared by the bindings (bindings/module.cpp, bindings/bind_contracted.cpp): shapes of inputs,
// writeable C-contiguous outputs, and the backward passes' common blocks. The Python wrappers
// validate first (with InputError); these keep a direct call from reading out of bounds.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <initializer_list>
#include <string>
#include <vector>

namespace geoddp {
namespace bind {

namespace py = pybind11;

// Inputs: float64, C-contiguous (converted on the way in when they are not).
typedef py::array_t<double, py::array::c_style | py::array::forcecast> Arr;

// Outputs written in place: float64, never converted (a converted copy would drop the writes).
typedef py::array_t<double> Out;

// A new uninitialised output of `shape`.
inline Arr empty(std::vector<py::ssize_t> shape) { return Arr(shape); }

// `a` has exactly `shape` (an entry -1 matches any extent).
inline void check_shape(const py::array& a, std::initializer_list<long> shape, const char* name) {
  bool ok = a.ndim() == (py::ssize_t)shape.size();
  int i = 0;
  for (long s : shape) {
    if (!ok) break;
    if (s >= 0 && a.shape(i) != s) ok = false;
    ++i;
  }
  if (!ok) throw py::value_error(std::string(name) + ": wrong shape");
}

// An output written in place: writeable, C-contiguous, of exactly `shape`.
inline void check_output(const py::array& a, std::initializer_list<long> shape, const char* name) {
  if (!(a.flags() & py::array::c_style) || !a.writeable())
    throw py::value_error(std::string(name) + ": expected a writeable C-contiguous array");
  check_shape(a, shape, name);
}

// Sizes of a backward pass, read from Phi (H, n, n) and B (H, n, m).
struct PassSizes {
  long H, n, m;
};

// The first-order inputs of every recursion over the horizon (the backward passes and the
// gradient): Phi, B and the cost gradients.
inline PassSizes check_first_order_inputs(const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu) {
  if (Phi.ndim() != 3 || B.ndim() != 3) throw py::value_error("Phi, B: expected (H, n, n), (H, n, m)");
  const long H = Phi.shape(0), n = Phi.shape(1), m = B.shape(2);
  check_shape(Phi, {H, n, n}, "Phi");
  check_shape(B, {H, n, m}, "B");
  check_shape(lx, {H, n}, "lx");
  check_shape(lu, {H, m}, "lu");
  return {H, n, m};
}

// The inputs every backward pass takes: those above, the cost Hessians and the final value function.
inline PassSizes check_pass_inputs(const Arr& Phi, const Arr& B, const Arr& lx, const Arr& lu, const Arr& lxx,
                                   const Arr& lux, const Arr& luu, const Arr& Vx_final, const Arr& Vxx_final) {
  const PassSizes z = check_first_order_inputs(Phi, B, lx, lu);
  const long H = z.H, n = z.n, m = z.m;
  check_shape(lxx, {H, n, n}, "lxx");
  check_shape(lux, {H, m, n}, "lux");
  check_shape(luu, {H, m, m}, "luu");
  check_shape(Vx_final, {n}, "Vx_final");
  check_shape(Vxx_final, {n, n}, "Vxx_final");
  return {H, n, m};
}

// The gains every pass writes: k_ff (H, m), K_fb (H, m, n), quu_eig (H,).
inline void check_gain_outputs(const py::array& k_ff, const py::array& K_fb, const py::array& quu_eig,
                               const PassSizes& z) {
  check_output(k_ff, {z.H, z.m}, "k_ff");
  check_output(K_fb, {z.H, z.m, z.n}, "K_fb");
  check_output(quu_eig, {z.H}, "quu_eig");
}

// The box-constrained passes' extra arrays: u_bar, lower, upper (H, m) in; active (H, m) int8,
// Vx0 (n,), Vxx0 (n, n) out.
inline void check_box_arrays(const Arr& u_bar, const Arr& lower, const Arr& upper, const py::array& active,
                             const py::array& Vx0, const py::array& Vxx0, const PassSizes& z) {
  check_shape(u_bar, {z.H, z.m}, "u_bar");
  check_shape(lower, {z.H, z.m}, "lower");
  check_shape(upper, {z.H, z.m}, "upper");
  check_output(active, {z.H, z.m}, "active");
  check_output(Vx0, {z.n}, "Vx0");
  check_output(Vxx0, {z.n, z.n}, "Vxx0");
}

// The backward passes' worker count: 0 (the core chooses by measurement), 1 or 2.
inline void check_workers(int workers) {
  if (workers < 0 || workers > 2) throw py::value_error("workers: expected 0 (choose), 1 or 2");
}

}  // namespace bind
}  // namespace geoddp
