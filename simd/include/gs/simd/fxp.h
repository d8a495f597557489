// SPDX-License-Identifier: MIT
// Fixed-point requantisation helpers of the integer kernels (the int8 decoder MLP): a real scale
// becomes a Q31 multiplier and a power-of-two shift at prepare time, and the kernels rescale int32
// accumulators with integer arithmetic only, so every variant is bit-exact with its reference.
//   value * real  ~=  multiply_by_quantized_multiplier(value, multiplier, shift)
// Rounding: the doubling high multiply rounds to nearest with ties up (+2^30 before the shift, as
// the rounding doubling multiplies of NEON and SSSE3 do); the power-of-two division rounds half away
// from zero. Header-only; includes nothing of the project.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include "gs/simd/isa.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)
namespace fxp {

// real in (0, 2^31): *multiplier in [2^30, 2^31) (Q31 of the mantissa) and *shift with
// real = multiplier / 2^31 * 2^shift. real <= 0 or not finite: multiplier 0, shift 0.
inline void quantize_multiplier(double real, int32_t* multiplier, int* shift) {
  if (!(real > 0) || !std::isfinite(real)) {
    *multiplier = 0;
    *shift = 0;
    return;
  }
  int e = 0;
  const double m = std::frexp(real, &e);  // real = m 2^e, m in [0.5, 1)
  int64_t q = std::llround(m * 2147483648.0);
  if (q == (int64_t(1) << 31)) {  // m rounded up to 1.0
    q /= 2;
    ++e;
  }
  *multiplier = int32_t(q);
  *shift = e;
}

// round(a b / 2^31) with ties up, saturated: the one overflow, INT32_MIN * INT32_MIN, gives INT32_MAX.
inline int32_t saturating_rounding_doubling_high_mul(int32_t a, int32_t b) {
  if (a == std::numeric_limits<int32_t>::min() && b == std::numeric_limits<int32_t>::min())
    return std::numeric_limits<int32_t>::max();
  const int64_t ab = int64_t(a) * int64_t(b);
  return int32_t((ab + (int64_t(1) << 30)) >> 31);
}

// x / 2^exponent rounded to nearest, ties away from zero; exponent in [0, 31].
inline int32_t rounding_divide_by_pot(int32_t x, int exponent) {
  if (exponent <= 0) return x;
  const int64_t mask = (int64_t(1) << exponent) - 1;
  const int64_t remainder = int64_t(x) & mask;
  const int64_t threshold = (mask >> 1) + (x < 0 ? 1 : 0);
  return int32_t((int64_t(x) >> exponent) + (remainder > threshold ? 1 : 0));
}

// x * 2^shift saturated to int32 (shift in [0, 31]).
inline int32_t saturating_left_shift(int32_t x, int shift) {
  const int64_t v = int64_t(x) * (int64_t(1) << shift);
  if (v > std::numeric_limits<int32_t>::max()) return std::numeric_limits<int32_t>::max();
  if (v < std::numeric_limits<int32_t>::min()) return std::numeric_limits<int32_t>::min();
  return int32_t(v);
}

// x * multiplier / 2^31 * 2^shift (shift in [-31, 31]): left shift first (saturating), then the
// doubling high multiply, then the rounding right shift.
inline int32_t multiply_by_quantized_multiplier(int32_t x, int32_t multiplier, int shift) {
  const int left = shift > 0 ? shift : 0, right = shift > 0 ? 0 : -shift;
  return rounding_divide_by_pot(saturating_rounding_doubling_high_mul(saturating_left_shift(x, left), multiplier), right);
}

inline int8_t saturate_int8(int32_t v) { return int8_t(v < -128 ? -128 : (v > 127 ? 127 : v)); }
inline int16_t saturate_int16(int32_t v) { return int16_t(v < -32768 ? -32768 : (v > 32767 ? 32767 : v)); }
inline uint8_t saturate_uint8(int32_t v) { return uint8_t(v < 0 ? 0 : (v > 255 ? 255 : v)); }

}  // namespace fxp
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
