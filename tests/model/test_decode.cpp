// SPDX-License-Identifier: MIT
// Neural-Gaussian decoding (gs/model/decode.h) in double: finite-difference checks of decode_bwd
// (MLP outputs, offsets, anchor log-scales) and of the volume regulariser, the decoder input rows,
// log_sigmoid at extreme arguments, the visibility pre-filter (behind, near plane, image border
// with a large scale, far outside, rotated camera) and the dropping rule (opacity <= 0, zero
// quaternion, NaN) with zero gradient for dropped candidates.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gs/model/decode.h"
#include "gs/model/step_graph.h"
#include "gs/platform/thread_pool.h"
#include "support/random_scene.h"

namespace gs::model {
namespace {

// 4-point central difference; every function checked here is smooth away from the drop rule
// (which the probes below stay clear of: |opacity| >= 0.05), and the objectives are O(10), so with
// h = 1e-5 the truncation error (h^4 f^(5) ~ 1e-20) and the rounding noise (1e-16 x 10 / 1e-5 =
// 1e-10) are both far below the tolerance: relative 1e-6 plus absolute 1e-8 (measured worst: 7e-8).
constexpr double kStep = 1e-5;
constexpr double kRelTol = 1e-6;
constexpr double kAbsTol = 1e-8;

template <class F>
double fd4(double* slot, F&& f, double h = kStep) {
  const double x0 = *slot;
  double l[4];
  const double off[4] = {-2 * h, -h, h, 2 * h};
  for (int i = 0; i < 4; ++i) {
    *slot = x0 + off[i];
    l[i] = f();
  }
  *slot = x0;
  return (8 * (l[2] - l[1]) - (l[3] - l[0])) / (12 * h);
}

bool close(double fd, double an) {
  return std::fabs(fd - an) <= kRelTol * std::max(std::fabs(fd), std::fabs(an)) + kAbsTol;
}

// A decoding problem: M anchors, rows = the visible subset, MLP outputs for V x k candidates.
struct Problem {
  size_t M = 7;
  int k = 4, F = 5;
  std::vector<double> positions, offsets, log_scales, features;
  std::vector<uint32_t> rows;
  std::vector<double> y_op, y_cov, y_col;  // [V, k] [V, k, 7] [V, k, 3]
  // Weights of the objective, indexed by candidate s (so the objective is a fixed function of the
  // inputs whichever candidates are kept).
  std::vector<double> w_mean, w_ls, w_q, w_op, w_col;

