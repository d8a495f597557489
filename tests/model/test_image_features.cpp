// SPDX-License-Identifier: MIT
// Image-based anchor features (gs/model/image_features.h) on a synthetic rig: three cameras with
// known poses and 8-bit images whose colour is a known function of the pixel. Checks the view
// choice (the camera whose optical axis points most directly at the anchor, among those that see
// it), the -1 / all-zero result for anchors behind or outside every camera, level-0 colour as the
// bilinear sample at the projection (pixel centres at +0.5), levels 1-2 as 2x2 box-downsampled
// images sampled at the same point, the valid flag, the ray deviation, pose re-reading, errors, and
// that compute() allocates nothing.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gs/model/hybrid_model.h"
#include "gs/model/image_features.h"
#include "gs/platform/thread_pool.h"
#include "support/alloc_counter.h"
#include "support/model_fixtures.h"
#include "support/rgb_image.h"

namespace gs::model {
namespace {

constexpr int kW = 64, kH = 48;  // multiples of 4: levels 1 and 2 are exact 2x2 reductions

Camera look_at(const double C[3], const double at[3], float fx, float cx, float cy) {
  return test::look_at(C, at, PinholeIntrinsics{fx, fx, cx, cy, kW, kH});
}


// Colour of view v at pixel (x, y): a strongly varying but known pattern.
uint8_t texel(int v, int x, int y, int c) { return uint8_t((x * (37 + 5 * c) + y * (11 + 7 * c) + 29 * v + x * y * (c + 1)) % 256); }

io::Image8 make_image(int v) { return test::rgb_image(kW, kH, [v](int x, int y, int c) { return texel(v, x, y, c); }); }

// Reference pyramid level l of view v in double (exact 2^l x 2^l box averages, no rounding).
double level_texel(int v, int l, int x, int y, int c) {
  const int s = 1 << l;
  double sum = 0;
  for (int dy = 0; dy < s; ++dy)
    for (int dx = 0; dx < s; ++dx) sum += texel(v, s * x + dx, s * y + dy, c);
  return sum / (s * s) / 255.0;
}

// Bilinear sample of level l at level-0 pixel coordinates (u, v): level-l coordinates u / 2^l,
// pixel centres at +0.5, clamped at the edges.
double sample_ref(int view, int l, double u, double v, int c) {
  const int w = kW >> l, h = kH >> l;
  const double px = std::clamp(u / (1 << l) - 0.5, 0.0, double(w - 1)), py = std::clamp(v / (1 << l) - 0.5, 0.0, double(h - 1));
  const int x0 = int(std::floor(px)), y0 = int(std::floor(py));
  const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const double fx = px - x0, fy = py - y0;
  return (1 - fy) * ((1 - fx) * level_texel(view, l, x0, y0, c) + fx * level_texel(view, l, x1, y0, c)) +
         fy * ((1 - fx) * level_texel(view, l, x0, y1, c) + fx * level_texel(view, l, x1, y1, c));
}

struct Rig {
  std::vector<Camera> cams;
  std::vector<io::Image8> images;
  ImageFeatureBank bank;
  Rig() {
    // A: at the origin looking along +z. B: at (4, 0, 0) looking at (1, 0.5, 6). C: at (-3, -1, 1)
    // looking at (0, 0, 8), a longer focal length (narrower view).
    const double a0[3] = {0, 0, 0}, a1[3] = {0, 0, 10};
    const double b0[3] = {4, 0, 0}, b1[3] = {1, 0.5, 6};
    const double c0[3] = {-3, -1, 1}, c1[3] = {0, 0, 8};
    cams.push_back(look_at(a0, a1, 50, 32, 24));
    cams.push_back(look_at(b0, b1, 45, 30.5f, 25));
    cams.push_back(look_at(c0, c1, 80, 33, 23.5f));
    for (int v = 0; v < 3; ++v) images.push_back(make_image(v));
    std::vector<const Camera*> cp;
    std::vector<const io::Image8*> ip;
    for (int v = 0; v < 3; ++v) cp.push_back(&cams[size_t(v)]), ip.push_back(&images[size_t(v)]);
    const Status st = bank.init(cp, ip);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
  }
};

// Camera-frame point, pixel, and whether camera `cam` sees p (z > 0.2, 0 <= u < W, 0 <= v < H).
bool sees(const Camera& cam, const float p[3], double xc[3], double* u, double* v) {
  for (int r = 0; r < 3; ++r)
    xc[r] = double(cam.pose.R[3 * r]) * p[0] + double(cam.pose.R[3 * r + 1]) * p[1] + double(cam.pose.R[3 * r + 2]) * p[2] + double(cam.pose.t[r]);
  if (!(xc[2] > 0.2)) return false;
  *u = cam.intr.fx * xc[0] / xc[2] + cam.intr.cx;
  *v = cam.intr.fy * xc[1] / xc[2] + cam.intr.cy;
  return *u >= 0 && *u < cam.intr.width && *v >= 0 && *v < cam.intr.height;
}

// The view whose optical axis is closest in angle to the anchor among those that see it (the
// ALGORITHM.md score adds |x - c| / 200, which only matters for near ties).
int expected_view(const Rig& rig, const float p[3]) {
  int best = -1;
  double best_score = 0;
  for (size_t j = 0; j < rig.cams.size(); ++j) {
    double xc[3], u, v;
    if (!sees(rig.cams[j], p, xc, &u, &v)) continue;
    const double d = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1] + xc[2] * xc[2]);
    const double score = d / 200 + 1.1 - xc[2] / d;
    if (best < 0 || score < best_score) best = int(j), best_score = score;
  }
  return best;
}

