// SPDX-License-Identifier: MIT
// lane_sums(rows) = the batch whose lane k is the sum of the lanes of rows[k], for N = batch size
// rows: a transposing reduction that serves N horizontal sums for about 3 instructions a row
// (the raster backward sums 9 accumulators per splat). xsimd::haddp, except on AVX-512, where
// xsimd 8.1's haddp returns the sums in a permuted lane order (lanes 2-3 and 4-5, 10-11 and 12-13
// swapped), so it has its own unpack/shuffle tree here. Included only by the per-ISA kernel headers;
// the raster kernel tests (SIMD against the scalar reference) check it on every table.
#pragma once

#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {
namespace kernels {

template <class A>
inline xsimd::batch<float, A> lane_sums(const xsimd::batch<float, A>* rows) {
  return xsimd::haddp(rows);
}

#if defined(__AVX512F__)
inline xsimd::batch<float, xsimd::avx512bw> lane_sums(const xsimd::batch<float, xsimd::avx512bw>* rows) {
  // Level 1, rows 2k and 2k+1: per 128-bit block q, [a0+a2, b0+b2, a1+a3, b1+b3] of that block.
  __m512 pair[8];
  for (int k = 0; k < 8; ++k) {
    const __m512 a = rows[2 * k], b = rows[2 * k + 1];
    pair[k] = _mm512_add_ps(_mm512_unpacklo_ps(a, b), _mm512_unpackhi_ps(a, b));
  }
  // Level 2, rows 4k..4k+3: per block q, the four rows' sums over that block.
  __m512 quad[4];
  for (int k = 0; k < 4; ++k) {
    const __m512 x = pair[2 * k], y = pair[2 * k + 1];
    quad[k] = _mm512_add_ps(_mm512_shuffle_ps(x, y, _MM_SHUFFLE(1, 0, 1, 0)), _mm512_shuffle_ps(x, y, _MM_SHUFFLE(3, 2, 3, 2)));
  }
  // Level 3: block j of the result is the sum over blocks q of quad[j].
  const __m512 d0 = _mm512_add_ps(_mm512_shuffle_f32x4(quad[0], quad[1], _MM_SHUFFLE(1, 0, 1, 0)),
                                  _mm512_shuffle_f32x4(quad[0], quad[1], _MM_SHUFFLE(3, 2, 3, 2)));
  const __m512 d1 = _mm512_add_ps(_mm512_shuffle_f32x4(quad[2], quad[3], _MM_SHUFFLE(1, 0, 1, 0)),
                                  _mm512_shuffle_f32x4(quad[2], quad[3], _MM_SHUFFLE(3, 2, 3, 2)));
  return _mm512_add_ps(_mm512_shuffle_f32x4(d0, d1, _MM_SHUFFLE(2, 0, 2, 0)),
                       _mm512_shuffle_f32x4(d0, d1, _MM_SHUFFLE(3, 1, 3, 1)));
}
#endif

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