  explicit Problem(uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    positions.resize(3 * M);
    offsets.resize(3 * M * size_t(k));
    log_scales.resize(6 * M);
    features.resize(M * size_t(F));
    for (double& x : positions) x = 3 * u(rng);
    for (double& x : offsets) x = u(rng);
    for (double& x : log_scales) x = -1.5 + 0.5 * u(rng);
    for (double& x : features) x = u(rng);
    rows = {0, 2, 3, 5, 6};  // anchors 1 and 4 are not visible
    const size_t S = rows.size() * size_t(k);
    y_op.resize(S);
    y_cov.resize(7 * S);
    y_col.resize(3 * S);
    for (size_t s = 0; s < S; ++s) {
      // |opacity| >= 0.05 so no probe crosses the drop threshold; about a third are negative.
      const double a = 0.05 + 0.9 * (0.5 + 0.5 * u(rng));
      y_op[s] = (s % 3 == 1) ? -a : a;
    }
    for (double& x : y_cov) x = 2 * u(rng);
    for (double& x : y_col) x = 0.5 + 0.5 * u(rng);
    // Candidate 2 of visible anchor 1: positive opacity, zero quaternion -> dropped.
    y_op[1 * size_t(k) + 2] = 0.6;
    for (int l = 3; l < 7; ++l) y_cov[7 * (1 * size_t(k) + 2) + size_t(l)] = 0;
    w_mean.resize(3 * S), w_ls.resize(3 * S), w_q.resize(4 * S), w_op.resize(S), w_col.resize(3 * S);
    for (auto* w : {&w_mean, &w_ls, &w_q, &w_op, &w_col})
      for (double& x : *w) x = u(rng);
  }
  size_t V() const { return rows.size(); }
  AnchorParams<double> anchors() const {
    AnchorParams<double> a;
    a.count = M;
    a.k = k;
    a.feature_dim = F;
    a.positions = positions.data();
    a.offsets = offsets.data();
    a.log_scales = log_scales.data();
    a.features = features.data();
    return a;
  }
};

struct Decoded : NeuralGaussianBuffers<double> {
  explicit Decoded(size_t cap) { assign_rows(cap); }
};

double objective(const Problem& p, const Decoded& d) {
  double L = 0;
  for (size_t n = 0; n < d.ng.count; ++n) {
    const size_t s = d.source[n];
    for (int l = 0; l < 3; ++l)
      L += p.w_mean[3 * s + l] * d.means[3 * n + l] + p.w_ls[3 * s + l] * d.log_scales[3 * n + l] +
           p.w_col[3 * s + l] * d.colors[3 * n + l];
    for (int l = 0; l < 4; ++l) L += p.w_q[4 * s + l] * d.quats[4 * n + l];
    L += p.w_op[s] * d.opacities[n];
  }
  return L;
}

TEST_CASE("decode: forward values follow the documented formulas") {
  Problem p(1);
  Decoded d(p.V() * size_t(p.k));
  const size_t N = decode_fwd(p.anchors(), p.rows.data(), p.V(), p.y_op.data(), p.y_cov.data(), p.y_col.data(), &d.ng);
  CHECK(N == d.ng.count);
  size_t expected = 0;
  uint32_t prev = 0;
  for (size_t v = 0; v < p.V(); ++v)
    for (int j = 0; j < p.k; ++j) {
      const size_t s = v * size_t(p.k) + size_t(j);
      const double* c = &p.y_cov[7 * s];
      if (p.y_op[s] > 0 && c[3] * c[3] + c[4] * c[4] + c[5] * c[5] + c[6] * c[6] > 1e-24) ++expected;
    }
  REQUIRE(N == expected);
  REQUIRE(N > 0);
  for (size_t n = 0; n < N; ++n) {
    const uint32_t s = d.source[n];
    if (n > 0) CHECK(s > prev);  // kept in candidate order
    prev = s;
    const size_t v = s / uint32_t(p.k), j = s % uint32_t(p.k), row = p.rows[v];
    for (int l = 0; l < 3; ++l) {
      const double mean = p.positions[3 * row + l] + p.offsets[(row * size_t(p.k) + j) * 3 + l] * std::exp(p.log_scales[6 * row + l]);
      CHECK(d.means[3 * n + l] == doctest::Approx(mean).epsilon(1e-14));
      const double u = p.y_cov[7 * s + l];
      CHECK(d.log_scales[3 * n + l] == doctest::Approx(p.log_scales[6 * row + 3 + l] + std::log(1 / (1 + std::exp(-u)))).epsilon(1e-13));
      CHECK(d.colors[3 * n + l] == p.y_col[3 * s + l]);
    }
    for (int l = 0; l < 4; ++l) CHECK(d.quats[4 * n + l] == p.y_cov[7 * s + 3 + l]);
    CHECK(d.opacities[n] == p.y_op[s]);
  }
}

TEST_CASE("decode: finite differences of decode_bwd w.r.t. MLP outputs offsets and anchor log-scales") {
  for (uint64_t seed : {2, 3, 4}) {
    CAPTURE(seed);
    Problem p(seed);
    const size_t V = p.V(), k = size_t(p.k), S = V * k;
    Decoded d(S);
    auto fwd = [&]() {
      decode_fwd(p.anchors(), p.rows.data(), V, p.y_op.data(), p.y_cov.data(), p.y_col.data(), &d.ng);
      return objective(p, d);
    };
    fwd();
    const size_t N = d.ng.count;
    // dObjective / d(kept Gaussian outputs) = the weights of their candidates.
    std::vector<double> gm(3 * N), gl(3 * N), gq(4 * N), go(N), gc(3 * N);
    for (size_t n = 0; n < N; ++n) {
      const size_t s = d.source[n];
      for (int l = 0; l < 3; ++l) gm[3 * n + l] = p.w_mean[3 * s + l], gl[3 * n + l] = p.w_ls[3 * s + l], gc[3 * n + l] = p.w_col[3 * s + l];
      for (int l = 0; l < 4; ++l) gq[4 * n + l] = p.w_q[4 * s + l];
      go[n] = p.w_op[s];
    }
    const GaussianGradsT<double> g{gm.data(), gl.data(), gq.data(), go.data(), gc.data()};
    // Outputs pre-filled with garbage (must be overwritten), anchor gradients with a constant
    // (must be accumulated into).
    constexpr double kPre = 0.25;
    std::vector<double> v_op(S, 7.0), v_cov(7 * S, 7.0), v_col(3 * S, 7.0);
    std::vector<double> v_off(p.offsets.size(), kPre), v_ls(p.log_scales.size(), kPre);
    decode_bwd(p.anchors(), p.rows.data(), V, p.y_cov.data(), d.ng, g, v_op.data(), v_cov.data(), v_col.data(), v_off.data(), v_ls.data());

    int probes = 0, failures = 0, nonzero = 0;
    double worst = 0;
    auto check = [&](const std::string& name, size_t i, double* slot, double an) {
      const double fd = fd4(slot, fwd);
      ++probes;
      if (std::fabs(an) > 1e-6) ++nonzero;
      if (std::fabs(an) > 1e-6) worst = std::max(worst, std::fabs(fd - an) / std::fabs(an));
      if (!close(fd, an)) {
        ++failures;
        MESSAGE(name << "[" << i << "]: fd " << fd << " vs analytic " << an);
      }
    };
    for (size_t s = 0; s < S; ++s) {
      check("y_opacity", s, &p.y_op[s], v_op[s]);
      // (The zero quaternion of the dropped candidate sits on the drop boundary: any step keeps it.)
      const bool zero_q = p.y_cov[7 * s + 3] == 0 && p.y_cov[7 * s + 4] == 0 && p.y_cov[7 * s + 5] == 0 && p.y_cov[7 * s + 6] == 0;
      for (size_t l = 0; l < (zero_q ? 3 : 7); ++l) check("y_cov", 7 * s + l, &p.y_cov[7 * s + l], v_cov[7 * s + l]);
      for (size_t l = 0; l < 3; ++l) check("y_color", 3 * s + l, &p.y_col[3 * s + l], v_col[3 * s + l]);
    }
    for (size_t i = 0; i < p.offsets.size(); ++i) check("offset", i, &p.offsets[i], v_off[i] - kPre);
    for (size_t i = 0; i < p.log_scales.size(); ++i) check("anchor log-scale", i, &p.log_scales[i], v_ls[i] - kPre);
    MESSAGE("seed " << seed << ": " << probes << " probes (" << nonzero << " non-zero), worst relative error " << worst);
    CHECK(failures == 0);
    CHECK(nonzero > probes / 2);

    // Dropped candidates: exactly zero gradient; rows 1 and 4 (not visible) untouched.
    for (size_t s = 0; s < S; ++s) {
      const bool kept = std::find(d.source.begin(), d.source.begin() + long(N), uint32_t(s)) != d.source.begin() + long(N);
      if (kept) continue;
      CHECK(v_op[s] == 0);
      for (size_t l = 0; l < 7; ++l) CHECK(v_cov[7 * s + l] == 0);
      for (size_t l = 0; l < 3; ++l) CHECK(v_col[3 * s + l] == 0);
    }
    for (size_t row : {size_t(1), size_t(4)}) {
      for (size_t i = 0; i < 3 * k; ++i) CHECK(v_off[row * 3 * k + i] == kPre);
      for (size_t i = 0; i < 6; ++i) CHECK(v_ls[6 * row + i] == kPre);
    }
  }
}

TEST_CASE("decode: the drop rule is strict and the zero-quaternion threshold is 1e-24") {
  Problem p(5);
  const size_t k = size_t(p.k);
  // Visible anchor 0: candidates with opacity exactly 0, -0, a tiny positive value, NaN.
  p.y_op[0] = 0.0;
  p.y_op[1] = -0.0;
  p.y_op[2] = 1e-300;
  p.y_op[3] = std::numeric_limits<double>::quiet_NaN();
  for (size_t j = 0; j < 4; ++j) p.y_cov[7 * j + 3] = 1;  // valid quaternions
  // Visible anchor 2: quaternions of squared norm 1e-26 (dropped), 4e-24 (kept), 1e-24 exactly
  // representable is not, so use 0 and a large one.
  const size_t b = 2 * k;
  for (size_t j = 0; j < 4; ++j) {
    p.y_op[b + j] = 0.5;
    for (int l = 3; l < 7; ++l) p.y_cov[7 * (b + j) + size_t(l)] = 0;
  }
  p.y_cov[7 * (b + 0) + 3] = 1e-13;  // |q|^2 = 1e-26
  p.y_cov[7 * (b + 1) + 4] = 2e-12;  // |q|^2 = 4e-24
  p.y_cov[7 * (b + 2) + 5] = 0;      // zero
  p.y_cov[7 * (b + 3) + 6] = -1e-3;  // kept
  Decoded d(p.V() * k);
  const size_t N = decode_fwd(p.anchors(), p.rows.data(), p.V(), p.y_op.data(), p.y_cov.data(), p.y_col.data(), &d.ng);
  auto kept = [&](size_t s) { return std::find(d.source.begin(), d.source.begin() + long(N), uint32_t(s)) != d.source.begin() + long(N); };
  CHECK_FALSE(kept(0));
  CHECK_FALSE(kept(1));
  CHECK(kept(2));
  CHECK_FALSE(kept(3));
  CHECK_FALSE(kept(b + 0));
  CHECK(kept(b + 1));
  CHECK_FALSE(kept(b + 2));
  CHECK(kept(b + 3));
  // Whatever the gradients of the kept Gaussians, the dropped candidates get exact zeros.
  std::vector<double> ones(7 * N, 1.0);
  const GaussianGradsT<double> g{ones.data(), ones.data(), ones.data(), ones.data(), ones.data()};
  const size_t S = p.V() * k;
  std::vector<double> v_op(S, 9.0), v_cov(7 * S, 9.0), v_col(3 * S, 9.0), v_off(p.offsets.size(), 0), v_ls(p.log_scales.size(), 0);
  decode_bwd(p.anchors(), p.rows.data(), p.V(), p.y_cov.data(), d.ng, g, v_op.data(), v_cov.data(), v_col.data(), v_off.data(), v_ls.data());
  for (size_t s : {size_t(0), size_t(1), size_t(3), b + 0, b + 2}) {
    CAPTURE(s);
    CHECK(v_op[s] == 0);
    for (size_t l = 0; l < 7; ++l) CHECK(v_cov[7 * s + l] == 0);
    for (size_t l = 0; l < 3; ++l) CHECK(v_col[3 * s + l] == 0);
    // ... and add nothing to their offsets.
    const size_t row = p.rows[s / k], j = s % k;
    for (size_t l = 0; l < 3; ++l) CHECK(v_off[(row * k + j) * 3 + l] == 0);
  }
  for (size_t s : {size_t(2), b + 1, b + 3}) CHECK(v_op[s] == 1.0);
}

TEST_CASE("decode: log_sigmoid and its derivative are finite and accurate at extreme arguments") {
  for (double u : {-1000.0, -100.0, -30.0, -1.0, 0.0, 1.0, 30.0, 100.0, 1000.0}) {
    CAPTURE(u);
    const double ls = log_sigmoid(u);
    CHECK(std::isfinite(ls));
    CHECK(ls <= 0);
    // Exact forms: u < 0: u - log1p(exp(u)); u >= 0: -log1p(exp(-u)).
    const double expect = u < 0 ? u - std::log1p(std::exp(u)) : -std::log1p(std::exp(-u));
    CHECK(ls == doctest::Approx(expect).epsilon(1e-15));
    const float lsf = log_sigmoid(float(u));
    CHECK(std::isfinite(lsf));
    CHECK(double(lsf) == doctest::Approx(expect).epsilon(1e-6));
    // The derivative the backward uses, 1 - sigmoid(u), is finite and in [0, 1].
    const double dsig = 1 - sigmoid(u);
    CHECK(std::isfinite(dsig));
    CHECK(dsig >= 0);
    CHECK(dsig <= 1);
    if (std::fabs(u) <= 30) {
      double x = u;
      const double fd = fd4(&x, [&] { return log_sigmoid(x); }, 1e-4);
      CHECK(fd == doctest::Approx(dsig).epsilon(1e-9));
    }
  }
  CHECK(log_sigmoid(-100.0) == doctest::Approx(-100.0).epsilon(1e-15));
  CHECK(log_sigmoid(100.0) < 0);
  CHECK(log_sigmoid(100.0) > -1e-40);
  // The decoded log-scale stays finite for u_s = +-100 and the backward's factor is finite.
  Problem p(6);
  p.y_op.assign(p.y_op.size(), 0.5);
  for (size_t s = 0; s < p.y_op.size(); ++s) p.y_cov[7 * s] = (s % 2 ? 100.0 : -100.0), p.y_cov[7 * s + 3] = 1;
  Decoded d(p.y_op.size());
  const size_t N = decode_fwd(p.anchors(), p.rows.data(), p.V(), p.y_op.data(), p.y_cov.data(), p.y_col.data(), &d.ng);
  REQUIRE(N == p.y_op.size());
  for (size_t i = 0; i < 3 * N; ++i) CHECK(std::isfinite(d.log_scales[i]));
}

TEST_CASE("decode: volume regulariser value and finite-difference gradient") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-3, 0);
  const size_t N = 9;
  std::vector<double> ls(3 * N);
  for (double& x : ls) x = u(rng);
  const double weight = 0.37;
  double expect = 0;
  for (size_t n = 0; n < N; ++n) expect += std::exp(ls[3 * n]) * std::exp(ls[3 * n + 1]) * std::exp(ls[3 * n + 2]);
  expect *= weight / double(N);
  constexpr double kPre = -0.5;
  std::vector<double> v(3 * N, kPre);
  const double val = volume_fwd_bwd(N, ls.data(), weight, v.data());
  CHECK(val == doctest::Approx(expect).epsilon(1e-14));
  for (size_t i = 0; i < 3 * N; ++i) {
    CAPTURE(i);
    const double fd = fd4(&ls[i], [&] { return volume_fwd_bwd(N, ls.data(), weight, static_cast<double*>(nullptr)); });
    CHECK(close(fd, v[i] - kPre));
    CHECK(std::fabs(fd) > 1e-6);
  }
  // Empty set and zero weight: 0, nothing written.
  std::vector<double> untouched(3 * N, 1.5);
  CHECK(volume_fwd_bwd(size_t(0), ls.data(), weight, untouched.data()) == 0);
  CHECK(volume_fwd_bwd(N, ls.data(), 0.0, untouched.data()) == 0);
  for (double x : untouched) CHECK(x == 1.5);
}

