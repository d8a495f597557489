// SPDX-License-Identifier: MIT
// The avx512 FMA throughput loop (peak_fma.hpp): 16 lanes, vfmadd. Compiled with avx512 flags.
#include <immintrin.h>

#include "peak_fma.hpp"

namespace gs::bench::peak {
namespace {
struct Avx512Ops {
  using V = __m512;
  static constexpr int kLanes = 16;
  static V set1(float x) { return _mm512_set1_ps(x); }
  static V fma(V x, V m, V a) { return _mm512_fmadd_ps(x, m, a); }
  static void store(float* p, V x) { _mm512_store_ps(p, x); }
};
}  // namespace

uint64_t fma_loop_avx512(uint64_t steps, float* sink) { return fma_loop<Avx512Ops>(steps, sink); }

}  // namespace gs::bench::peak
