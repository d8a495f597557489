// SPDX-License-Identifier: MIT
// A minimal parallel-for over [0, n) with std::thread. Work items are claimed dynamically, so
// callers must make each item's output depend only on its index (that keeps results independent
// of the thread count).
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace hbgs::synth::detail {

inline int resolve_threads(int requested) {
  if (requested > 0) return requested;
  unsigned hw = std::thread::hardware_concurrency();
  return hw ? int(hw) : 1;
}

template <class F>
void parallel_for(int n, int threads, F&& fn) {
  int workers = std::max(1, std::min(resolve_threads(threads), n));
  std::atomic<int> next{0};
  auto run = [&] {
    for (int i = next.fetch_add(1); i < n; i = next.fetch_add(1)) fn(i);
  };
  if (workers == 1) {
    run();
    return;
  }
  std::vector<std::thread> pool;
  pool.reserve(size_t(workers - 1));
  try {
    for (int w = 1; w < workers; ++w) pool.emplace_back(run);
  } catch (...) {
    // Could not start a thread (resource limits): the threads already running and this one
    // still drain the whole range.
  }
  run();
  for (auto& t : pool) t.join();
}

}  // namespace hbgs::synth::detail