// The step graph's volume_term: on a pool the exps run in parallel ranges and the sum follows in
// index order, so value and gradient are volume_fwd_bwd's bit for bit (float, as in training).
TEST_CASE("decode: volume_term on 1, 2 and 3 threads is volume_fwd_bwd exactly") {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<float> u(-6, 1);
  const size_t N = 20011;
  std::vector<float> ls(3 * N);
  for (float& x : ls) x = u(rng);
  const double weight = 0.01;
  std::vector<float> expect_v(3 * N, 0.0f);
  const double expect = volume_fwd_bwd(N, ls.data(), weight, expect_v.data());
  std::vector<double> scratch(N);
  for (int threads : {1, 2, 3}) {
    CAPTURE(threads);
    platform::ThreadPool pool(threads);
    std::vector<float> v(3 * N, 9.0f);  // volume_term zeroes it first
    const double got = volume_term(&pool, N, ls.data(), weight, v.data(), scratch.data(), N * sizeof(double));
    CHECK(got == expect);
    CHECK(v == expect_v);
  }
}

TEST_CASE("decode: decoder input rows are features then image features then direction and distance") {
  Problem p(8);
  const int G = 3;
  const size_t V = p.V(), D = size_t(p.F + G + 4);
  std::vector<double> g(V * size_t(G));
  for (size_t i = 0; i < g.size(); ++i) g[i] = 0.1 * double(i) - 0.7;
  const double centre[3] = {0.4, -0.3, -5.0};
  // Put visible anchor 3 (row 5) exactly at the camera centre: finite output, distance 1e-6.
  for (int c = 0; c < 3; ++c) p.positions[3 * 5 + size_t(c)] = centre[c];
  std::vector<double> X(V * D, -99);
  build_decoder_input(p.anchors(), p.rows.data(), V, g.data(), G, centre, X.data());
  for (size_t v = 0; v < V; ++v) {
    CAPTURE(v);
    const size_t row = p.rows[v];
    const double* x = &X[v * D];
    for (int c = 0; c < p.F; ++c) CHECK(x[c] == p.features[row * size_t(p.F) + size_t(c)]);
    for (int c = 0; c < G; ++c) CHECK(x[p.F + c] == g[v * size_t(G) + size_t(c)]);
    const double d[3] = {p.positions[3 * row] - centre[0], p.positions[3 * row + 1] - centre[1], p.positions[3 * row + 2] - centre[2]};
    const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int c = 0; c < 4; ++c) CHECK(std::isfinite(x[p.F + G + c]));
    if (row == 5) {
      CHECK(x[p.F + G + 3] == 1e-6);
      continue;
    }
    for (int c = 0; c < 3; ++c) CHECK(x[p.F + G + c] == doctest::Approx(d[c] / dist).epsilon(1e-14));
    CHECK(x[p.F + G + 3] == doctest::Approx(dist).epsilon(1e-14));
  }
  // G = 0 (image features off): D = F + 4, g ignored.
  const size_t D0 = size_t(p.F + 4);
  std::vector<double> X0(V * D0);
  build_decoder_input(p.anchors(), p.rows.data(), V, static_cast<const double*>(nullptr), 0, centre, X0.data());
  for (size_t v = 0; v < V; ++v) {
    for (int c = 0; c < p.F; ++c) CHECK(X0[v * D0 + size_t(c)] == X[v * D + size_t(c)]);
    for (int c = 0; c < 4; ++c) CHECK(X0[v * D0 + size_t(p.F + c)] == X[v * D + size_t(p.F + G + c)]);
  }
  // The centre from the pose: C = -R^T t.
  std::mt19937_64 rng(9);
  const ref::View<double> vw = test::random_view(rng, 32, 24);
  const Camera cam = test::to_camera(test::to_float(vw));
  double C[3];
  camera_centre(cam.pose, C);
  for (int i = 0; i < 3; ++i) {
    double x = double(cam.pose.t[i]);
    for (int j = 0; j < 3; ++j) x += double(cam.pose.R[3 * i + j]) * C[j];
    CHECK(std::fabs(x) < 1e-6);  // R C + t = 0
  }
}

