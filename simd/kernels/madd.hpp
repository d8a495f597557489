// SPDX-License-Identifier: MIT
// madd(x, y, z) = x * y + z with one rounding (a fused multiply-add) on every architecture that has
// one: xsimd::fma, except on AVX-512, where xsimd 8.1 has no fma kernel and falls back to a multiply
// and an add (the build compiles with -ffp-contract=off, so the compiler never fuses them itself).
// Included only by the per-ISA kernel headers.
#pragma once

#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {
namespace kernels {

template <class A>
inline xsimd::batch<float, A> madd(const xsimd::batch<float, A>& x, const xsimd::batch<float, A>& y,
                                   const xsimd::batch<float, A>& z) {
  return xsimd::fma(x, y, z);
}

#if defined(__AVX512F__)
inline xsimd::batch<float, xsimd::avx512bw> madd(const xsimd::batch<float, xsimd::avx512bw>& x,
                                                 const xsimd::batch<float, xsimd::avx512bw>& y,
                                                 const xsimd::batch<float, xsimd::avx512bw>& z) {
  return _mm512_fmadd_ps(x, y, z);
}
#endif

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
