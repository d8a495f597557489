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
  // num_threads <= 0: hardware concurrency. The calling thread counts as one of the workers.
  explicit ThreadPool(int num_threads = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int num_threads() const;
  // Runs fn over [0, n) in chunks of `grain` items; returns when every chunk is done.
  void parallel_for(size_t n, size_t grain, RangeFn fn, void* ctx);

  // Convenience for lambdas: the lambda must outlive the call (it does: we block).
  template <class F>
  void parallel_for(size_t n, size_t grain, F& f) {
    parallel_for(n, grain, [](void* c, size_t b, size_t e, int w) { (*static_cast<F*>(c))(b, e, w); }, &f);
  }

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace gs::platform