TEST_CASE("decode: finite differences of the decoder input w.r.t. the camera centre and its pose chain") {
  Problem p(11);
  const int G = 2;
  const size_t V = p.V(), D = size_t(p.F + G + 4);
  std::vector<double> g(V * size_t(G), 0.3);
  std::mt19937_64 rng(12);
  std::normal_distribution<double> nrm(0, 1);
  std::vector<double> w(V * D);  // objective L = sum w . X
  for (double& x : w) x = nrm(rng);
  double centre[3] = {0.4, -0.3, -5.0};
  std::vector<double> X(V * D);
  auto objective = [&] {
    build_decoder_input(p.anchors(), p.rows.data(), V, g.data(), G, centre, X.data());
    double l = 0;
    for (size_t i = 0; i < X.size(); ++i) l += w[i] * X[i];
    return l;
  };
  double v_centre[3] = {0, 0, 0};
  decoder_input_centre_bwd(p.anchors(), p.rows.data(), V, G, centre, w.data(), v_centre);
  for (int c = 0; c < 3; ++c) {
    const double fd = fd4(&centre[c], objective);
    CAPTURE(c);
    CHECK(std::fabs(v_centre[c]) > 1e-3);
    CHECK(close(fd, v_centre[c]));
  }
  // An anchor on the distance floor contributes nothing and stays finite.
  for (int c = 0; c < 3; ++c) p.positions[3 * size_t(p.rows[0]) + size_t(c)] = centre[c];
  double v_floor[3] = {0, 0, 0};
  decoder_input_centre_bwd(p.anchors(), p.rows.data(), 1, G, centre, w.data(), v_floor);
  for (int c = 0; c < 3; ++c) CHECK(v_floor[c] == 0);

  // The chain to the twist: C(rho) = -R^T (t + rho) for T <- Exp((rho, 0)) T, so dL/drho = -R g_C.
  const ref::View<double> vw = test::random_view(rng, 32, 24);
  const Camera cam = test::to_camera(test::to_float(vw));
  const double g_c[3] = {0.7, -1.1, 0.4};
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
  centre_grad_to_pose(cam.pose, g_c, v_pose);
  for (int r = 0; r < 3; ++r) {
    double expect = 0;  // d(g_C . C)/d rho_r = -sum_j g_C[j] R[r][j]
    for (int j = 0; j < 3; ++j) expect -= g_c[j] * double(cam.pose.R[3 * r + j]);
    CHECK(v_pose[r] == doctest::Approx(expect).epsilon(1e-12));
  }
  for (int r = 3; r < 6; ++r) CHECK(v_pose[r] == 0);
}

