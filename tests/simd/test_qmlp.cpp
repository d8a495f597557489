// SPDX-License-Identifier: MIT
// The int8 decoder MLP (gs/simd/qmlp.h): every SIMD variant bit-exact with the reference over
// random shapes (widths not multiples of the lanes, the decoder's shapes, batch 1..300), saturating
// extremes (all weights -128 or 127, inputs at +-127, huge biases and multipliers), and no
// allocation in the kernel.
#include <doctest/doctest.h>

#include <cstring>
#include <random>
#include <vector>

#include "gs/simd/kernel_table.h"
#include "gs/simd/qmlp.h"
#include "support/alloc_counter.h"
#include "support/simd_isa.h"

namespace {

using gs::simd::QMlpParams;

struct Net {
  QMlpParams p{};
  std::vector<int32_t> w1t, b1, m1, s1, w2t, b2, m2, s2;
};

// extreme: 0 random, 1 all weights 127 and inputs 127, 2 all weights -128, 3 large biases and shifts.
Net random_net(std::mt19937& rng, int I, int H, int O, int extreme) {
  Net n;
  const int Hp = gs::simd::qmlp_pad(H), Op = gs::simd::qmlp_pad(O);
  std::uniform_int_distribution<int> w(-128, 127), bias(-20000, 20000), sh(-12, 2);
  std::uniform_int_distribution<int32_t> mul(1 << 30, 2147483647);
  auto weight = [&]() { return extreme == 1 ? 127 : (extreme == 2 ? -128 : w(rng)); };
  n.w1t.assign(size_t(I) * Hp, 0);
  n.w2t.assign(size_t(H) * Op, 0);
  for (int i = 0; i < I; ++i)
    for (int h = 0; h < H; ++h) n.w1t[size_t(i) * Hp + h] = weight();
  for (int h = 0; h < H; ++h)
    for (int o = 0; o < O; ++o) n.w2t[size_t(h) * Op + o] = weight();
  n.b1.assign(Hp, 0);
  n.b2.assign(Op, 0);
  for (int h = 0; h < H; ++h) n.b1[h] = extreme == 3 ? bias(rng) * 50000 : bias(rng);
  for (int o = 0; o < O; ++o) n.b2[o] = extreme == 3 ? bias(rng) * 50000 : bias(rng);
  for (int h = 0; h < H; ++h) n.m1.push_back(mul(rng)), n.s1.push_back(extreme == 3 ? 20 : sh(rng));
  for (int o = 0; o < O; ++o) n.m2.push_back(mul(rng)), n.s2.push_back(extreme == 3 ? -31 : sh(rng));
  n.p = QMlpParams{I, H, O, Hp, Op, n.w1t.data(), n.b1.data(), n.m1.data(), n.s1.data(),
                   n.w2t.data(), n.b2.data(), n.m2.data(), n.s2.data()};
  return n;
}

void check(const gs::simd::KernelTable* kt) {
  std::mt19937 rng(7);
  const int shapes[][3] = {{36, 32, 10}, {44, 32, 70}, {44, 32, 30}, {13, 16, 8}, {1, 1, 1}, {17, 23, 5}, {64, 48, 33}};
  int cases = 0;
  for (const auto& s : shapes)
    for (int extreme = 0; extreme < 4; ++extreme)
      for (int batch : {1, 7, 300}) {
        CAPTURE(s[0]); CAPTURE(s[1]); CAPTURE(s[2]); CAPTURE(extreme); CAPTURE(batch);
        const Net n = random_net(rng, s[0], s[1], s[2], extreme);
        std::vector<int8_t> x(size_t(batch) * s[0]);
        std::uniform_int_distribution<int> xv(-127, 127);
        for (int8_t& v : x) v = int8_t(extreme == 1 ? 127 : (extreme == 2 ? -127 : xv(rng)));
        std::vector<int8_t> h_ref(size_t(batch) * s[1]), h_out(h_ref.size(), 99);
        std::vector<int16_t> y_ref(size_t(batch) * s[2]), y_out(y_ref.size(), 12345);
        gs::simd::qmlp_fwd_ref(&n.p, batch, x.data(), h_ref.data(), y_ref.data());
        {
          gs::test::AllocationScope scope;
          kt->qmlp_fwd(&n.p, batch, x.data(), h_out.data(), y_out.data());
          REQUIRE(scope.count() == 0);
        }
        REQUIRE(h_out == h_ref);
        REQUIRE(y_out == y_ref);
        ++cases;
      }
  CHECK(cases == 84);
}

}  // namespace

GS_SIMD_TEST_CASE(qmlp, "int8 decoder MLP kernels are bit-exact with the reference") { check(kt); }

TEST_CASE("int8 decoder MLP reference: saturation and ReLU behave as specified") {
  // One input, one hidden unit, one output: hidden = clamp(rq(b1 + x w1)), y = sat16(rq(b2 + h w2)).
  std::mt19937 rng(1);
  Net n = random_net(rng, 1, 1, 1, 0);
  n.w1t[0] = 100; n.b1[0] = -50; n.w2t[0] = 127; n.b2[0] = 40000000;
  gs::simd::fxp::quantize_multiplier(1.0, &n.m1[0], &n.s1[0]);
  gs::simd::fxp::quantize_multiplier(1.0, &n.m2[0], &n.s2[0]);
  int8_t x = 1, h = 0;
  int16_t y = 0;
  gs::simd::qmlp_fwd_ref(&n.p, 1, &x, &h, &y);
  CHECK(h == 50);       // 100 - 50, scale 1
  CHECK(y == 32767);    // 40,000,000 + 50 * 127 saturates
  x = -1;
  gs::simd::qmlp_fwd_ref(&n.p, 1, &x, &h, &y);
  CHECK(h == 0);        // ReLU
  x = 127;
  gs::simd::qmlp_fwd_ref(&n.p, 1, &x, &h, &y);
  CHECK(h == 127);      // 12,650: clamped to int8
}
