// SPDX-License-Identifier: MIT
// The avx2 FMA throughput loop (peak_fma.hpp): 8 lanes, vfmadd (FMA3). Compiled with avx2 + fma flags.
#include <immintrin.h>

#include "peak_fma.hpp"

namespace gs::bench::peak {
namespace {
struct Avx2Ops {
  using V = __m256;
  static constexpr int kLanes = 8;
  static V set1(float x) { return _mm256_set1_ps(x); }
  static V fma(V x, V m, V a) { return _mm256_fmadd_ps(x, m, a); }
  static void store(float* p, V x) { _mm256_store_ps(p, x); }
};
}  // namespace

uint64_t fma_loop_avx2(uint64_t steps, float* sink) { return fma_loop<Avx2Ops>(steps, sink); }

}  // namespace gs::bench::peak
