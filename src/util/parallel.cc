#include "banmo/util/parallel.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace banmo {
namespace {
std::atomic<int> g_num_threads{0};

// Set on the pool's workers and, while it runs a call's chunks, on the
// calling thread: a ParallelFor from inside a chunk runs its chunks in turn
// on that thread (the pool is busy with the outer call).
thread_local bool t_inside_parallel_for = false;

// Chunks per thread of a call: more chunks than threads, claimed in turn by
// whichever thread is free, so that uneven chunks (rays of different cost,
// videos of different length) do not leave a core idle at the join. The
// split itself is fixed by n and the thread count only (see parallel.h).
constexpr int kChunksPerThread = 4;

// A fixed set of worker threads, created once per thread count: a
// std::thread per call cost about 0.2 ms a call in thread creation and join
// (about 50 calls a batch in the solver).
class Pool {
 public:
  explicit Pool(int workers) {
    threads_.reserve(workers);
    for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { WorkerLoop(); });
  }
  ~Pool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  int workers() const { return static_cast<int>(threads_.size()); }

  // Runs chunk(c) for c in [0, num_chunks) on the workers and the calling
  // thread; returns when all are done; rethrows the first exception.
  void Run(int num_chunks, const std::function<void(int)>& chunk) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      chunk_ = &chunk;
      num_chunks_ = num_chunks;
      next_.store(0);
      busy_ = workers();
      error_ = nullptr;
      ++generation_;
    }
    wake_.notify_all();
    t_inside_parallel_for = true;
    Claim();
    t_inside_parallel_for = false;
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return busy_ == 0; });
    chunk_ = nullptr;
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void Claim() {
    for (int c = next_.fetch_add(1); c < num_chunks_; c = next_.fetch_add(1)) {
      try {
        (*chunk_)(c);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
      }
    }
  }
  void WorkerLoop() {
    t_inside_parallel_for = true;
    long seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
      }
      Claim();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (--busy_ == 0) done_.notify_one();
      }
    }
  }

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void(int)>* chunk_ = nullptr;
  int num_chunks_ = 0;
  std::atomic<int> next_{0};
  int busy_ = 0;
  long generation_ = 0;
  bool stop_ = false;
  std::exception_ptr error_;
};

// The pool of the current thread count, and who may use it: one call at a
// time (a second thread calling ParallelFor meanwhile runs its chunks itself).
// A forked child (e.g. a GoogleTest death test) inherits the pool but not its
// threads: it leaves the parent's pool alone (never joins or locks it) and
// makes its own.
std::mutex g_pool_mutex;
std::unique_ptr<Pool> g_pool;
pid_t g_pool_pid = 0;
}  // namespace

int NumThreads() {
  const int n = g_num_threads.load();
  if (n > 0) return n;
  return std::max(1u, std::thread::hardware_concurrency());
}

void SetNumThreads(int num_threads) { g_num_threads = std::max(1, num_threads); }

void ParallelFor(int n, const std::function<void(int, int)>& fn) {
  if (n <= 0) return;
  const int threads = NumThreads();
  if (threads == 1 || n == 1) {
    fn(0, n);
    return;
  }
  // Fixed split: num_chunks contiguous chunks of size or size + 1 (the first
  // `extra` ones larger), whoever runs them.
  const int num_chunks = std::min(n, threads * kChunksPerThread);
  const int size = n / num_chunks;
  const int extra = n % num_chunks;
  const std::function<void(int)> chunk = [&](int c) {
    const int begin = c * size + std::min(c, extra);
    fn(begin, begin + size + (c < extra ? 1 : 0));
  };
  std::unique_lock<std::mutex> lock(g_pool_mutex, std::defer_lock);
  if (t_inside_parallel_for || !lock.try_lock()) {
    for (int c = 0; c < num_chunks; ++c) chunk(c);
    return;
  }
  if (g_pool && g_pool_pid != getpid()) {
    static_cast<void>(g_pool.release());  // the parent's; its threads are not ours
  }
  if (!g_pool || g_pool->workers() != threads - 1) {
    g_pool.reset();
    g_pool = std::make_unique<Pool>(threads - 1);
    g_pool_pid = getpid();
  }
  g_pool->Run(num_chunks, chunk);
}

}  // namespace banmo