// Visibility pre-filter cases on a 64 x 48 camera (fx = 50, fy = 55, principal point off centre).
struct VisCase {
  Camera cam;
  std::vector<double> positions, log_scales;
  std::vector<double> offsets, features;
  void add(double x, double y, double z, double log_s, double log_base = -2.0) {
    // (x, y, z) in camera coordinates -> world through the inverse pose.
    const double c[3] = {x - cam.pose.t[0], y - cam.pose.t[1], z - cam.pose.t[2]};
    for (int k = 0; k < 3; ++k)
      positions.push_back(cam.pose.R[k] * c[0] + cam.pose.R[3 + k] * c[1] + cam.pose.R[6 + k] * c[2]);
    for (int k = 0; k < 3; ++k) log_scales.push_back(k == 1 ? log_s : log_s - 0.5);  // max is component 1
    for (int k = 0; k < 3; ++k) log_scales.push_back(log_base);
  }
  std::vector<uint32_t> select() {
    AnchorParams<double> a;
    a.count = positions.size() / 3;
    a.k = 1;
    a.feature_dim = 0;
    a.positions = positions.data();
    a.log_scales = log_scales.data();
    std::vector<uint32_t> rows(a.count + 1, 999);
    const size_t V = select_visible_anchors(cam, a, rows.data());
    CHECK(rows[V] == 999);  // never writes past V
    rows.resize(V);
    return rows;
  }
};

