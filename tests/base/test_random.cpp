// SPDX-License-Identifier: MIT
// gs/random.h, the one SplitMix64: the published reference outputs (Vigna's splitmix64.c for seeds 0
// and 1234567), and the ranges of uniform() and uniform_open().
#include <doctest/doctest.h>

#include <cstdint>

#include "gs/random.h"

namespace gs {
namespace {

TEST_CASE("SplitMix64: reference outputs") {
  SplitMix64 zero{0};
  CHECK(zero.next() == 0xE220A8397B1DCDAFull);
  CHECK(zero.next() == 0x6E789E6AA1B965F4ull);
  CHECK(zero.next() == 0x06C45D188009454Full);
  SplitMix64 g{1234567};
  const uint64_t expect[5] = {6457827717110365317ull, 3203168211198807973ull, 9817491932198370423ull,
                              4593380528125082431ull, 16408922859458223821ull};
  for (uint64_t e : expect) CHECK(g.next() == e);
  // mix64 is the output function: the first output of state s is mix64(s + golden increment).
  CHECK(mix64(0x9E3779B97F4A7C15ull) == 0xE220A8397B1DCDAFull);
}

TEST_CASE("SplitMix64: uniform (0 to 1, 1 excluded) and uniform_open (both excluded) from the top 53 bits") {
  SplitMix64 a{42}, b{42}, c{42};
  double lo = 1, hi = 0, sum = 0;
  const int n = 100000;
  for (int i = 0; i < n; ++i) {
    const uint64_t bits = c.next() >> 11;
    const double u = a.uniform(), o = b.uniform_open();
    CHECK(u == double(bits) / 9007199254740992.0);
    CHECK(o == (double(bits) + 0.5) / 9007199254740992.0);
    REQUIRE(u >= 0.0);
    REQUIRE(u < 1.0);
    REQUIRE(o > 0.0);
    REQUIRE(o < 1.0);
    lo = u < lo ? u : lo, hi = u > hi ? u : hi, sum += u;
  }
  CHECK(lo < 1e-3);
  CHECK(hi > 1 - 1e-3);
  CHECK(sum / n == doctest::Approx(0.5).epsilon(0.01));  // 5 sigma of the mean is 0.0046
}

}  // namespace
}  // namespace gs
