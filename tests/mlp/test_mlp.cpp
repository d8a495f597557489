// SPDX-License-Identifier: MIT
// Decoder MLP and Adam kernels (mlp.h): finite-difference gradient check of the double reference
// with ReLU kinks excluded and counted, ReLU'(0) = 0, gradient accumulation, every SIMD kernel table
// against the float reference with canaries after every output, and Adam against a hand-computed
// two-step example and the reference.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gs/simd/kernel_table.h"
#include "gs/simd/mlp.h"
#include "support/simd_isa.h"

namespace {

using gs::simd::AdamParams;
using gs::simd::MlpAct;
using gs::simd::MlpShape;
constexpr float kCanary = -12345.0f;
constexpr size_t kCanaryCount = 16;  // one AVX-512 register of floats after every output
constexpr MlpAct kActs[] = {MlpAct::kNone, MlpAct::kSigmoid, MlpAct::kTanh};

// All MLP arrays of one problem, in the order x, W1, b1, W2, b2.
template <class T>
struct Net {
  MlpShape s;
  int32_t batch;
  std::vector<T> p[5];
  Net(MlpShape shape, int32_t b, std::mt19937_64& rng) : s(shape), batch(b) {
    const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out);
    const size_t sizes[5] = {size_t(b) * I, H * I, H, O * H, O};
    // Weights scaled like a default init (1/sqrt(fan_in)) so pre-activations are O(1).
    const double scales[5] = {1.0, 1.0 / std::sqrt(double(I)), 0.5, 1.0 / std::sqrt(double(H)), 0.5};
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 5; ++k) {
      p[k].resize(sizes[k]);
      for (T& e : p[k]) e = T(scales[k] * u(rng));
    }
  }
};

// Objective sum(r * y) for a fixed random cotangent r.
double objective(const Net<double>& n, const std::vector<double>& r, std::vector<double>* hidden,
                 std::vector<double>* y) {
  gs::simd::mlp_fwd_ref<double>(&n.s, n.batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                n.p[4].data(), hidden->data(), y->data());
  double sum = 0;
  for (size_t k = 0; k < r.size(); ++k) sum += r[k] * (*y)[k];
  return sum;
}

// Hidden pre-activations [B, H] computed directly (for the kink band).
std::vector<double> pre_activations(const Net<double>& n) {
  const size_t I = size_t(n.s.in), H = size_t(n.s.hidden);
  std::vector<double> pre(size_t(n.batch) * H);
  for (size_t b = 0; b < size_t(n.batch); ++b)
    for (size_t j = 0; j < H; ++j) {
      double a = n.p[2][j];
      for (size_t i = 0; i < I; ++i) a += n.p[1][j * I + i] * n.p[0][b * I + i];
      pre[b * H + j] = a;
    }
  return pre;
}

// 4-point central differences, h = 1e-4. The objective is a sum of O(1) smooth terms (tanh,
// sigmoid, identity of O(1) pre-activations with O(1) weights), so the O(h^4 f^(5)) truncation is
// ~1e-16 and the rounding noise ~1e-16 |f| / h ~ 1e-12. A relative 1e-7 plus absolute 1e-9 sits
// far above both and far below any real mistake (a missing or wrong term is O(1) relative).
// Kink band: a probe is excluded (and counted) when any hidden pre-activation changes sign across
// the four evaluations (the ReLU kink lies inside the stencil), or sits within 1e-6 of 0 at the
// base point; the count is bounded instead of loosening the tolerance.
constexpr double kStep = 1e-4;
constexpr double kRelTol = 1e-7;
constexpr double kAbsTol = 1e-9;
constexpr double kKinkBand = 1e-6;

