// Minimal data parallelism over an index range, used by batched passes.
// Deterministic: the range is split into contiguous chunks by n and
// NumThreads() alone (up to 4 chunks a thread), each chunk writes only its
// own outputs, and which thread runs a chunk does not matter. The chunks run
// on a persistent pool of NumThreads() - 1 workers plus the calling thread,
// each taking the next unclaimed chunk; a ParallelFor called from inside a
// chunk (or while another thread's call holds the pool) runs its chunks in
// turn on the calling thread. An exception thrown by a chunk is rethrown by
// ParallelFor once every chunk has finished.
#pragma once

#include <functional>

namespace banmo {

// Number of worker threads used by ParallelFor (default: hardware threads).
int NumThreads();
void SetNumThreads(int num_threads);

// Calls fn(begin, end) on disjoint contiguous chunks covering [0, n);
// fn may run concurrently on distinct chunks.
void ParallelFor(int n, const std::function<void(int begin, int end)>& fn);

}  // namespace banmo