void check_features(const Rig& rig, const float p[3], const float raw[kImageRawDim], int view) {
  REQUIRE(view >= 0);
  double xc[3], u, v;
  REQUIRE(sees(rig.cams[size_t(view)], p, xc, &u, &v));
  for (int l = 0; l < kImagePyramidLevels; ++l)
    for (int c = 0; c < 3; ++c) {
      CAPTURE(l);
      CAPTURE(c);
      // Level 0 is read from the 8-bit image exactly; levels 1-2 are 8-bit (rounded) reductions.
      const double tol = l == 0 ? 1e-5 : 1.01 / 255;
      CHECK(std::fabs(double(raw[3 * l + c]) - sample_ref(view, l, u, v, c)) <= tol);
    }
  const double n = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1] + xc[2] * xc[2]);
  CHECK(raw[9] == doctest::Approx(xc[0] / n).epsilon(1e-5));
  CHECK(raw[10] == doctest::Approx(xc[1] / n).epsilon(1e-5));
  CHECK(double(raw[11]) == doctest::Approx(xc[2] / n - 1).epsilon(1e-5).scale(1e-2));
  CHECK(raw[12] == 1.0f);
}

// World point seen by camera `cam` at pixel (u, v) and depth z.
void unproject(const Camera& cam, double u, double v, double z, float p[3]) {
  const double c[3] = {(u - cam.intr.cx) / cam.intr.fx * z - cam.pose.t[0], (v - cam.intr.cy) / cam.intr.fy * z - cam.pose.t[1],
                       z - cam.pose.t[2]};
  for (int k = 0; k < 3; ++k) p[k] = float(cam.pose.R[k] * c[0] + cam.pose.R[3 + k] * c[1] + cam.pose.R[6 + k] * c[2]);
}

