// SPDX-License-Identifier: MIT
// The neon64 FMA throughput loop (peak_fma.hpp): 4 lanes, fmla.
#include <arm_neon.h>

#include "peak_fma.hpp"

namespace gs::bench::peak {
namespace {
struct Neon64Ops {
  using V = float32x4_t;
  static constexpr int kLanes = 4;
  static V set1(float x) { return vdupq_n_f32(x); }
  static V fma(V x, V m, V a) { return vfmaq_f32(a, x, m); }
  static void store(float* p, V x) { vst1q_f32(p, x); }
};
}  // namespace

uint64_t fma_loop_neon64(uint64_t steps, float* sink) { return fma_loop<Neon64Ops>(steps, sink); }

}  // namespace gs::bench::peak