void fd_check(MlpShape s, int32_t batch, uint64_t seed) {
  CAPTURE(s.in); CAPTURE(s.hidden); CAPTURE(s.out); CAPTURE(int(s.act2)); CAPTURE(batch); CAPTURE(seed);
  std::mt19937_64 rng(seed);
  Net<double> n(s, batch, rng);
  const size_t H = size_t(s.hidden), O = size_t(s.out);
  std::vector<double> r(size_t(batch) * O), hidden(size_t(batch) * H), y(r.size());
  std::uniform_real_distribution<double> u(-1, 1);
  for (double& e : r) e = u(rng);
  objective(n, r, &hidden, &y);
  std::vector<double> g[5];
  for (int k = 0; k < 5; ++k) g[k].assign(n.p[k].size(), 0.0);
  gs::simd::mlp_bwd_ref<double>(&n.s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                n.p[4].data(), hidden.data(), y.data(), r.data(), g[0].data(), g[1].data(),
                                g[2].data(), g[3].data(), g[4].data());
  const std::vector<double> pre0 = pre_activations(n);
  const char* names[5] = {"x", "W1", "b1", "W2", "b2"};
  size_t probes = 0, excluded = 0;
  double worst_rel = 0;
  for (int k = 0; k < 5; ++k) {
    for (size_t e = 0; e < n.p[k].size(); ++e) {
      const double orig = n.p[k][e];
      double f[4];
      bool kink = false;
      const double offs[4] = {-2 * kStep, -kStep, kStep, 2 * kStep};
      for (int q = 0; q < 4; ++q) {
        n.p[k][e] = orig + offs[q];
        f[q] = objective(n, r, &hidden, &y);
        const std::vector<double> pre = pre_activations(n);
        for (size_t t = 0; t < pre.size(); ++t)
          if ((pre[t] > 0) != (pre0[t] > 0) || std::fabs(pre0[t]) < kKinkBand) kink = true;
      }
      n.p[k][e] = orig;
      ++probes;
      if (kink) {
        ++excluded;
        continue;
      }
      const double fd = (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * kStep);
      const double an = g[k][e];
      const double err = std::fabs(fd - an);
      worst_rel = std::max(worst_rel, err / std::max(std::fabs(an), 1e-3));
      if (err > kRelTol * std::fabs(an) + kAbsTol) {
        CAPTURE(names[k]); CAPTURE(e); CAPTURE(fd); CAPTURE(an);
        CHECK(err <= kRelTol * std::fabs(an) + kAbsTol);
      }
    }
  }
  MESSAGE("FD act2=" << int(s.act2) << " (I,H,O)=(" << s.in << "," << s.hidden << "," << s.out << ") probes "
                     << probes << " excluded " << excluded << " worst rel err " << worst_rel);
  CHECK(excluded * 20 <= probes);  // at most 5% of probes near a kink (measured: a handful)
}

}  // namespace

TEST_CASE("mlp: FD gradient of the double reference (small shape)") {
  for (MlpAct a : kActs) fd_check(MlpShape{5, 7, 3, a}, 3, 11 + uint64_t(a));
}

TEST_CASE("mlp: FD gradient of the double reference (hbgs shape 36-32-10)") {
  for (MlpAct a : kActs) fd_check(MlpShape{36, 32, 10, a}, 2, 23 + uint64_t(a));
}

TEST_CASE("mlp: ReLU derivative is 0 at a pre-activation of exactly 0") {
  // x = 0 and b1 = 0 give pre-activations of exactly 0 for every unit: no gradient may reach W1,
  // b1 or x, while the second layer still gets its bias gradient.
  const MlpShape s{4, 3, 2, MlpAct::kNone};
  std::vector<double> x(4, 0.0), W1(12, 0.7), b1(3, 0.0), W2(6, 0.3), b2(2, 0.1), h(3), y(2), v_y{1.0, -2.0};
  gs::simd::mlp_fwd_ref<double>(&s, 1, x.data(), W1.data(), b1.data(), W2.data(), b2.data(), h.data(), y.data());
  std::vector<double> v_x(4, 9.0), v_W1(12, 0.0), v_b1(3, 0.0), v_W2(6, 0.0), v_b2(2, 0.0);
  gs::simd::mlp_bwd_ref<double>(&s, 1, x.data(), W1.data(), b1.data(), W2.data(), b2.data(), h.data(), y.data(),
                                v_y.data(), v_x.data(), v_W1.data(), v_b1.data(), v_W2.data(), v_b2.data());
  for (double e : v_x) CHECK(e == 0.0);
  for (double e : v_W1) CHECK(e == 0.0);
  for (double e : v_b1) CHECK(e == 0.0);
  CHECK(v_b2[0] == 1.0);
  CHECK(v_b2[1] == -2.0);
}

