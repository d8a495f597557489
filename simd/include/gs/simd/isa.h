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
// tests/simd/check_isa_symbols.sh checks every variant object with nm.
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

// The float and double forms of a one-argument libm function: name(float) calls ::namef.
#define GS_SIMD_SCALAR_LIBM(name)                             \
  inline float name(float x) { return ::name##f(x); }         \
  inline double name(double x) { return ::name(x); }
GS_SIMD_SCALAR_LIBM(exp)
GS_SIMD_SCALAR_LIBM(log)
GS_SIMD_SCALAR_LIBM(log2)
GS_SIMD_SCALAR_LIBM(sqrt)
GS_SIMD_SCALAR_LIBM(tanh)
GS_SIMD_SCALAR_LIBM(floor)
GS_SIMD_SCALAR_LIBM(ceil)
#undef GS_SIMD_SCALAR_LIBM
inline double pow(double x, double y) { return ::pow(x, y); }

}  // namespace scalar
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
