// The pool behind Buffer (see buffers.hpp).
#include "runtime/buffers.hpp"

#include <mutex>
#include <utility>
#include <vector>

namespace geoddp {

// At most POOL_BUFFERS released buffers and POOL_BYTES in all (the tensors and blocks of one set of
// factored terms, and a second set for a linearisation still alive), taken back by exact size;
// anything beyond is freed. Never destroyed: Python may release its last terms after static
// destructors have run.
namespace {
constexpr size_t POOL_BUFFERS = 20;
constexpr size_t POOL_BYTES = size_t(512) << 20;
struct Pool {
  std::mutex mutex;
  std::vector<std::pair<size_t, double*>> free;  // (doubles, memory), oldest first
  size_t doubles = 0;
};
Pool& pool() {
  static Pool* p = new Pool;
  return *p;
}
}  // namespace

double* buffer_take(size_t n) {
  if (n == 0) return nullptr;
  Pool& P = pool();
  {
    std::lock_guard<std::mutex> lock(P.mutex);
    for (size_t i = P.free.size(); i-- > 0;)
      if (P.free[i].first == n) {
        double* p = P.free[i].second;
        P.free.erase(P.free.begin() + i);
        P.doubles -= n;
        return p;
      }
  }
  return new double[n];
}

void buffer_give(double* p, size_t n) {
  if (!p) return;
  Pool& P = pool();
  std::vector<double*> drop;
  {
    std::lock_guard<std::mutex> lock(P.mutex);
    P.free.emplace_back(n, p);
    P.doubles += n;
    while (!P.free.empty() && (P.free.size() > POOL_BUFFERS || P.doubles * sizeof(double) > POOL_BYTES)) {
      drop.push_back(P.free.front().second);  // the oldest go first
      P.doubles -= P.free.front().first;
      P.free.erase(P.free.begin());
    }
  }
  for (double* d : drop) delete[] d;
}

}  // namespace geoddp