TEST_CASE("mlp: weight gradients accumulate over calls") {
  // Two calls on halves of a batch sum to one call on the whole batch.
  std::mt19937_64 rng(5);
  const MlpShape s{6, 8, 4, MlpAct::kTanh};
  Net<double> n(s, 4, rng);
  std::vector<double> h(4 * 8), y(4 * 4), v_y(4 * 4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (double& e : v_y) e = u(rng);
  gs::simd::mlp_fwd_ref<double>(&s, 4, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(),
                                h.data(), y.data());
  std::vector<double> one[4], two[4];
  for (int k = 0; k < 4; ++k) {
    one[k].assign(n.p[k + 1].size(), 0.0);
    two[k].assign(n.p[k + 1].size(), 0.0);
  }
  auto bwd = [&](int32_t r0, int32_t rows, std::vector<double>* g) {
    gs::simd::mlp_bwd_ref<double>(&s, rows, n.p[0].data() + r0 * 6, n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                  n.p[4].data(), h.data() + r0 * 8, y.data() + r0 * 4, v_y.data() + r0 * 4, nullptr,
                                  g[0].data(), g[1].data(), g[2].data(), g[3].data());
  };
  bwd(0, 4, one);
  bwd(0, 2, two);
  bwd(2, 2, two);
  for (int k = 0; k < 4; ++k)
    for (size_t e = 0; e < one[k].size(); ++e) CHECK(two[k][e] == doctest::Approx(one[k][e]).epsilon(1e-12));
}

namespace {

// Buffer with kCanaryCount canaries after n values.
std::vector<float> with_canary(size_t n, float fill = 0.0f) {
  std::vector<float> v(n + kCanaryCount, kCanary);
  std::fill(v.begin(), v.begin() + long(n), fill);
  return v;
}

void check_canary(const std::vector<float>& v, size_t n, const char* what) {
  for (size_t k = n; k < v.size(); ++k) {
    CAPTURE(what);
    REQUIRE(v[k] == kCanary);
  }
}

// max |a - b| / max(max |b|, 1e-6) over the first n values.
double rel_err(const std::vector<float>& a, const std::vector<float>& b, size_t n) {
  double diff = 0, scale = 1e-6;
  for (size_t k = 0; k < n; ++k) {
    diff = std::max(diff, std::fabs(double(a[k]) - double(b[k])));
    scale = std::max(scale, std::fabs(double(b[k])));
  }
  return diff / scale;
}

}  // namespace

// Float SIMD vs the float reference (double accumulation). The dot products have at most 70 terms
// of O(1); float partial sums in lanes plus FMA contraction give ~sqrt(70) * 6e-8 ~ 5e-7 relative
// to the largest value of the array, and exp/tanh are within a few ULP, so 2e-5 leaves a wide
// margin and still catches any wrong term or lane (O(1e-2) or more).
constexpr double kSimdTol = 2e-5;

GS_SIMD_TEST_CASE(mlp_matches_ref, "mlp: SIMD kernels match the float reference") {
  const gs::simd::KernelTable* const tables[] = {kt};  // one ISA per case (support/simd_isa.h)
  const MlpShape shapes[] = {{36, 32, 10, MlpAct::kNone}, {36, 32, 70, MlpAct::kNone}, {5, 7, 3, MlpAct::kNone}};
  const int32_t batches[] = {1, 3, 17, 64};
  double worst_fwd = 0, worst_bwd = 0;
  for (const gs::simd::KernelTable* t : tables) {
    for (MlpShape s0 : shapes) {
      for (MlpAct a : kActs) {
        for (int32_t batch : batches) {
          MlpShape s = s0;
          s.act2 = a;
          CAPTURE(t->isa); CAPTURE(s.in); CAPTURE(s.hidden); CAPTURE(s.out); CAPTURE(int(a)); CAPTURE(batch);
          std::mt19937_64 rng(uint64_t(batch) * 131 + uint64_t(s.out) * 7 + uint64_t(a));
          Net<float> n(s, batch, rng);
          const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out), Bn = size_t(batch);
          std::vector<float> v_y(Bn * O);
          std::uniform_real_distribution<float> u(-1, 1);
          for (float& e : v_y) e = u(rng);
          // Kills one hidden unit for every row (bias far negative) so masked lanes are exercised.
          n.p[2][H / 2] = -100.0f;
          const size_t gsz[4] = {H * I, H, O * H, O};
          std::vector<float> prefill[4];  // weight gradients start non-zero: tests accumulation
          for (int k = 0; k < 4; ++k) {
            prefill[k].resize(gsz[k]);
            for (float& e : prefill[k]) e = u(rng);
          }
          std::vector<float> h_ref = with_canary(Bn * H), y_ref = with_canary(Bn * O);
          std::vector<float> h_s = with_canary(Bn * H), y_s = with_canary(Bn * O);
          gs::simd::mlp_fwd_ref<float>(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                       n.p[4].data(), h_ref.data(), y_ref.data());
          t->mlp_fwd(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(),
                     h_s.data(), y_s.data());
          check_canary(h_s, Bn * H, "hidden");
          check_canary(y_s, Bn * O, "y");
          const double ef = std::max(rel_err(h_s, h_ref, Bn * H), rel_err(y_s, y_ref, Bn * O));
          worst_fwd = std::max(worst_fwd, ef);
          CHECK(ef <= kSimdTol);
          // Backward on the reference forward outputs (same inputs for both).
          std::vector<float> g_ref[5], g_s[5];
          g_ref[0] = with_canary(Bn * I, 7.0f);
          g_s[0] = with_canary(Bn * I, 7.0f);  // v_x is overwritten
          for (int k = 0; k < 4; ++k) {
            g_ref[k + 1] = with_canary(gsz[k]);
            std::copy(prefill[k].begin(), prefill[k].end(), g_ref[k + 1].begin());
            g_s[k + 1] = g_ref[k + 1];
          }
          gs::simd::mlp_bwd_ref<float>(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                       n.p[4].data(), h_ref.data(), y_ref.data(), v_y.data(), g_ref[0].data(),
                                       g_ref[1].data(), g_ref[2].data(), g_ref[3].data(), g_ref[4].data());
          t->mlp_bwd(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(),
                     h_ref.data(), y_ref.data(), v_y.data(), g_s[0].data(), g_s[1].data(), g_s[2].data(),
                     g_s[3].data(), g_s[4].data());
          const size_t gn[5] = {Bn * I, H * I, H, O * H, O};
          const char* names[5] = {"v_x", "v_W1", "v_b1", "v_W2", "v_b2"};
          for (int k = 0; k < 5; ++k) {
            check_canary(g_s[k], gn[k], names[k]);
            const double eb = rel_err(g_s[k], g_ref[k], gn[k]);
            worst_bwd = std::max(worst_bwd, eb);
            CAPTURE(names[k]);
            CHECK(eb <= kSimdTol);
          }
          // v_x is optional.
          std::vector<float> g_n[4];
          for (int k = 0; k < 4; ++k) g_n[k] = g_s[k + 1];
          t->mlp_bwd(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(),
                     h_ref.data(), y_ref.data(), v_y.data(), nullptr, g_n[0].data(), g_n[1].data(), g_n[2].data(),
                     g_n[3].data());
          for (int k = 0; k < 4; ++k) check_canary(g_n[k], gn[k + 1], names[k + 1]);
        }
      }
    }
  }
  MESSAGE("SIMD vs ref worst relative error: forward " << worst_fwd << ", backward " << worst_bwd);
}