void visibility_cases(const Camera& cam) {
  VisCase c;
  c.cam = cam;
  const double fx = cam.intr.fx, fy = cam.intr.fy, cx = cam.intr.cx, cy = cam.intr.cy;
  const double fmax = std::max(fx, fy);
  auto at_pixel = [&](double u, double v, double z) { return std::vector<double>{(u - cx) / fx * z, (v - cy) / fy * z, z}; };
  std::vector<bool> expect;
  auto add = [&](std::vector<double> p, double log_s, bool visible, double log_base = -2.0) {
    c.add(p[0], p[1], p[2], log_s, log_base);
    expect.push_back(visible);
  };
  add(at_pixel(32, 24, 3), std::log(0.01), true);     // 0: centre
  add({0.0, 0.0, -3.0}, std::log(0.01), false);       // 1: behind the camera
  add({0.0, 0.0, -3.0}, std::log(10.0), false);       // 2: behind with a huge scale
  add({0.0, 0.0, 0.15}, std::log(0.01), false);       // 3: in front of the near plane
  add({0.0, 0.0, 0.25}, std::log(0.01), true);        // 4: just beyond it
  // 5, 6: 20 px left of the image at z = 2: r = 3 s fmax / z + 1 must exceed 20 px.
  const double s_big = 30.0 * 2.0 / (3.0 * fmax), s_small = 10.0 * 2.0 / (3.0 * fmax);
  add(at_pixel(-20, 24, 2), std::log(s_big), true);
  add(at_pixel(-20, 24, 2), std::log(s_small), false);
  // 7: same small scale but a huge base scale l[3:6]: only l[0:3] counts.
  add(at_pixel(-20, 24, 2), std::log(s_small), false, std::log(100.0));
  add(at_pixel(64 + 20, 48 + 15, 2), std::log(s_big), true);  // 8: beyond the bottom-right corner, big scale
  add(at_pixel(10000, 24, 2), std::log(0.01), false);         // 9: far outside
  add(at_pixel(24, -1e4, 5), std::log(1.0), false);           // 10: far above with a unit scale
  add(at_pixel(63.9, 47.9, 8), std::log(1e-4), true);         // 11: inside near the corner, tiny scale
  // 12, 13: the exact edge: u + r = -0.05 px (out) and +0.05 px (in) with s = 0.01 at z = 2.
  const double r = 3 * 0.01 * fmax / 2.0 + 1.0;
  add(at_pixel(-r - 0.05, 24, 2), std::log(0.01), false);
  add(at_pixel(-r + 0.05, 24, 2), std::log(0.01), true);
  const std::vector<uint32_t> rows = c.select();
  std::vector<uint32_t> want;
  for (size_t i = 0; i < expect.size(); ++i)
    if (expect[i]) want.push_back(uint32_t(i));
  CHECK(rows == want);
}