TEST_CASE("image features: the chosen view is the camera whose axis points most directly at the anchor") {
  Rig rig;
  CHECK(rig.bank.view_count() == 3);
  // On A's axis: A (cos = 1), although B sees it too.
  const float on_a[3] = {0, 0, 6};
  double xc[3], u, v;
  REQUIRE(sees(rig.cams[1], on_a, xc, &u, &v));
  CHECK(rig.bank.best_view(on_a) == 0);
  // On B's axis (seen by A as well): B.
  float on_b[3];
  unproject(rig.cams[1], rig.cams[1].intr.cx, rig.cams[1].intr.cy, 5.0, on_b);
  REQUIRE(sees(rig.cams[0], on_b, xc, &u, &v));
  CHECK(rig.bank.best_view(on_b) == 1);
  // On C's axis, also seen by A: C even though A is nearer.
  float on_c[3];
  unproject(rig.cams[2], rig.cams[2].intr.cx, rig.cams[2].intr.cy, 8.0, on_c);
  REQUIRE(sees(rig.cams[0], on_c, xc, &u, &v));
  CHECK(rig.bank.best_view(on_c) == 2);
  // Random anchors in front of the rig against the reference rule; every camera wins somewhere.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> ux(-6, 6), uz(1, 12);
  int wins[4] = {0, 0, 0, 0}, mismatches = 0;
  for (int i = 0; i < 2000; ++i) {
    const float p[3] = {float(ux(rng)), float(0.5 * ux(rng)), float(uz(rng))};
    const int want = expected_view(rig, p), got = rig.bank.best_view(p);
    ++wins[want + 1];
    if (want != got) {
      ++mismatches;
      if (mismatches < 5) MESSAGE("anchor (" << p[0] << ", " << p[1] << ", " << p[2] << "): view " << got << ", expected " << want);
    }
  }
  MESSAGE("2000 random anchors: none " << wins[0] << ", A " << wins[1] << ", B " << wins[2] << ", C " << wins[3]);
  CHECK(mismatches == 0);
  for (int w : wins) CHECK(w > 20);
}

TEST_CASE("image features: anchors behind or outside every camera get -1 and 13 zeros") {
  Rig rig;
  const float behind[3] = {0.5f, 0, -20};     // behind all three cameras
  const float outside[3] = {60, 0, 5};        // far to the side of every frustum
  const float below[3] = {0, 200, 10};        // far below every image
  float near_plane[3];                        // on A's axis at z = 0.15, before its near plane;
  unproject(rig.cams[0], 32, 24, 0.15, near_plane);  // B and C do not see it either
  for (const float* p : {behind, outside, below, static_cast<const float*>(near_plane)}) {
    CAPTURE(p[0]);
    CAPTURE(p[2]);
    for (size_t j = 0; j < 3; ++j) {
      double xc[3], u, v;
      REQUIRE_FALSE(sees(rig.cams[j], p, xc, &u, &v));
    }
    CHECK(rig.bank.best_view(p) == -1);
    float raw[kImageRawDim];
    std::fill(raw, raw + kImageRawDim, 7.0f);
    rig.bank.compute(p, 1, raw, nullptr);
    for (float x : raw) CHECK(x == 0.0f);
  }
  // Just inside and just outside A's right edge (u = W - 0.01 and W + 0.01) where only A could see it.
  float in[3], out[3];
  unproject(rig.cams[0], kW - 0.01, 4, 0.5, in);
  unproject(rig.cams[0], kW + 0.01, 4, 0.5, out);
  CHECK(expected_view(rig, in) == 0);
  CHECK(rig.bank.best_view(in) == 0);
  CHECK(expected_view(rig, out) == -1);
  CHECK(rig.bank.best_view(out) == -1);
}

