// A persistent worker pool for the per-node kernels: parallel_for used to start and join
// std::threads on every call (about the cost of a first-order node's work each, so first-order
// passes ran on one thread); the pool's workers wait on a condition variable between calls.
//
// * One dispatch at a time (a mutex): kernels may be called from several Python threads, the GIL
//   being released while they run.
// * Fork safety: a child process (multiprocessing, dask) inherits the pool object but not its
//   threads, so the pool records the pid that created it and a child builds a fresh one (the
//   parent's copy is abandoned, never touched: its mutexes may have been held at the fork).
// * The pool is never destroyed: its workers block forever and end with the process (joining them
//   from a static destructor during interpreter shutdown could deadlock).
#pragma once

#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace geoddp {

class WorkerPool {
 public:
  // Runs task(worker) for worker = 0 .. T-1, worker 0 on the calling thread; returns when all
  // are done and rethrows the first exception of any of them.
  void run(int T, const std::function<void(int)>& task) {
    if (T <= 1) {
      task(0);
      return;
    }
    std::lock_guard<std::mutex> one_dispatch(dispatch_);
    {
      std::lock_guard<std::mutex> lk(m_);
      while ((int)workers_.size() < T - 1) {
        const int id = (int)workers_.size() + 1;
        workers_.emplace_back([this, id]() { loop(id); });
        workers_.back().detach();
      }
      task_ = &task;
      active_ = T;
      pending_ = T - 1;
      errors_.assign(T, nullptr);
      ++generation_;
    }
    wake_.notify_all();
    try {
      task(0);
    } catch (...) {
      errors_[0] = std::current_exception();
    }
    {
      std::unique_lock<std::mutex> lk(m_);
      done_.wait(lk, [this]() { return pending_ == 0; });
      task_ = nullptr;
    }
    for (auto& e : errors_)
      if (e) std::rethrow_exception(e);
  }

  // The process's pool (a new one in a forked child).
  static WorkerPool& get() {
    static std::mutex guard;
    static WorkerPool* pool = nullptr;
    std::lock_guard<std::mutex> lk(guard);
    if (pool == nullptr || pool->pid_ != getpid()) pool = new WorkerPool();  // the parent's is abandoned
    return *pool;
  }

 private:
  WorkerPool() : pid_(getpid()) {}

  void loop(int id) {
    std::uint64_t seen = 0;
    std::unique_lock<std::mutex> lk(m_);
    for (;;) {
      wake_.wait(lk, [&]() { return generation_ != seen; });
      seen = generation_;
      if (id >= active_) continue;
      const std::function<void(int)>* task = task_;
      lk.unlock();
      try {
        (*task)(id);
      } catch (...) {
        errors_[id] = std::current_exception();
      }
      lk.lock();
      if (--pending_ == 0) done_.notify_one();
    }
  }

  pid_t pid_;
  std::mutex dispatch_, m_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> workers_;
  const std::function<void(int)>* task_ = nullptr;
  int active_ = 0, pending_ = 0;
  std::vector<std::exception_ptr> errors_;
  std::uint64_t generation_ = 0;
};

}  // namespace geoddp