TEST_CASE("decode: visibility pre-filter excludes anchors behind and outside and keeps large ones at the border") {
  Camera cam;
  cam.intr = {50, 55, 31.3f, 24.6f, 64, 48};
  visibility_cases(cam);
  // The same cases for a rotated and translated camera (positions placed through its pose).
  std::mt19937_64 rng(10);
  const ref::View<double> vw = test::random_view(rng, 64, 48);
  Camera rot = test::to_camera(test::to_float(vw));
  rot.intr = cam.intr;
  visibility_cases(rot);
}


// The step graph runs decoding in ranges of visible anchors (in parallel) and joins them in order:
// every split must give the one-pass results exactly.
TEST_CASE("decode: ranges of visible anchors joined in order equal one pass forward and backward") {
  Problem p(3);
  const AnchorParams<double> a = p.anchors();
  const size_t V = p.V(), K = size_t(p.k), S = V * K;
  Decoded whole(S);
  decode_fwd(a, p.rows.data(), V, p.y_op.data(), p.y_cov.data(), p.y_col.data(), &whole.ng);
  // Gradients of the kept Gaussians (any values), and the one-pass backward.
  std::vector<double> g_mean(3 * S), g_ls(3 * S), g_q(4 * S), g_op(S), g_col(3 * S);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  for (auto* g : {&g_mean, &g_ls, &g_q, &g_op, &g_col})
    for (double& x : *g) x = u(rng);
  const GaussianGradsT<double> gg{g_mean.data(), g_ls.data(), g_q.data(), g_op.data(), g_col.data()};
  struct Bwd {
    std::vector<double> v_op, v_cov, v_col, v_off, v_ls;
  };
  auto fresh = [&]() {
    Bwd b{std::vector<double>(S, 7.0), std::vector<double>(7 * S, 7.0), std::vector<double>(3 * S, 7.0),
          std::vector<double>(p.offsets.size(), 0.5), std::vector<double>(p.log_scales.size(), 0.5)};
    return b;
  };
  Bwd one = fresh();
  decode_bwd(a, p.rows.data(), V, p.y_cov.data(), whole.ng, gg, one.v_op.data(), one.v_cov.data(), one.v_col.data(),
             one.v_off.data(), one.v_ls.data());
  for (size_t parts = 1; parts <= V; ++parts) {
    CAPTURE(parts);
    Decoded split(S);
    size_t n = 0;
    for (size_t i = 0; i < parts; ++i) {
      const size_t v0 = i * V / parts, v1 = (i + 1) * V / parts;
      const size_t kept = count_kept_range(p.k, v0, v1, p.y_op.data(), p.y_cov.data());
      CHECK(decode_fwd_range(a, p.rows.data(), v0, v1, p.y_op.data(), p.y_cov.data(), p.y_col.data(), n, &split.ng) ==
            kept);
      n += kept;
    }
    split.ng.count = n;
    REQUIRE(n == whole.ng.count);
    CHECK(split.means == whole.means);
    CHECK(split.log_scales == whole.log_scales);
    CHECK(split.quats == whole.quats);
    CHECK(split.opacities == whole.opacities);
    CHECK(split.colors == whole.colors);
    CHECK(split.source == whole.source);
    Bwd b = fresh();
    for (size_t i = parts; i-- > 0;)  // last range first: no range may rely on another's order
      decode_bwd_range(a, p.rows.data(), i * V / parts, (i + 1) * V / parts, p.y_cov.data(), split.ng, gg,
                       b.v_op.data(), b.v_cov.data(), b.v_col.data(), b.v_off.data(), b.v_ls.data());
    CHECK(b.v_op == one.v_op);
    CHECK(b.v_cov == one.v_cov);
    CHECK(b.v_col == one.v_col);
    CHECK(b.v_off == one.v_off);
    CHECK(b.v_ls == one.v_ls);
  }
  // Visibility in ranges: each range's rows, concatenated, are the one-pass rows.
  Camera cam;
  cam.intr.fx = cam.intr.fy = 40.0f;  // a small image: some anchors fall outside it
  cam.intr.cx = 8.0f;
  cam.intr.cy = 6.0f;
  cam.intr.width = 16;
  cam.intr.height = 12;
  cam.pose.t[2] = 6.0f;
  std::vector<uint32_t> all(p.M), joined;
  const size_t visible = select_visible_anchors(cam, a, all.data());
  all.resize(visible);
  MESSAGE("visible anchors: " << visible << " of " << p.M);
  REQUIRE(visible > 0);
  for (size_t b = 0; b < p.M; b += 3) {
    std::vector<uint32_t> part(3);
    part.resize(select_visible_anchor_range(cam, a, b, std::min(p.M, b + 3), part.data()));
    joined.insert(joined.end(), part.begin(), part.end());
  }
  CHECK(joined == all);
}

}  // namespace
}  // namespace gs::model
