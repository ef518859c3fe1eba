#include "banmo/util/parallel.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace banmo {
namespace {
std::atomic<int> g_num_threads{0};
}  // namespace

int NumThreads() {
  const int n = g_num_threads.load();
  if (n > 0) return n;
  return std::max(1u, std::thread::hardware_concurrency());
}

void SetNumThreads(int num_threads) { g_num_threads = std::max(1, num_threads); }

void ParallelFor(int n, const std::function<void(int, int)>& fn) {
  if (n <= 0) return;
  const int threads = std::min(NumThreads(), n);
  if (threads == 1) {
    fn(0, n);
    return;
  }
  std::vector<std::thread> workers;
  workers.reserve(threads - 1);
  const int chunk = (n + threads - 1) / threads;
  for (int t = 1; t < threads; ++t) {
    const int begin = t * chunk;
    const int end = std::min(n, begin + chunk);
    if (begin < end) workers.emplace_back(fn, begin, end);
  }
  fn(0, std::min(n, chunk));
  for (auto& w : workers) w.join();
}

}  // namespace banmo
