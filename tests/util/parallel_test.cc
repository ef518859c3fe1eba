#include "banmo/util/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <mutex>
#include <utility>
#include <vector>

namespace banmo {
namespace {

// Restores the thread count of the process after a test changes it.
class ThreadCountGuard {
 public:
  ThreadCountGuard() : saved_(NumThreads()) {}
  ~ThreadCountGuard() { SetNumThreads(saved_); }

 private:
  int saved_;
};

TEST(ParallelFor, ChunksAreDisjointContiguousAndCoverTheRange) {
  ThreadCountGuard guard;
  for (int threads : {1, 2, 3, 8}) {
    SetNumThreads(threads);
    for (int n : {0, 1, 2, 7, 100, 1001}) {
      std::vector<int> hits(n, 0);
      std::mutex mutex;
      std::vector<std::pair<int, int>> chunks;
      ParallelFor(n, [&](int begin, int end) {
        ASSERT_LE(0, begin);
        ASSERT_LT(begin, end);
        ASSERT_LE(end, n);
        for (int i = begin; i < end; ++i) ++hits[i];
        std::lock_guard<std::mutex> lock(mutex);
        chunks.emplace_back(begin, end);
      });
      for (int i = 0; i < n; ++i) EXPECT_EQ(hits[i], 1) << "n " << n << " i " << i;
      EXPECT_LE(static_cast<int>(chunks.size()), std::max(threads, 1)) << "n " << n;
    }
  }
}

TEST(ParallelFor, SplitIsDeterministic) {
  ThreadCountGuard guard;
  SetNumThreads(4);
  auto split = [] {
    std::vector<std::pair<int, int>> chunks;
    std::mutex mutex;
    ParallelFor(103, [&](int begin, int end) {
      std::lock_guard<std::mutex> lock(mutex);
      chunks.emplace_back(begin, end);
    });
    std::sort(chunks.begin(), chunks.end());
    return chunks;
  };
  EXPECT_EQ(split(), split());
}

TEST(SetNumThreads, IsReadBack) {
  ThreadCountGuard guard;
  SetNumThreads(3);
  EXPECT_EQ(NumThreads(), 3);
}

}  // namespace
}  // namespace banmo
