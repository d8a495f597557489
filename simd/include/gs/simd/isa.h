// SPDX-License-Identifier: MIT
// The per-instruction-set namespace. Every inline function, inline function template and kernel class
// template of libgs_simd is defined inside
//     namespace gs::simd { inline namespace GS_SIMD_ISA_NS { ... } }
// A per-ISA translation unit (simd/kernels/variants/kernels__<isa>.cpp) defines GS_SIMD_ISA_NS as
// isa_<isa> before its first include; every other TU gets isa_baseline. An inline helper such as
// tile_rect<float> or adam_consts compiled with AVX-512 flags is then a different symbol
// (gs::simd::isa_avx512::tile_rect<float>) from the baseline copy, so the linker can never merge the
// two and hand an SSE2-only CPU the AVX-512 one. The namespace is inline, so callers keep writing
// gs::simd::tile_rect. Types (structs, enums, constants) and the out-of-line reference kernels stay
// in gs::simd itself: they are ISA-independent, and KernelTable must be one type everywhere.
//
// The helpers below replace std:: function templates and the inline float overloads of <cmath>
// (std::min<T>, std::fill, std::exp(float), ...) in code that variant TUs compile: those are weak
// symbols in namespace std, merged across ISAs like any other. They are bit-identical to what they
// replace (same comparison as std::min / std::max; the same libm calls that <cmath> forwards to).
// tests/simd/check_isa_symbols.cmake checks every variant object with nm.
#pragma once
#define GS_SIMD_ISA_H_INCLUDED 1

#include <math.h>  // ::expf and friends: out-of-line libm functions, not inline wrappers

#include <cstddef>

#if !defined(GS_SIMD_ISA_NS)
#define GS_SIMD_ISA_NS isa_baseline
#endif

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {
namespace scalar {

template <class T>
inline T min(T a, T b) {
  return b < a ? b : a;  // std::min
}
template <class T>
inline T max(T a, T b) {
  return a < b ? b : a;  // std::max
}
template <class T>
inline void fill(T* first, T* last, T value) {
  for (; first != last; ++first) *first = value;
}
template <class T>
inline void copy(const T* first, const T* last, T* out) {
  for (; first != last; ++first, ++out) *out = *first;
}

inline float exp(float x) { return ::expf(x); }
inline double exp(double x) { return ::exp(x); }
inline float log(float x) { return ::logf(x); }
inline double log(double x) { return ::log(x); }
inline float sqrt(float x) { return ::sqrtf(x); }
inline double sqrt(double x) { return ::sqrt(x); }
inline float tanh(float x) { return ::tanhf(x); }
inline double tanh(double x) { return ::tanh(x); }
inline float floor(float x) { return ::floorf(x); }
inline double floor(double x) { return ::floor(x); }
inline float ceil(float x) { return ::ceilf(x); }
inline double ceil(double x) { return ::ceil(x); }
inline double pow(double x, double y) { return ::pow(x, y); }

}  // namespace scalar
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
