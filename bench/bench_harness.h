// SPDX-License-Identifier: MIT
// Header-only timing harness for the benchmarks: warm-up runs, then N timed repetitions (optionally
// cut short by a time budget), reported as min / median / mean / max in milliseconds. The minimum
// is the least noisy figure on a shared machine; the median is what a user sees. Process CPU time
// is recorded too: on a busy machine it stays close to the work done while wall time inflates.
#pragma once

#include <time.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/platform/clock.h"

namespace gs::bench {

struct Timing {
  int reps = 0;  // timed repetitions actually run
  double min_ms = 0, median_ms = 0, mean_ms = 0, max_ms = 0;
  double cpu_median_ms = 0;  // process CPU time (all threads) of the median-CPU repetition
};

using gs::platform::process_cpu_seconds;  // CPU time of this process, all threads, seconds

struct HarnessOptions {
  int warmup = 1;          // untimed runs first (page faults, caches, branch predictors)
  int reps = 5;            // timed repetitions wanted
  int min_reps = 2;        // ... but at least this many even when over budget
  double max_seconds = 0;  // > 0: stop adding repetitions once this much time has been spent timing
};

inline Timing summarize(std::vector<double> ms, std::vector<double> cpu_ms = {}) {
  Timing t;
  if (!cpu_ms.empty()) {
    std::sort(cpu_ms.begin(), cpu_ms.end());
    const size_t c = cpu_ms.size();
    t.cpu_median_ms = c % 2 ? cpu_ms[c / 2] : 0.5 * (cpu_ms[c / 2 - 1] + cpu_ms[c / 2]);
  }
  t.reps = int(ms.size());
  if (ms.empty()) return t;
  std::sort(ms.begin(), ms.end());
  t.min_ms = ms.front();
  t.max_ms = ms.back();
  const size_t n = ms.size();
  t.median_ms = n % 2 ? ms[n / 2] : 0.5 * (ms[n / 2 - 1] + ms[n / 2]);
  double sum = 0;
  for (double v : ms) sum += v;
  t.mean_ms = sum / double(n);
  return t;
}

// Times f() (one call per repetition).
template <class F>
Timing measure(F&& f, const HarnessOptions& opt = {}) {
  for (int i = 0; i < opt.warmup; ++i) f();
  std::vector<double> ms, cpu_ms;
  ms.reserve(size_t(std::max(opt.reps, 1)));
  cpu_ms.reserve(size_t(std::max(opt.reps, 1)));
  double spent = 0;
  for (int i = 0; i < std::max(opt.reps, 1); ++i) {
    if (opt.max_seconds > 0 && i >= opt.min_reps && spent >= opt.max_seconds) break;
    const double c0 = process_cpu_seconds();
    const uint64_t t0 = platform::now_ns();
    f();
    const uint64_t t1 = platform::now_ns();
    cpu_ms.push_back((process_cpu_seconds() - c0) * 1e3);
    ms.push_back(double(t1 - t0) * 1e-6);
    spent += double(t1 - t0) * 1e-9;
  }
  return summarize(std::move(ms), std::move(cpu_ms));
}

// For calls far shorter than the clock's resolution: each repetition runs f() `batch` times, where
// batch is calibrated so one repetition takes at least min_rep_seconds; reports time per call.
template <class F>
Timing measure_batched(F&& f, const HarnessOptions& opt = {}, double min_rep_seconds = 2e-3, int64_t* batch_out = nullptr) {
  for (int i = 0; i < opt.warmup; ++i) f();
  int64_t batch = 1;
  for (;;) {
    const uint64_t t0 = platform::now_ns();
    for (int64_t k = 0; k < batch; ++k) f();
    const double s = double(platform::now_ns() - t0) * 1e-9;
    if (s >= min_rep_seconds || batch >= (int64_t(1) << 30)) break;
    batch = s <= 0 ? batch * 16 : std::max(batch * 2, int64_t(double(batch) * 1.2 * min_rep_seconds / s));
  }
  if (batch_out) *batch_out = batch;
  auto once = [&] {
    for (int64_t k = 0; k < batch; ++k) f();
  };
  HarnessOptions o = opt;
  o.warmup = 0;
  Timing t = measure(once, o);
  const double inv = 1.0 / double(batch);
  t.min_ms *= inv;
  t.median_ms *= inv;
  t.mean_ms *= inv;
  t.max_ms *= inv;
  t.cpu_median_ms *= inv;
  return t;
}

}  // namespace gs::bench
