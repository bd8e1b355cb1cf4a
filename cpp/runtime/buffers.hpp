// Recycled float64 buffers for the large per-linearisation arrays (dynamics/second_order_terms.hpp).
//
// Every exact linearisation makes a new set of factored second-order terms of the same sizes
// (4 nv^3 doubles per node). Fresh megabytes from the system cost page faults and the kernel's
// zeroing, about as much as filling them, so a released buffer waits in a small pool (at most 20
// buffers, 512 MB in all) for the next request of its size. The memory is uninitialised: every
// entry is written before it is read.
#pragma once

#include <cstddef>

namespace geoddp {

// n doubles (nullptr for 0), from the pool if it holds a buffer of exactly that size.
double* buffer_take(size_t n);
// Back to the pool (the oldest are freed beyond its limits); p may be nullptr.
void buffer_give(double* p, size_t n);

// An owning handle: resize() gives the old memory back and takes a buffer of the new size.
struct Buffer {
  double* p = nullptr;
  size_t n = 0;
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer() { buffer_give(p, n); }
  void resize(size_t k) {
    if (k == n) return;
    buffer_give(p, n);
    p = buffer_take(k);
    n = k;
  }
  double* data() { return p; }
  const double* data() const { return p; }
  size_t size() const { return n; }
};

}  // namespace geoddp