TEST_CASE("image features: colour at three pyramid levels and the ray deviation") {
  Rig rig;
  // At the exact centre of pixel (30, 21) of A (near its axis, so A is chosen): level 0 is that
  // pixel's colour.
  float p[3];
  unproject(rig.cams[0], 30.5, 21.5, 3.0, p);
  REQUIRE(expected_view(rig, p) == 0);
  REQUIRE(rig.bank.best_view(p) == 0);
  float raw[kImageRawDim];
  rig.bank.compute(p, 1, raw, nullptr);
  for (int c = 0; c < 3; ++c) CHECK(raw[c] == doctest::Approx(texel(0, 30, 21, c) / 255.0).epsilon(1e-5));
  // On a pixel boundary (u = 30): the mean of pixels 29 and 30.
  unproject(rig.cams[0], 30.0, 21.5, 3.0, p);
  REQUIRE(rig.bank.best_view(p) == 0);
  rig.bank.compute(p, 1, raw, nullptr);
  for (int c = 0; c < 3; ++c)
    CHECK(raw[c] == doctest::Approx((texel(0, 29, 21, c) + texel(0, 30, 21, c)) / 510.0).epsilon(1e-5));
  // On the optical axis of A: zero deviation.
  const float axis[3] = {0, 0, 5};
  rig.bank.compute(axis, 1, raw, nullptr);
  for (int c = 9; c < 12; ++c) CHECK(std::fabs(raw[c]) < 1e-6);
  // Random anchors: all 13 values against the reference, whichever view is chosen, including
  // projections within half a pixel of the border (edge clamping).
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u01(0, 1);
  int checked = 0;
  for (int i = 0; i < 300; ++i) {
    const size_t view = size_t(i % 3);
    float q[3];
    const double u = i % 10 == 0 ? 0.2 + 0.1 * u01(rng) : kW * u01(rng), v = i % 10 == 1 ? kH - 0.3 * u01(rng) : kH * u01(rng);
    unproject(rig.cams[view], u, v, 2 + 8 * u01(rng), q);
    const int want = expected_view(rig, q);
    if (want < 0) continue;
    REQUIRE(rig.bank.best_view(q) == want);
    float r[kImageRawDim];
    rig.bank.compute(q, 1, r, nullptr);
    check_features(rig, q, r, want);
    ++checked;
  }
  CHECK(checked > 250);
}

TEST_CASE("image features: batch compute with a thread pool matches one by one and allocates nothing") {
  Rig rig;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> ux(-8, 8), uz(-3, 14);
  const size_t n = 3000;
  std::vector<float> pos(3 * n), a(n * kImageRawDim, -1.0f), b(n * kImageRawDim, -2.0f);
  for (size_t i = 0; i < n; ++i) pos[3 * i] = float(ux(rng)), pos[3 * i + 1] = float(0.4 * ux(rng)), pos[3 * i + 2] = float(uz(rng));
  platform::ThreadPool pool(2);
  {
    test::AllocationScope s;
    rig.bank.compute(pos.data(), n, a.data(), &pool);
    rig.bank.compute(pos.data(), n, b.data(), nullptr);
    CHECK(s.count() == 0);
  }
  CHECK(a == b);
  size_t valid = 0;
  for (size_t i = 0; i < n; ++i) {
    float one[kImageRawDim];
    rig.bank.compute(&pos[3 * i], 1, one, nullptr);
    CHECK(std::equal(one, one + kImageRawDim, &a[i * kImageRawDim]));
    valid += a[i * kImageRawDim + 12] == 1.0f;
  }
  CHECK(valid > n / 4);
  CHECK(valid < n);
}

TEST_CASE("image features: moved camera poses are re-read") {
  Rig rig;
  float p[3];
  unproject(rig.cams[1], rig.cams[1].intr.cx, rig.cams[1].intr.cy, 5.0, p);
  REQUIRE(rig.bank.best_view(p) == 1);
  float before[kImageRawDim], after[kImageRawDim];
  rig.bank.compute(p, 1, before, nullptr);
  // Turn camera B around (R <- diag(-1, 1, -1) R, same centre): it no longer sees p.
  Camera& b = rig.cams[1];
  double C[3];
  for (int i = 0; i < 3; ++i) C[i] = -(b.pose.R[i] * b.pose.t[0] + b.pose.R[3 + i] * b.pose.t[1] + b.pose.R[6 + i] * b.pose.t[2]);
  for (int c = 0; c < 3; ++c) b.pose.R[c] = -b.pose.R[c], b.pose.R[6 + c] = -b.pose.R[6 + c];
  for (int r = 0; r < 3; ++r) b.pose.t[r] = float(-(b.pose.R[3 * r] * C[0] + b.pose.R[3 * r + 1] * C[1] + b.pose.R[3 * r + 2] * C[2]));
  const int want = expected_view(rig, p);
  CHECK(want != 1);
  CHECK(rig.bank.best_view(p) == want);
  rig.bank.compute(p, 1, after, nullptr);
  CHECK_FALSE(std::equal(before, before + kImageRawDim, after));
  if (want >= 0) check_features(rig, p, after, want);
}