// The shapes hbgs trains with, at the batch sizes that hit every tile path: 0 (no-op), 1, one
// row short of / exactly / one row past 16 lanes, a few chunks, and a real per-view row count.
// (13,32,16) pads the input to whole vectors, (52,33,70) the hidden layer too, and (300,40,5)
// exceeds the kernels' stack scratch (the row-at-a-time fallback). Per table and case: forward
// against the float reference; backward (on the reference forward outputs) with v_x and with
// v_x = nullptr, both accumulating into random non-zero weight / bias gradients, v_x overwritten
// over a non-zero fill, canaries after every output; batch 0 must leave every output untouched.
// Tolerance: kSimdTol, relative to the largest value of each array. The largest sums here are the
// bias gradients over 3301 rows, which the float reference itself accumulates row by row in
// float: its rounding error (~sqrt(3301) * 6e-8 relative) is ~3.5e-6, the kernels' chunked sums
// less, so 2e-5 still holds without loosening.
GS_SIMD_TEST_CASE(mlp_training_shapes, "mlp: SIMD kernels match the float reference on the training shapes and batch tails") {
  const gs::simd::KernelTable* const tables[] = {kt};  // one ISA per case (support/simd_isa.h)
  const MlpShape shapes[] = {{52, 32, 10, MlpAct::kTanh},    {52, 32, 70, MlpAct::kNone},
                             {52, 32, 30, MlpAct::kSigmoid}, {13, 32, 16, MlpAct::kNone},
                             {36, 32, 70, MlpAct::kNone},    {52, 33, 70, MlpAct::kSigmoid},
                             {300, 40, 5, MlpAct::kTanh}};
  const int32_t batches[] = {0, 1, 15, 16, 17, 1000, 3301};
  const char* names[5] = {"v_x", "v_W1", "v_b1", "v_W2", "v_b2"};
  double worst_fwd = 0, worst_bwd = 0;
  for (const MlpShape& s : shapes) {
    for (int32_t batch : batches) {
      CAPTURE(s.in); CAPTURE(s.hidden); CAPTURE(s.out); CAPTURE(int(s.act2)); CAPTURE(batch);
      std::mt19937_64 rng(uint64_t(batch) * 977 + uint64_t(s.in) * 31 + uint64_t(s.out));
      Net<float> n(s, batch, rng);
      const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out), Bn = size_t(batch);
      std::uniform_real_distribution<float> u(-1, 1);
      std::vector<float> v_y(Bn * O);
      for (float& e : v_y) e = u(rng);
      n.p[2][H / 2] = -100.0f;  // one dead hidden unit: masked lanes
      const size_t gn[5] = {Bn * I, H * I, H, O * H, O};
      std::vector<float> prefill[5];
      prefill[0] = with_canary(gn[0], 7.0f);  // v_x: overwritten
      for (int k = 1; k < 5; ++k) {
        prefill[k] = with_canary(gn[k]);
        for (size_t e = 0; e < gn[k]; ++e) prefill[k][e] = u(rng);
      }
      // Reference, once per case.
      std::vector<float> h_ref = with_canary(Bn * H), y_ref = with_canary(Bn * O);
      gs::simd::mlp_fwd_ref<float>(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                   n.p[4].data(), h_ref.data(), y_ref.data());
      std::vector<float> g_ref[5];
      for (int k = 0; k < 5; ++k) g_ref[k] = prefill[k];
      gs::simd::mlp_bwd_ref<float>(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                   n.p[4].data(), h_ref.data(), y_ref.data(), v_y.data(), g_ref[0].data(),
                                   g_ref[1].data(), g_ref[2].data(), g_ref[3].data(), g_ref[4].data());
      for (const gs::simd::KernelTable* t : tables) {
        CAPTURE(std::string(t->isa));
        std::vector<float> h_s = with_canary(Bn * H, 3.0f), y_s = with_canary(Bn * O, 3.0f);
        t->mlp_fwd(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(), h_s.data(),
                   y_s.data());
        check_canary(h_s, Bn * H, "hidden");
        check_canary(y_s, Bn * O, "y");
        const double ef = std::max(rel_err(h_s, h_ref, Bn * H), rel_err(y_s, y_ref, Bn * O));
        worst_fwd = std::max(worst_fwd, ef);
        CHECK(ef <= kSimdTol);
        for (int with_vx = 0; with_vx < 2; ++with_vx) {
          CAPTURE(with_vx);
          std::vector<float> g_s[5];
          for (int k = 0; k < 5; ++k) g_s[k] = prefill[k];
          t->mlp_bwd(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(),
                     h_ref.data(), y_ref.data(), v_y.data(), with_vx ? g_s[0].data() : nullptr, g_s[1].data(),
                     g_s[2].data(), g_s[3].data(), g_s[4].data());
          for (int k = with_vx ? 0 : 1; k < 5; ++k) {
            CAPTURE(std::string(names[k]));
            check_canary(g_s[k], gn[k], names[k]);
            const double eb = rel_err(g_s[k], g_ref[k], gn[k]);
            worst_bwd = std::max(worst_bwd, eb);
            CHECK(eb <= kSimdTol);
          }
          if (!with_vx) CHECK(g_s[0] == prefill[0]);  // v_x = nullptr: nothing written
          if (batch == 0)
            for (int k = 0; k < 5; ++k) CHECK(g_s[k] == prefill[k]);  // bit-exact: nothing accumulated
        }
      }
    }
  }
  MESSAGE("SIMD vs ref (training shapes) worst relative error: forward " << worst_fwd << ", backward " << worst_bwd);
}

