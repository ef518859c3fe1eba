// Minimal data parallelism over an index range (std::thread based), used by
// batched passes. Deterministic: the range is split into contiguous chunks in
// a fixed way, and each chunk writes only its own outputs.
#pragma once

#include <functional>

namespace banmo {

// Number of worker threads used by ParallelFor (default: hardware threads).
int NumThreads();
void SetNumThreads(int num_threads);

// Calls fn(begin, end) on disjoint contiguous chunks covering [0, n).
void ParallelFor(int n, const std::function<void(int begin, int end)>& fn);

}  // namespace banmo