TEST_CASE("image features in visible mode: the colour mean and spread over the views that see the anchor unhidden") {
  Rig rig;
  std::vector<const Camera*> cp;
  std::vector<const io::Image8*> ip;
  for (size_t v = 0; v < 3; ++v) cp.push_back(&rig.cams[v]), ip.push_back(&rig.images[v]);
  ImageFeatureBank bank;
  REQUIRE(bank.init(cp, ip, ImageFeatureMode::kVisible).ok());
  // A point every camera sees.
  const float p[3] = {0.4f, 0.2f, 7.0f};
  std::vector<int> seen;
  for (int j = 0; j < 3; ++j) {
    double xc[3], u, v;
    if (sees(rig.cams[size_t(j)], p, xc, &u, &v)) seen.push_back(j);
  }
  REQUIRE(seen.size() == 3);
  // The mean over `views` of each level's bilinear sample, and the level-0 spread.
  auto expect = [&](const std::vector<int>& views, const float raw[kImageRawDim]) {
    for (int l = 0; l < kImagePyramidLevels; ++l)
      for (int c = 0; c < 3; ++c) {
        double sum = 0, sq = 0;
        for (int j : views) {
          double xc[3], u = 0, v = 0;
          sees(rig.cams[size_t(j)], p, xc, &u, &v);
          const double s = sample_ref(j, l, u, v, c);
          sum += s, sq += s * s;
        }
        const double mean = sum / double(views.size());
        CHECK(raw[3 * l + c] == doctest::Approx(mean).epsilon(2e-3));
        if (l == 0) CHECK(raw[9 + c] == doctest::Approx(std::sqrt(std::max(0.0, sq / double(views.size()) - mean * mean))).epsilon(2e-2));
      }
    CHECK(raw[12] == 1.0f);
  };
  float raw[kImageRawDim];
  bank.compute(p, 1, raw, nullptr);  // no occluders yet: every view counts
  expect({0, 1, 2}, raw);
  // An anchor on camera A's ray to p, halfway: A no longer sees p, B and C still do.
  double xa[3], ua, va;
  sees(rig.cams[0], p, xa, &ua, &va);
  const float occluder[3] = {0.5f * p[0], 0.5f * p[1], 0.5f * p[2]};  // A sits at the origin
  const float both[6] = {p[0], p[1], p[2], occluder[0], occluder[1], occluder[2]};
  bank.set_occluders(both, 2, 0.05f, nullptr);
  bank.compute(p, 1, raw, nullptr);
  expect({1, 2}, raw);
  // Alone, the anchor hides nothing (its own depth is its own).
  bank.set_occluders(p, 1, 0.05f, nullptr);
  bank.compute(p, 1, raw, nullptr);
  expect({0, 1, 2}, raw);
  // Hidden from every view (a disc as wide as the scene at p's depth in front of it): all zeros.
  bank.set_occluders(p, 1, 1000.0f, nullptr);
  const float far_side[3] = {p[0], p[1], p[2] + 2.0f};
  double xf[3], uf, vf;
  REQUIRE(sees(rig.cams[0], far_side, xf, &uf, &vf));  // in view, only hidden
  bank.compute(far_side, 1, raw, nullptr);
  for (float v : raw) CHECK(v == 0.0f);
}

TEST_CASE("image features: init refuses no views and images that do not match their camera") {
  ImageFeatureBank bank;
  CHECK_FALSE(bank.init({}, {}).ok());
  Camera cam;
  cam.intr = {50, 50, 32, 24, kW, kH};
  io::Image8 img = make_image(0);
  CHECK(bank.init({&cam}, {&img}).ok());
  io::Image8 wrong = img;
  wrong.width = kW - 1;  // claims another size
  const Status st = bank.init({&cam}, {&wrong});
  REQUIRE_FALSE(st.ok());
  MESSAGE(st.to_string());
  CHECK(st.message().find(std::to_string(kW - 1)) != std::string::npos);
  CHECK_FALSE(bank.init({&cam, &cam}, {&img}).ok());  // counts differ
}

}  // namespace
}  // namespace gs::model
