// The per-node kernels' split of N nodes over the persistent pool's workers (runtime/pool.hpp).
//
// Nodes go to workers in contiguous chunks that depend only on N and the worker count, and each
// node's arithmetic is the same on any worker, so no result depends on the number of threads
// (tested).
#pragma once

#include <functional>

#include "runtime/pool.hpp"

namespace geoddp {

// Worker threads of a pass when threads <= 0 ("default"): min(2, cores in the process's affinity
// mask).
int default_threads();

// How many workers a pass over N nodes uses (per-worker scratch is sized by it): `threads` if > 0,
// else default_threads() but at least 16 nodes a worker; never more than N.
int node_workers(int N, int threads);

// Runs fn(begin, end, worker) on contiguous chunks of [0, N) with node_workers(N, threads) workers
// of the pool (on the calling thread alone when that is one).
template <typename Fn>
inline void parallel_for(int N, int threads, Fn fn) {
  const int T = node_workers(N, threads);
  if (T == 1) {
    fn(0, N, 0);
    return;
  }
  const std::function<void(int)> task = [&](int t) {
    const int b = (int)((long)N * t / T), e = (int)((long)N * (t + 1) / T);
    fn(b, e, t);
  };
  WorkerPool::get().run(T, task);
}

// parallel_for behind a std::function, for kernels outside this translation unit: fn(begin, end),
// or fn(begin, end, worker) with worker in 0 .. node_workers(N, threads) - 1.
void parallel_nodes(int N, int threads, const std::function<void(int, int)>& fn);
void parallel_nodes_indexed(int N, int threads, const std::function<void(int, int, int)>& fn);

}  // namespace geoddp
