#include "banmo/util/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "../common/thread_count_guard.h"

namespace banmo {
namespace {

using testing::ThreadCountGuard;

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
      // Up to 4 chunks a thread (parallel.h), never more than n.
      EXPECT_LE(static_cast<int>(chunks.size()), std::min(std::max(n, 1), 4 * threads))
          << "n " << n;
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

// The split depends on n and the thread count only, not on which thread ran
// which chunk: the same chunks from the pool, from inside another call's
// chunk (nested calls run in turn on the caller) and from a second thread
// calling while the pool is busy.
std::vector<std::pair<int, int>> Split(int n) {
  std::vector<std::pair<int, int>> chunks;
  std::mutex mutex;
  ParallelFor(n, [&](int begin, int end) {
    std::lock_guard<std::mutex> lock(mutex);
    chunks.emplace_back(begin, end);
  });
  std::sort(chunks.begin(), chunks.end());
  return chunks;
}

TEST(ParallelFor, NestedAndConcurrentCallsSplitAlike) {
  ThreadCountGuard guard;
  SetNumThreads(2);
  const std::vector<std::pair<int, int>> reference = Split(103);
  ASSERT_EQ(reference.size(), 8u);  // 4 chunks a thread
  std::vector<std::vector<std::pair<int, int>>> nested(5);
  ParallelFor(5, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) nested[i] = Split(103);
  });
  for (const auto& chunks : nested) EXPECT_EQ(chunks, reference);
  std::vector<std::vector<std::pair<int, int>>> concurrent(4);
  std::vector<std::thread> callers;
  for (auto& out : concurrent) {
    callers.emplace_back([&out] {
      for (int repeat = 0; repeat < 50; ++repeat) out = Split(103);
    });
  }
  for (std::thread& t : callers) t.join();
  for (const auto& chunks : concurrent) EXPECT_EQ(chunks, reference);
}

TEST(ParallelFor, RethrowsAChunksExceptionAfterEveryChunkFinished) {
  ThreadCountGuard guard;
  SetNumThreads(2);
  std::atomic<int> ran{0};
  EXPECT_THROW(ParallelFor(64,
                           [&](int begin, int end) {
                             ran += end - begin;
                             if (begin == 0) throw std::runtime_error("chunk 0");
                           }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 64);
  // The pool still works afterwards.
  std::atomic<int> sum{0};
  ParallelFor(1000, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) sum += i;
  });
  EXPECT_EQ(sum.load(), 999 * 1000 / 2);
}

TEST(ParallelFor, FollowsAChangeOfThreadCount) {
  ThreadCountGuard guard;
  for (int threads : {3, 1, 2, 4}) {
    SetNumThreads(threads);
    std::mutex mutex;
    std::vector<std::thread::id> ids;
    ParallelFor(400, [&](int, int) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      std::lock_guard<std::mutex> lock(mutex);
      ids.push_back(std::this_thread::get_id());
    });
    std::sort(ids.begin(), ids.end());
    const int distinct = static_cast<int>(std::unique(ids.begin(), ids.end()) - ids.begin());
    EXPECT_LE(distinct, threads) << threads;
    EXPECT_EQ(static_cast<int>(ids.size()), threads == 1 ? 1 : 4 * threads) << threads;
  }
}

// A death test forks: the child has the parent's pool but none of its
// threads, and must still finish its ParallelFor.
TEST(ParallelForDeathTest, WorksInAForkedChild) {
  ThreadCountGuard guard;
  SetNumThreads(2);
  std::atomic<int> sum{0};
  ParallelFor(100, [&](int begin, int end) { sum += end - begin; });  // the parent's pool
  ASSERT_EQ(sum.load(), 100);
  EXPECT_DEATH(
      {
        std::atomic<int> child{0};
        ParallelFor(100, [&](int begin, int end) { child += end - begin; });
        if (child.load() == 100) std::abort();
      },
      "");
}

TEST(SetNumThreads, IsReadBack) {
  ThreadCountGuard guard;
  SetNumThreads(3);
  EXPECT_EQ(NumThreads(), 3);
}

}  // namespace
}  // namespace banmo
