// A persistent worker pool for the per-node kernels (runtime/parallel.hpp splits the nodes): starting
// and joining std::threads on every call costs about a first-order node's work, so the workers live
// and wait between calls.
//
// * Spin, then sleep. A DDP iteration calls the kernels back to back (expansion, costs, passes,
//   with the sequential rollouts of the line search and some Python between them), a fraction of a
//   millisecond apart, and a worker blocked on a condition variable takes tens of microseconds to
//   wake, as long as a small pass. So after each task a worker (and a caller waiting for its
//   workers) polls an atomic counter with the CPU's pause hint for up to spin_microseconds()
//   (GEODDP_SPIN_US, default 1000 us; 0: sleep at once) before it blocks, as OpenMP runtimes do
//   (libgomp's GOMP_SPINCOUNT, Crocoddyl's threads); the results are bitwise the same either way
//   (tests/test_core_contracted.py; benchmarks/pool_spin.py times the settings). The cost: the idle
//   worker keeps a core busy for up to that long after each call; on a machine shared with other
//   work set GEODDP_SPIN_US=0 (a sweep's workers run one thread each and never spin).
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
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace geoddp {

// How long an idle worker (or a caller waiting for its workers) polls before it sleeps, in
// microseconds: GEODDP_SPIN_US (an integer 0..SPIN_US_MAX), read once at the first use, default
// SPIN_US_DEFAULT; set_spin_microseconds changes it (geoddp._core.set_spin_microseconds:
// benchmarks compare settings in one process). geoddp.validate.SPIN_US_MAX is the Python twin of
// the bound (tests/test_core_contracted.py checks they agree).
constexpr int SPIN_US_DEFAULT = 1000, SPIN_US_MAX = 100000;
inline std::atomic<int>& spin_setting() {
  static std::atomic<int> us{[]() {
    const char* env = std::getenv("GEODDP_SPIN_US");
    if (env == nullptr || *env == '\0') return SPIN_US_DEFAULT;
    char* end = nullptr;
    const long v = std::strtol(env, &end, 10);
    if (*end != '\0' || v < 0 || v > SPIN_US_MAX) return SPIN_US_DEFAULT;  // geoddp.validate refuses it first
    return (int)v;
  }()};
  return us;
}
inline int spin_microseconds() { return spin_setting().load(std::memory_order_relaxed); }
inline void set_spin_microseconds(int us) { spin_setting().store(us, std::memory_order_relaxed); }

// Polls done() with the pause hint until it is true or spin_microseconds() have passed; returns
// done()'s last value. The clock is read every 64 polls (a read costs ~20 ns, a pause ~10-40).
template <typename Done>
inline bool spin_until(Done&& done) {
  const int us = spin_microseconds();
  if (us <= 0) return done();
  const auto end = std::chrono::steady_clock::now() + std::chrono::microseconds(us);
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (done()) return true;
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    }
    if (std::chrono::steady_clock::now() >= end) return done();
  }
}

class WorkerPool {
 public:
  // Runs task(worker) for worker = 0 .. T-1, worker 0 on the calling thread; returns when all
  // are done and rethrows the first exception of any of them.
  void run(int T, const std::function<void(int)>& task) {
    if (T <= 1) {
      task(0);
      return;
    }
    if (T > 0xffff) throw std::invalid_argument("threads: expected at most 65535 workers, got " + std::to_string(T));
    std::lock_guard<std::mutex> one_dispatch(dispatch_);
    bool wake = false;
    {
      // the post moves under m_, so a worker deciding to sleep (predicate checked under m_)
      // either sees the new task or is asleep when it is notified: no lost wake-up
      std::lock_guard<std::mutex> lk(m_);
      while ((int)workers_.size() < T - 1) {
        const int id = (int)workers_.size() + 1;
        workers_.emplace_back([this, id]() { loop(id); });
        workers_.back().detach();
      }
      task_ = &task;
      errors_.assign(T, nullptr);
      pending_.store(T - 1, std::memory_order_relaxed);
      // one atomic word holds the dispatch's number and its worker count, so a worker that was not
      // part of the last dispatch never pairs one dispatch's count with another's number
      const std::uint64_t number = (posted_.load(std::memory_order_relaxed) >> 16) + 1;
      posted_.store((number << 16) | (std::uint64_t)T, std::memory_order_release);
      wake = sleepers_ > 0;
    }
    if (wake) wake_.notify_all();
    try {
      task(0);
    } catch (...) {
      errors_[0] = std::current_exception();
    }
    const auto finished = [this]() { return pending_.load(std::memory_order_acquire) == 0; };
    if (!spin_until(finished)) {
      std::unique_lock<std::mutex> lk(m_);
      done_.wait(lk, finished);
    }
    task_ = nullptr;
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
    for (;;) {
      const auto posted = [&]() { return posted_.load(std::memory_order_acquire) != seen; };
      if (!spin_until(posted)) {
        std::unique_lock<std::mutex> lk(m_);
        ++sleepers_;
        wake_.wait(lk, posted);
        --sleepers_;
      }
      seen = posted_.load(std::memory_order_acquire);
      // not part of this dispatch (it asked for fewer workers than the pool has): the caller does
      // not wait for this worker, which reads nothing else
      if (id >= (int)(seen & 0xffff)) continue;
      // task_ and errors_ were written before the post (release/acquire), and stay until this
      // worker has counted itself off below
      const std::function<void(int)>* task = task_;
      try {
        (*task)(id);
      } catch (...) {
        errors_[id] = std::current_exception();
      }
      if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        // the caller may be asleep on done_: take m_ so that it is either before its predicate
        // check (and sees pending_ == 0) or waiting (and is notified)
        { std::lock_guard<std::mutex> lk(m_); }
        done_.notify_one();
      }
    }
  }

  pid_t pid_;
  std::mutex dispatch_, m_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> workers_;
  const std::function<void(int)>* task_ = nullptr;
  int sleepers_ = 0;
  std::atomic<int> pending_{0};
  std::vector<std::exception_ptr> errors_;
  std::atomic<std::uint64_t> posted_{0};  // (dispatch number << 16) | its worker count
};

}  // namespace geoddp
