// SPDX-License-Identifier: MIT
// The FMA throughput loop of bench_train --profile, templated on a per-ISA Ops struct (vector type,
// lanes, set1, fma, store written with that ISA's intrinsics): kAcc independent accumulators
// (enough to hide the FMA latency on two ports), each updated acc = acc * m + a per step. Intrinsics
// rather than xsimd: xsimd 8's avx512 architecture has no fma and the build's -ffp-contract=off
// keeps its multiply and add apart, so an xsimd loop would not measure the FMA units. Included only
// by the per-ISA translation units beside it, compiled with that ISA's flags (bench/CMakeLists.txt).
#pragma once

#include <cstdint>

namespace gs::bench::peak {

// Runs `steps` steps and returns the floating-point operations done (an FMA counts 2 per lane, as
// does a multiply + add pair on ISAs without FMA); *sink receives the sum of the accumulators so the
// loop cannot be removed.
template <class Ops>
uint64_t fma_loop(uint64_t steps, float* sink) {
  using V = typename Ops::V;
  constexpr int kAcc = 12;
  V acc[kAcc];
  for (int i = 0; i < kAcc; ++i) acc[i] = Ops::set1(1.0f + 0.01f * float(i));
  const V m = Ops::set1(0.99999994f), a = Ops::set1(1e-7f);
  for (uint64_t s = 0; s < steps; ++s) {
#if defined(__GNUC__)
#pragma GCC unroll 12
#endif
    for (int i = 0; i < kAcc; ++i) acc[i] = Ops::fma(acc[i], m, a);
  }
  alignas(64) float lanes[Ops::kLanes];
  float total = 0;
  for (int i = 0; i < kAcc; ++i) {
    Ops::store(lanes, acc[i]);
    for (int j = 0; j < Ops::kLanes; ++j) total += lanes[j];
  }
  *sink = total;
  return steps * uint64_t(kAcc) * uint64_t(Ops::kLanes) * 2;
}

}  // namespace gs::bench::peak