// mlp_fwd_exact (the on-device decode) is bit-identical to the float reference on every table:
// the hbgs shapes, odd shapes, every activation, batches with tails of every lane count (and 0,
// which writes nothing), a dead hidden unit, and pre-activations of exactly 0 (ReLU kinks); a
// shape too large for its stack buffer takes the reference itself. Canaries after every output.
GS_REF_AND_SIMD_TEST_CASE(mlp_exact_matches_ref, "mlp: the exact forward is bit-identical to the float reference") {
  const MlpShape shapes[] = {{52, 32, 10, MlpAct::kTanh}, {52, 32, 70, MlpAct::kNone}, {52, 32, 30, MlpAct::kSigmoid},
                             {36, 32, 10, MlpAct::kNone}, {5, 7, 3, MlpAct::kSigmoid}, {1, 1, 1, MlpAct::kTanh},
                             {300, 40, 5, MlpAct::kTanh}, {2000, 33, 4, MlpAct::kSigmoid}};
  const int32_t batches[] = {0, 1, 2, 3, 5, 7, 8, 9, 15, 16, 17, 100};
  size_t compared = 0;
  for (const MlpShape& s : shapes) {
    for (int32_t batch : batches) {
      CAPTURE(kt->isa); CAPTURE(s.in); CAPTURE(s.hidden); CAPTURE(s.out); CAPTURE(int(s.act2)); CAPTURE(batch);
      std::mt19937_64 rng(uint64_t(batch) * 313 + uint64_t(s.in) * 17 + uint64_t(s.out));
      Net<float> n(s, batch, rng);
      const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out), Bn = size_t(batch);
      n.p[2][H / 2] = -100.0f;  // a dead hidden unit
      if (Bn > 0 && H > 1) {    // an exact 0 pre-activation: row 0's first unit, b1 = -(W1 x) in double
        double acc = 0;
        for (size_t i = 0; i < I; ++i) acc += double(n.p[1][i]) * double(n.p[0][i]);
        n.p[2][0] = float(-acc);
      }
      std::vector<float> h_ref = with_canary(Bn * H), y_ref = with_canary(Bn * O);
      gs::simd::mlp_fwd_ref<float>(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(),
                                   n.p[4].data(), h_ref.data(), y_ref.data());
      std::vector<float> h = with_canary(Bn * H, 3.0f), y = with_canary(Bn * O, 3.0f);
      kt->mlp_fwd_exact(&s, batch, n.p[0].data(), n.p[1].data(), n.p[2].data(), n.p[3].data(), n.p[4].data(), h.data(),
                        y.data());
      check_canary(h, Bn * H, "hidden");
      check_canary(y, Bn * O, "y");
      if (batch == 0) continue;  // nothing written: the canaries above
      CHECK(std::memcmp(h.data(), h_ref.data(), Bn * H * sizeof(float)) == 0);
      CHECK(std::memcmp(y.data(), y_ref.data(), Bn * O * sizeof(float)) == 0);
      compared += Bn * (H + O);
    }
  }
  MESSAGE(std::string(kt->isa) << ": " << compared << " values bit-identical to the reference");
}

