// SPDX-License-Identifier: MIT
// measure_machine_peaks (machine_peaks.h): the per-ISA FMA loops of peak_fma__<isa>.cpp and a
// memcpy bandwidth loop, each timed on one thread and on all pool threads.
#include "machine_peaks.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <vector>

#include "gs/platform/clock.h"
#include "gs/platform/thread_pool.h"

namespace gs::bench {
namespace peak {
#if GS_PEAK_HAVE_SSE2
uint64_t fma_loop_sse2(uint64_t steps, float* sink);
#endif
#if GS_PEAK_HAVE_AVX2
uint64_t fma_loop_avx2(uint64_t steps, float* sink);
#endif
#if GS_PEAK_HAVE_AVX512
uint64_t fma_loop_avx512(uint64_t steps, float* sink);
#endif
#if GS_PEAK_HAVE_NEON64
uint64_t fma_loop_neon64(uint64_t steps, float* sink);
#endif
}  // namespace peak

namespace {

using FmaLoop = uint64_t (*)(uint64_t, float*);

FmaLoop fma_loop_for(const std::string& isa, std::string* used) {
  *used = isa;
#if GS_PEAK_HAVE_AVX512
  if (isa == "avx512") return peak::fma_loop_avx512;
#endif
#if GS_PEAK_HAVE_AVX2
  if (isa == "avx2") return peak::fma_loop_avx2;
#endif
#if GS_PEAK_HAVE_NEON64
  *used = "neon64";
  return peak::fma_loop_neon64;
#elif GS_PEAK_HAVE_SSE2
  *used = "sse2";
  return peak::fma_loop_sse2;
#else
  *used = "none";
  return nullptr;
#endif
}

// Best of `reps` timings of f() (returns work units), as units per second.
template <class F>
double best_rate(int reps, F&& f) {
  double best = 0;
  for (int r = 0; r < reps; ++r) {
    const uint64_t t0 = platform::now_ns();
    const double work = double(f());
    const double s = double(platform::now_ns() - t0) * 1e-9;
    if (s > 0) best = std::max(best, work / s);
  }
  return best;
}

}  // namespace

MachinePeaks measure_machine_peaks(const char* kernel_isa, platform::ThreadPool& pool, double seconds) {
  MachinePeaks out;
  const int reps = 3;
  const size_t threads = size_t(std::max(1, pool.num_threads()));
  FmaLoop loop = fma_loop_for(kernel_isa ? kernel_isa : "", &out.fma_isa);
  if (loop) {
    // Calibrate the step count to about `seconds / reps` per timing.
    float sink = 0;
    uint64_t steps = 1 << 20;
    for (;;) {
      const uint64_t t0 = platform::now_ns();
      loop(steps, &sink);
      const double s = double(platform::now_ns() - t0) * 1e-9;
      if (s > 0.02 || steps > (uint64_t(1) << 40)) {
        steps = uint64_t(double(steps) * (seconds / double(reps)) / std::max(s, 1e-6)) + 1;
        break;
      }
      steps *= 4;
    }
    out.fma_gflops_core = 1e-9 * best_rate(reps, [&] { return loop(steps, &sink); });
    std::vector<float> sinks(threads, 0.0f);
    out.fma_gflops_all = 1e-9 * best_rate(reps, [&] {
      std::atomic<uint64_t> flops{0};
      auto body = [&](size_t b, size_t e, int) {
        for (size_t i = b; i < e; ++i) flops.fetch_add(loop(steps, &sinks[i]), std::memory_order_relaxed);
      };
      pool.parallel_for(threads, 1, body);
      return flops.load();
    });
  }
  // Copy bandwidth: 64 MiB each way, twice the L3 of common desktop and server parts and far
  // beyond any L2. Bytes counted: read + written (a write-allocate cache moves a third on top).
  const size_t bytes = size_t(64) << 20;
  out.copy_buffer_bytes = bytes;
  std::vector<uint8_t> src(bytes, 1), dst(bytes, 0);
  const int passes = std::max(1, int(seconds / double(reps) / 0.02));  // ~20 ms per pass
  out.copy_gbs_core = 1e-9 * best_rate(reps, [&] {
    for (int p = 0; p < passes; ++p) {
      src[size_t(p) % bytes] = uint8_t(p);
      std::memcpy(dst.data(), src.data(), bytes);
    }
    return uint64_t(2) * bytes * uint64_t(passes);
  });
  out.copy_gbs_all = 1e-9 * best_rate(reps, [&] {
    auto body = [&](size_t b, size_t e, int) {
      for (size_t i = b; i < e; ++i) {
        const size_t lo = bytes * i / threads, hi = bytes * (i + 1) / threads;
        for (int p = 0; p < passes; ++p) std::memcpy(dst.data() + lo, src.data() + lo, hi - lo);
      }
    };
    pool.parallel_for(threads, 1, body);
    return uint64_t(2) * bytes * uint64_t(passes);
  });
  volatile uint8_t observed = dst[bytes / 2];  // the copies are observable
  (void)observed;
  return out;
}

}  // namespace gs::bench
