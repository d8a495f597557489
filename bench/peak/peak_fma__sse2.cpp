// SPDX-License-Identifier: MIT
// The sse2 throughput loop (peak_fma.hpp): 4 lanes, a multiply and an add (sse2 has no FMA).
#include <emmintrin.h>

#include "peak_fma.hpp"

namespace gs::bench::peak {
namespace {
struct Sse2Ops {
  using V = __m128;
  static constexpr int kLanes = 4;
  static V set1(float x) { return _mm_set1_ps(x); }
  static V fma(V x, V m, V a) { return _mm_add_ps(_mm_mul_ps(x, m), a); }
  static void store(float* p, V x) { _mm_store_ps(p, x); }
};
}  // namespace

uint64_t fma_loop_sse2(uint64_t steps, float* sink) { return fma_loop<Sse2Ops>(steps, sink); }

}  // namespace gs::bench::peak
