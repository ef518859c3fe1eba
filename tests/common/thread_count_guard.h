// Test helper: restores the process's ParallelFor thread count on scope exit.
#pragma once

#include "banmo/util/parallel.h"

namespace banmo {
namespace testing {

// Restores the thread count of the process after a test changes it (also
// when an ASSERT returns early).
class ThreadCountGuard {
 public:
  ThreadCountGuard() : saved_(NumThreads()) {}
  ~ThreadCountGuard() { SetNumThreads(saved_); }
  ThreadCountGuard(const ThreadCountGuard&) = delete;
  ThreadCountGuard& operator=(const ThreadCountGuard&) = delete;

 private:
  int saved_;
};

}  // namespace testing
}  // namespace banmo