TEST_CASE("adam: reference matches a hand-computed two-step example") {
  // lr 0.1, betas (0.9, 0.999), eps 1e-8, param 1, gradients 0.5 then -0.25.
  // Step 1: m = 0.05, v = 0.001 * 0.25 = 2.5e-4, bias corrections 0.1 and 0.001:
  //   param = 1 - (0.1 / 0.1) * 0.05 / (sqrt(2.5e-4 / 0.001) + 1e-8) = 1 - 0.05 / 0.50000001
  //         = 0.900000002.
  // Step 2: m = 0.9 * 0.05 - 0.1 * 0.25 = 0.02, v = 0.999 * 2.5e-4 + 0.001 * 0.0625 = 3.1225e-4,
  //   bias corrections 1 - 0.81 = 0.19 and 1 - 0.998001 = 0.001999:
  //   param = 0.900000002 - (0.1 / 0.19) * 0.02 / (sqrt(3.1225e-4 / 0.001999) + 1e-8)
  //         = 0.900000002 - 0.52631579 * 0.02 / 0.39522538 = 0.87336630.
  AdamParams p{0.1, 0.9, 0.999, 1e-8, 1};
  double param = 1, m = 0, v = 0;
  const double g1 = 0.5, g2 = -0.25;
  gs::simd::adam_step_ref<double>(&p, 1, &param, &g1, &m, &v);
  CHECK(m == doctest::Approx(0.05).epsilon(1e-14));
  CHECK(v == doctest::Approx(2.5e-4).epsilon(1e-14));
  CHECK(param == doctest::Approx(0.900000002).epsilon(1e-14));
  p.step = 2;
  gs::simd::adam_step_ref<double>(&p, 1, &param, &g2, &m, &v);
  CHECK(m == doctest::Approx(0.02).epsilon(1e-14));
  CHECK(v == doctest::Approx(3.1225e-4).epsilon(1e-14));
  CHECK(param == doctest::Approx(0.900000002 - (0.1 / 0.19) * 0.02 / (std::sqrt(3.1225e-4 / 0.001999) + 1e-8))
                     .epsilon(1e-14));
  CHECK(param == doctest::Approx(0.8733663).epsilon(1e-7));
}

