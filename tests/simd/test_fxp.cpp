// SPDX-License-Identifier: MIT
// The fixed-point requantisation helpers (gs/simd/fxp.h) against exact arithmetic: every shift,
// the int32 extremes, negative ties, many random values, and the multiplier round trip.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "gs/simd/fxp.h"

namespace {

using namespace gs::simd::fxp;
constexpr int32_t kMin = std::numeric_limits<int32_t>::min(), kMax = std::numeric_limits<int32_t>::max();

// Exact round(x / 2^e), ties away from zero (int64 holds every intermediate: |x| <= 2^31).
int32_t exact_divide_pot(int32_t x, int e) {
  const int64_t d = int64_t(1) << e, ax = x < 0 ? -int64_t(x) : int64_t(x);
  const int64_t q = (2 * ax + d) / (2 * d);  // floor(|x| / d + 1/2)
  return int32_t(x < 0 ? -q : q);
}

// Exact round(a b / 2^31) with ties towards +infinity, saturated (|a b| <= 2^62 fits int64).
int32_t exact_srdhm(int32_t a, int32_t b) {
  const int64_t p = int64_t(a) * b;
  int64_t q = p / (int64_t(1) << 31);  // truncation, then floor
  if (q * (int64_t(1) << 31) > p) --q;
  if (p - q * (int64_t(1) << 31) >= (int64_t(1) << 30)) ++q;
  return q > kMax ? kMax : int32_t(q);
}

std::vector<int32_t> edge_values() {
  std::vector<int32_t> v = {kMin, kMin + 1, kMin + 2, -65536, -32769, -32768, -257, -256, -255, -129, -128, -127,
                            -3, -2, -1, 0, 1, 2, 3, 127, 128, 255, 256, 32767, 32768, 65535, kMax - 1, kMax};
  for (int e = 0; e < 31; ++e) {
    const int32_t p = int32_t(1) << e;
    for (int32_t x : {p, -p, p + 1, -p - 1, p - 1, -p + 1, p / 2 * 3, -(p / 2 * 3)}) v.push_back(x);
  }
  return v;
}

}  // namespace

TEST_CASE("fxp: rounding_divide_by_pot matches exact rounding for every shift, edges and random values") {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int32_t> d(kMin, kMax);
  std::vector<int32_t> xs = edge_values();
  for (int i = 0; i < 20000; ++i) xs.push_back(d(rng));
  for (int e = 0; e <= 31; ++e)
    for (int32_t x : xs) {
      CAPTURE(x);
      CAPTURE(e);
      REQUIRE(rounding_divide_by_pot(x, e) == exact_divide_pot(x, e));
    }
  // Negative ties round away from zero: -3 / 2 -> -2, -5 / 4 -> -1, -6 / 4 -> -2.
  CHECK(rounding_divide_by_pot(-3, 1) == -2);
  CHECK(rounding_divide_by_pot(3, 1) == 2);
  CHECK(rounding_divide_by_pot(-5, 2) == -1);
  CHECK(rounding_divide_by_pot(-6, 2) == -2);
}

TEST_CASE("fxp: saturating rounding doubling high multiply matches exact arithmetic, saturating only at min * min") {
  std::mt19937 rng(2);
  std::uniform_int_distribution<int32_t> d(kMin, kMax);
  const std::vector<int32_t> edges = edge_values();
  for (int32_t a : edges)
    for (int32_t b : edges) REQUIRE(saturating_rounding_doubling_high_mul(a, b) == exact_srdhm(a, b));
  for (int i = 0; i < 200000; ++i) {
    const int32_t a = d(rng), b = d(rng);
    REQUIRE(saturating_rounding_doubling_high_mul(a, b) == exact_srdhm(a, b));
  }
  CHECK(saturating_rounding_doubling_high_mul(kMin, kMin) == kMax);
  CHECK(saturating_rounding_doubling_high_mul(kMin, kMax) == exact_srdhm(kMin, kMax));
}

TEST_CASE("fxp: quantize_multiplier round-trips reals within half a Q31 step, at powers of two and just below") {
  std::vector<double> reals = {1e-9, 1e-6, 0.001, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 1000.0, 1073741824.0};
  for (int e = -40; e <= 30; ++e) {
    reals.push_back(std::ldexp(1.0, e));
    reals.push_back(std::nextafter(std::ldexp(1.0, e), 0.0));
    reals.push_back(std::ldexp(1.0, e) * (1 - 1e-12));
  }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-30, 30);
  for (int i = 0; i < 5000; ++i) reals.push_back(std::exp2(u(rng)));
  for (double r : reals) {
    CAPTURE(r);
    int32_t m = 0;
    int s = 0;
    quantize_multiplier(r, &m, &s);
    REQUIRE(m >= (int32_t(1) << 30));
    const double back = double(m) / 2147483648.0 * std::ldexp(1.0, s);
    REQUIRE(std::fabs(back - r) <= std::ldexp(1.0, s - 32) * 1.0000001);  // half a step of 2^(s-31)
  }
  int32_t m = 7;
  int s = 7;
  quantize_multiplier(0.0, &m, &s);
  CHECK((m == 0 && s == 0));
  quantize_multiplier(std::nan(""), &m, &s);
  CHECK(m == 0);
}

TEST_CASE("fxp: multiply_by_quantized_multiplier approximates x * real, saturating shifts and casts") {
  std::mt19937 rng(4);
  std::uniform_int_distribution<int32_t> d(-(1 << 20), 1 << 20);
  std::uniform_real_distribution<double> u(-12, 6);
  for (int i = 0; i < 100000; ++i) {
    const double real = std::exp2(u(rng));
    int32_t m;
    int s;
    quantize_multiplier(real, &m, &s);
    const int32_t x = d(rng);
    const double want = double(x) * real;
    if (std::fabs(want) > 2e9) continue;
    // Two roundings (the high multiply, then the shift) and the multiplier's own rounding.
    REQUIRE(std::fabs(double(multiply_by_quantized_multiplier(x, m, s)) - want) <= 1.0 + std::fabs(want) * 1e-9);
  }
  CHECK(saturating_left_shift(1 << 30, 1) == kMax);
  CHECK(saturating_left_shift(-(1 << 30), 2) == kMin);
  CHECK(saturating_left_shift(-(1 << 30), 1) == kMin);
  CHECK(saturating_left_shift(3, 4) == 48);
  CHECK(saturate_int8(200) == 127);
  CHECK(saturate_int8(-200) == -128);
  CHECK(saturate_int8(-5) == -5);
  CHECK(saturate_int16(70000) == 32767);
  CHECK(saturate_int16(-70000) == -32768);
  CHECK(saturate_uint8(-1) == 0);
  CHECK(saturate_uint8(300) == 255);
}
