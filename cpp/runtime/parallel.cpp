// The node split's defaults (see parallel.hpp).
#include "runtime/parallel.hpp"

#include <algorithm>
#include <thread>

#ifdef __linux__
#include <sched.h>
#endif

namespace geoddp {

int default_threads() {
  // One worker per core, at most two (the count the kernels are tuned for). The cores this process may run on
  // are its affinity mask (taskset, a container's cpuset), not the machine's count: two workers on one
  // allowed core time-slice, and the two-worker backward pass (riccati/contracted.cpp) then waits a scheduler
  // slice per node. Read once: glibc's hardware_concurrency reads /sys on every call, which every kernel call
  // with threads <= 0 would pay.
  static const int workers = []() {
    int n = 0;
#ifdef __linux__
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof(set), &set) == 0) n = CPU_COUNT(&set);
#endif
    if (n <= 0) n = (int)std::thread::hardware_concurrency();
    return n <= 0 ? 1 : std::min(n, 2);
  }();
  return workers;
}

// A first-order node costs about as much as waking a pooled worker, so the default gives each
// worker at least this many nodes.
static const int MIN_NODES_PER_WORKER = 16;

int node_workers(int N, int threads) {
  const int T = threads > 0 ? threads : std::min(default_threads(), std::max(1, N / MIN_NODES_PER_WORKER));
  return std::max(1, std::min(T, N));
}

void parallel_nodes(int N, int threads, const std::function<void(int, int)>& fn) {
  parallel_for(N, threads, [&](int b, int e, int) { fn(b, e); });
}

void parallel_nodes_indexed(int N, int threads, const std::function<void(int, int, int)>& fn) {
  parallel_for(N, threads, fn);
}

}  // namespace geoddp
