// SPDX-License-Identifier: MIT
// A fixed pool of worker threads for data-parallel loops (tiles, Gaussian ranges). Work items are
// claimed from an atomic counter; a job is a plain function pointer + context, so dispatching a
// loop allocates nothing after the pool is built.
#pragma once

#include <cstddef>

namespace gs::platform {

// Called as fn(ctx, begin, end, worker_index) for disjoint [begin, end) chunks of the range.
using RangeFn = void (*)(void* ctx, size_t begin, size_t end, int worker);

class ThreadPool {
 public:
  // num_threads <= 0: the CPUs this process may run on. The calling thread counts as one of the
  // workers, so num_threads - 1 threads are started here (fewer if the OS refuses; see num_threads()).
  explicit ThreadPool(int num_threads = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int num_threads() const;
  // Runs fn over [0, n) in chunks of at most `grain` items (grain 0 means 1); returns when every
  // chunk is done. worker is in [0, num_threads()); the calling thread is worker 0, so per-worker
  // scratch indexed by it is never used by two threads at once. Allocates nothing.
  // - Nested calls (fn calling parallel_for on the same pool) run serially inline on the calling
  //   thread with its own worker index: correct, but not parallel.
  // - Calls from several threads are serialised: a second caller blocks until the first finishes.
  // - Not supported: cycles across pools (a job of A waits on B while a job of B waits on A) can
  //   deadlock. fn must not throw on a worker thread (std::terminate); if it throws on the calling
  //   thread the call waits for the other workers, then rethrows.
  void parallel_for(size_t n, size_t grain, RangeFn fn, void* ctx);

  // Convenience for lambdas: the lambda must outlive the call (it does: we block).
  template <class F>
  void parallel_for(size_t n, size_t grain, F& f) {
    parallel_for(n, grain, [](void* c, size_t b, size_t e, int w) { (*static_cast<F*>(c))(b, e, w); }, &f);
  }
  // fn(i) for each i in [0, n), items claimed one at a time (uneven items balance themselves).
  template <class F>
  void for_each_index(size_t n, F&& fn) {
    auto items = [&fn](size_t begin, size_t end, int) {
      for (size_t i = begin; i < end; ++i) fn(i);
    };
    parallel_for(n, 1, items);
  }

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace gs::platform