GS_SIMD_TEST_CASE(adam_matches_ref, "adam: SIMD kernels match the float reference") {
  const gs::simd::KernelTable* const tables[] = {kt};  // one ISA per case (support/simd_isa.h)
  const size_t sizes[] = {1, 7, 33, 1000};
  double worst = 0;
  for (const gs::simd::KernelTable* t : tables) {
    for (size_t n : sizes) {
      CAPTURE(t->isa); CAPTURE(n);
      std::mt19937_64 rng(n);
      std::uniform_real_distribution<float> u(-1, 1);
      std::vector<float> param = with_canary(n), grad(n), m = with_canary(n), v = with_canary(n);
      for (size_t k = 0; k < n; ++k) {
        param[k] = u(rng);
        m[k] = 0.1f * u(rng);
        v[k] = 0.01f * std::fabs(u(rng));
      }
      std::vector<float> param_r = param, m_r = m, v_r = v;
      for (int64_t step = 1; step <= 3; ++step) {
        const AdamParams p{1e-3, 0.9, 0.999, 1e-8, step};
        for (size_t k = 0; k < n; ++k) grad[k] = u(rng);
        gs::simd::adam_step_ref<float>(&p, n, param_r.data(), grad.data(), m_r.data(), v_r.data());
        t->adam_step(&p, n, param.data(), grad.data(), m.data(), v.data());
      }
      check_canary(param, n, "param");
      check_canary(m, n, "m");
      check_canary(v, n, "v");
      // Elementwise, same operation order; only FMA contraction can differ (a few ULP of m, v and
      // of the update, which is ~1e-3 of param): 1e-6 relative (8 ULP) with a 1e-3 floor on the
      // scale so values near 0 are judged against the size of the update.
      for (size_t k = 0; k < n; ++k) {
        const double e = std::max({std::fabs(double(param[k]) - param_r[k]) / (std::fabs(param_r[k]) + 1e-3),
                                   std::fabs(double(m[k]) - m_r[k]) / (std::fabs(m_r[k]) + 1e-3),
                                   std::fabs(double(v[k]) - v_r[k]) / (std::fabs(v_r[k]) + 1e-3)});
        worst = std::max(worst, e);
        CHECK(e <= 1e-6);
      }
    }
  }
  MESSAGE("Adam SIMD vs ref worst relative error " << worst);
}
