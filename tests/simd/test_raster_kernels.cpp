// SPDX-License-Identifier: MIT
// Every SIMD tile kernel against its scalar reference, one tile at a time: splat counts around the
// forward's chunk size (128) and the lane counts, border tiles with partial sizes, saturated tiles
// (early termination), and canaries: a kernel writes its own tile's pixels and nothing else, and
// never past the end of v_splats. Also the projection kernels on blocks with a tail.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "gs/simd/kernel_table.h"
#include "gs/simd/ref.h"
#include "support/simd_isa.h"

namespace {

using gs::simd::kSplatStride;
constexpr float kCanary = -12345.0f;

// Random splats around a tile, sorted front to back by construction (depth increasing).
std::vector<float> random_splats(std::mt19937_64& rng, int count, float x0, float y0, float max_sigma, float min_op) {
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<float> s(size_t(count) * kSplatStride + 16, kCanary);
  for (int i = 0; i < count; ++i) {
    float* r = &s[size_t(i) * kSplatStride];
    const float sx = 0.3f + max_sigma * u(rng), sy = 0.3f + max_sigma * u(rng), rho = 0.9f * (2 * u(rng) - 1);
    const float cxx = sx * sx, cyy = sy * sy, cxy = rho * sx * sy, det = cxx * cyy - cxy * cxy;
    r[gs::simd::kSplatMx] = x0 - 4 + 24 * u(rng);
    r[gs::simd::kSplatMy] = y0 - 4 + 24 * u(rng);
    r[gs::simd::kSplatA] = cyy / det;
    r[gs::simd::kSplatB] = -cxy / det;
    r[gs::simd::kSplatC] = cxx / det;
    r[gs::simd::kSplatOpacity] = min_op + (1 - min_op) * u(rng);
    for (int c = 0; c < 3; ++c) r[gs::simd::kSplatR + c] = u(rng);
    r[gs::simd::kSplatDepth] = 1.0f + float(i);
    gs::simd::splat_support(r + gs::simd::kSplatA, r[gs::simd::kSplatOpacity], r + gs::simd::kSplatTwoTau);
  }
  return s;
}

struct Outputs {
  std::vector<float> rgb, T, depth;
  std::vector<int32_t> last;
  explicit Outputs(size_t pixels) : rgb(3 * pixels, kCanary), T(pixels, kCanary), depth(pixels, kCanary), last(pixels, -7) {}
};

void check_tile(const gs::simd::KernelTable* kt, int width, int height, int tx, int ty, int count, float max_sigma,
                float min_op, uint64_t seed) {
  CAPTURE(kt->isa); CAPTURE(count); CAPTURE(tx); CAPTURE(ty); CAPTURE(seed);
  std::mt19937_64 rng(seed);
  const auto splats = random_splats(rng, count, float(tx * 16), float(ty * 16), max_sigma, min_op);
  gs::simd::RasterParams p{width, height, {0.2f, 0.3f, 0.1f}};
  const size_t P = size_t(width) * height;
  Outputs ref(P), out(P);
  gs::simd::raster_fwd_tile_ref<float>(&p, tx, ty, splats.data(), count, ref.rgb.data(), ref.T.data(), ref.last.data(),
                                       ref.depth.data());
  kt->raster_fwd_tile(&p, tx, ty, splats.data(), count, out.rgb.data(), out.T.data(), out.last.data(), out.depth.data());
  int flips = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t i = size_t(y) * width + x;
      const bool inside = x / 16 == tx && y / 16 == ty;
      if (!inside) {  // canary: nothing outside the tile is written
        REQUIRE(out.T[i] == kCanary);
        REQUIRE(out.last[i] == -7);
        continue;
      }
      // Tolerance: the kernels' exp and exponent evaluation differ from the reference by a few
      // 1e-7 relative; values are O(1) sums of up to ~count terms. A threshold tie may flip one
      // splat in a pixel (counted, bounded below).
      bool same = out.last[i] == ref.last[i] && std::fabs(out.T[i] - ref.T[i]) <= 2e-5f;
      for (int c = 0; c < 3; ++c) same = same && std::fabs(out.rgb[3 * i + c] - ref.rgb[3 * i + c]) <= 2e-5f;
      same = same && std::fabs(out.depth[i] - ref.depth[i]) <= 2e-5f * std::max(1.0f, ref.depth[i]);
      flips += same ? 0 : 1;
    }
  }
  CHECK(flips <= 2);
  // Backward with a random cotangent.
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> v_rgb(3 * P);
  for (float& v : v_rgb) v = u(rng);
  std::vector<float> g_ref(size_t(count) * kSplatStride + 16, kCanary), g_out(g_ref);
  gs::simd::raster_bwd_tile_ref<float>(&p, tx, ty, splats.data(), count, ref.T.data(), ref.last.data(), v_rgb.data(),
                                       g_ref.data());
  kt->raster_bwd_tile(&p, tx, ty, splats.data(), count, ref.T.data(), ref.last.data(), v_rgb.data(), g_out.data());
  for (int k = 0; k < 16; ++k) REQUIRE(g_out[size_t(count) * kSplatStride + k] == kCanary);
  double scale = 1e-3;
  for (int i = 0; i < count * kSplatStride; ++i) scale = std::max(scale, double(std::fabs(g_ref[i])));
  int bad = 0;
  for (int i = 0; i < count * kSplatStride; ++i)
    bad += std::fabs(double(g_out[i]) - double(g_ref[i])) > 1e-4 * scale ? 1 : 0;
  CHECK(bad <= std::max(2, count / 50));
}

}  // namespace

GS_SIMD_TEST_CASE(raster_chunks, "raster tile kernels match the reference across chunk and lane boundaries") {
  for (int count : {0, 1, 3, 15, 16, 17, 127, 128, 129, 255, 256, 300})
    check_tile(kt, 48, 40, 1, 1, count, 3.0f, 0.05f, 1000 + uint64_t(count));
}

GS_SIMD_TEST_CASE(raster_border, "raster tile kernels: border tiles with partial sizes and a 1x1 image") {
  check_tile(kt, 37, 21, 2, 1, 60, 4.0f, 0.05f, 7);   // 5x5 corner tile
  check_tile(kt, 37, 21, 0, 1, 60, 4.0f, 0.05f, 8);   // 16x5
  check_tile(kt, 37, 21, 2, 0, 60, 4.0f, 0.05f, 9);   // 5x16
  check_tile(kt, 1, 1, 0, 0, 20, 2.0f, 0.05f, 10);    // 1x1
}

GS_SIMD_TEST_CASE(raster_saturated, "raster tile kernels: saturated tiles stop early like the reference") {
  check_tile(kt, 32, 32, 1, 0, 400, 8.0f, 0.7f, 11);
}

GS_SIMD_TEST_CASE(project_tail, "projection kernels match the reference on blocks with a tail") {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<float> u(-1, 1);
  CAPTURE(kt->isa);
  for (size_t n : {size_t(1), size_t(7), size_t(16), size_t(33), size_t(100)}) {
    gs::simd::ProjectParams p{};
    const float R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::memcpy(p.R, R, sizeof(R));
    p.t[2] = 0.5f;
    p.fx = p.fy = 50; p.cx = 31; p.cy = 20; p.width = 64; p.height = 40;
    gs::simd::finish_project_params(&p);
    std::vector<float> m(3 * n), s(3 * n), q(4 * n);
    for (size_t i = 0; i < n; ++i) {
      m[3 * i] = 2 * u(rng); m[3 * i + 1] = 1.5f * u(rng); m[3 * i + 2] = 2.5f + 2 * u(rng);  // some near/behind
      for (int k = 0; k < 3; ++k) s[3 * i + k] = std::log(0.05f + 0.3f * (u(rng) + 1));
      for (int k = 0; k < 4; ++k) q[4 * i + k] = u(rng) + (k == 0 ? 1.5f : 0.0f);
    }
    std::vector<float> m2a(2 * n + 8, kCanary), m2b(m2a), ca(3 * n + 8, kCanary), cb(ca), da(n + 8, kCanary), db(da);
    std::vector<int32_t> ra(n + 8, -7), rb(ra);
    gs::simd::project_fwd_ref<float>(&p, n, m.data(), s.data(), q.data(), m2a.data(), ca.data(), da.data(), ra.data());
    kt->project_fwd(&p, n, m.data(), s.data(), q.data(), m2b.data(), cb.data(), db.data(), rb.data());
    for (size_t i = 0; i < n; ++i) {
      REQUIRE(ra[i] == rb[i]);
      if (ra[i] == 0) continue;
      for (int k = 0; k < 2; ++k) CHECK(m2b[2 * i + k] == doctest::Approx(m2a[2 * i + k]).epsilon(1e-5));
      for (int k = 0; k < 3; ++k) CHECK(cb[3 * i + k] == doctest::Approx(ca[3 * i + k]).epsilon(1e-4).scale(std::fabs(ca[3 * i]) + std::fabs(ca[3 * i + 2])));
      CHECK(db[i] == doctest::Approx(da[i]).epsilon(1e-6));
    }
    for (int k = 0; k < 8; ++k) REQUIRE(rb[n + k] == -7);
    std::vector<float> vm2(2 * n), vc(3 * n);
    for (float& v : vm2) v = u(rng);
    for (float& v : vc) v = u(rng);
    std::vector<float> a1(3 * n), a2(3 * n), a3(4 * n), b1(3 * n), b2(3 * n), b3(4 * n);
    double pa[6] = {0}, pb[6] = {0};
    gs::simd::project_bwd_ref<float>(&p, n, m.data(), s.data(), q.data(), ra.data(), vm2.data(), vc.data(), nullptr,
                                     a1.data(), a2.data(), a3.data(), pa);
    kt->project_bwd(&p, n, m.data(), s.data(), q.data(), ra.data(), vm2.data(), vc.data(), nullptr, b1.data(),
                    b2.data(), b3.data(), pb);
    auto close = [](const std::vector<float>& x, const std::vector<float>& y) {
      double sc = 1e-6;
      for (float v : x) sc = std::max(sc, double(std::fabs(v)));
      for (size_t i = 0; i < x.size(); ++i)
        if (std::fabs(double(x[i]) - double(y[i])) > 1e-4 * sc) return false;
      return true;
    };
    CHECK(close(a1, b1));
    CHECK(close(a2, b2));
    CHECK(close(a3, b3));
    double ps = 1e-6;
    for (double v : pa) ps = std::max(ps, std::fabs(v));
    for (int k = 0; k < 6; ++k) CHECK(std::fabs(pa[k] - pb[k]) <= 1e-4 * ps);
  }
}

// Binning tests every tile of a splat's rect in one call (splat_reaches_tiles, the renderer's
// projection stage); it must give splat_reaches_tile's answer for each tile, bit for bit: small,
// large, needle-thin and non-positive-definite conics, opacities near 1/255, centres inside,
// beside and far outside the rect, and rects clipped by a partial last tile column or row.
TEST_CASE("splat_reaches_tiles agrees with splat_reaches_tile on every tile of the rect") {
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<float> u(0, 1);
  const int32_t width = 101, height = 77;  // 7 x 5 tiles, the last column and row partial
  size_t tiles = 0, reached = 0;
  for (int n = 0; n < 20000; ++n) {
    const float sx = 0.2f + (n % 3 == 0 ? 30.0f : 4.0f) * u(rng), sy = 0.2f + 6.0f * u(rng);
    const float rho = (n % 7 == 0 ? 0.999f : 0.95f) * (2 * u(rng) - 1);
    const float cxx = sx * sx, cyy = sy * sy, cxy = rho * sx * sy, det = cxx * cyy - cxy * cxy;
    float conic[3] = {cyy / det, -cxy / det, cxx / det};
    if (n % 50 == 0) conic[2] = -conic[2];  // not positive definite: reaches every tile
    const float mean[2] = {-20 + 140 * u(rng), -20 + 115 * u(rng)};
    const float opacity = n % 5 == 0 ? (1.0f + 0.02f * (u(rng) - 0.5f)) / 255.0f : u(rng);
    const float two_tau = opacity * 255.0f >= 1.0f ? 2.0f * std::log(255.0f * opacity) : -1.0f;
    int32_t rect[4];
    rect[0] = int32_t(u(rng) * 7), rect[1] = int32_t(u(rng) * 5);
    rect[2] = std::min(7, rect[0] + 1 + int32_t(u(rng) * 8)), rect[3] = std::min(5, rect[1] + 1 + int32_t(u(rng) * 8));
    if ((rect[2] - rect[0]) * (rect[3] - rect[1]) > 64) continue;
    const uint64_t mask = gs::simd::splat_reaches_tiles(mean, conic, two_tau, rect, width, height);
    int bit = 0;
    for (int32_t ty = rect[1]; ty < rect[3]; ++ty)
      for (int32_t tx = rect[0]; tx < rect[2]; ++tx, ++bit) {
        const bool want = gs::simd::splat_reaches_tile(mean, conic, two_tau, tx, ty, width, height);
        CAPTURE(n); CAPTURE(tx); CAPTURE(ty);
        REQUIRE(((mask >> bit) & 1) == uint64_t(want));
        ++tiles;
        reached += want ? 1 : 0;
      }
    REQUIRE((bit == 64 || (mask >> bit) == 0));
  }
  MESSAGE("splat_reaches_tiles: " << tiles << " tiles, " << reached << " reached");
  CHECK(reached > tiles / 20);  // both answers are common (about 9 % reached)
  CHECK(reached < tiles);
}

// The tile kernels clip each splat to the pixels whose centres lie within splat_support's
// half-extents of its mean, so those extents must hold every pixel the reference blends (alpha >=
// 1/255 by eval_splat_ref), for round, slanted and needle-thin splats (the projection's +0.3 px^2
// dilation included, standard deviations up to 60 px, correlations up to 0.9999) and opacities from
// just above 1/255 to 1; and they must stay within 0.1 % + 0.05 px of the exact ellipse's extents,
// sqrt(two_tau cov_xx) and sqrt(two_tau cov_yy) (a wider margin puts rows no pixel reaches into
// every blend loop).
TEST_CASE("splat_support holds every pixel the reference blends, within 0.1 % + 0.05 px of the ellipse") {
  std::mt19937_64 rng(91);
  std::uniform_real_distribution<double> u(0, 1);
  size_t splats = 0, pixels = 0;
  double widest_x = 0, widest_y = 0;  // the largest reached |offset| / extent seen, per axis
  for (int n = 0; n < 3000; ++n) {
    const double sx = 0.1 + (n % 4 == 0 ? 60.0 : 5.0) * u(rng), sy = 0.1 + (n % 3 == 0 ? 20.0 : 3.0) * u(rng);
    const double rho = (n % 5 == 0 ? 0.9999 : 0.95) * (2 * u(rng) - 1);
    const double cxx = sx * sx + 0.3, cyy = sy * sy + 0.3, cxy = rho * sx * sy, det = cxx * cyy - cxy * cxy;
    float rec[kSplatStride] = {};
    rec[gs::simd::kSplatMx] = float(100 * u(rng));
    rec[gs::simd::kSplatMy] = float(100 * u(rng));
    rec[gs::simd::kSplatA] = float(cyy / det);
    rec[gs::simd::kSplatB] = float(-cxy / det);
    rec[gs::simd::kSplatC] = float(cxx / det);
    rec[gs::simd::kSplatOpacity] = float(n % 7 == 0 ? (1.0 + 0.05 * u(rng)) / 255.0 : 0.01 + 0.99 * u(rng));
    gs::simd::splat_support(rec + gs::simd::kSplatA, rec[gs::simd::kSplatOpacity], rec + gs::simd::kSplatTwoTau);
    const float ex = rec[gs::simd::kSplatExtX], ey = rec[gs::simd::kSplatExtY];
    CAPTURE(n); CAPTURE(sx); CAPTURE(sy); CAPTURE(rho);
    REQUIRE(ex >= 0.0f);
    REQUIRE(ey >= 0.0f);
    // The exact extents from the float conic (the record's own ellipse), inverted in double.
    const double a = rec[gs::simd::kSplatA], b = rec[gs::simd::kSplatB], c = rec[gs::simd::kSplatC];
    const double two_tau = rec[gs::simd::kSplatTwoTau], cdet = a * c - b * b;
    CHECK(double(ex) <= std::sqrt(two_tau * c / cdet) * 1.0011 + 0.0501);
    CHECK(double(ey) <= std::sqrt(two_tau * a / cdet) * 1.0011 + 0.0501);
    // Every pixel centre in a window 2 px wider than the box on each side, at most 400 x 400.
    const float mx = rec[gs::simd::kSplatMx], my = rec[gs::simd::kSplatMy];
    const int x0 = int(std::floor(mx - std::min(ex, 200.0f))) - 2, x1 = int(std::ceil(mx + std::min(ex, 200.0f))) + 2;
    const int y0 = int(std::floor(my - std::min(ey, 200.0f))) - 2, y1 = int(std::ceil(my + std::min(ey, 200.0f))) + 2;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        gs::simd::SplatEval<float> e;
        if (!gs::simd::eval_splat_ref(rec, float(x) + 0.5f, float(y) + 0.5f, &e)) continue;
        ++pixels;
        CAPTURE(x); CAPTURE(y);
        REQUIRE(std::fabs(e.dx) <= ex);
        REQUIRE(std::fabs(e.dy) <= ey);
        widest_x = std::max(widest_x, double(std::fabs(e.dx)) / ex);
        widest_y = std::max(widest_y, double(std::fabs(e.dy)) / ey);
      }
    ++splats;
  }
  MESSAGE("splat_support: " << splats << " splats, " << pixels << " blended pixels, widest reached offset / extent "
                            << widest_x << " (x), " << widest_y << " (y)");
  CHECK(widest_x > 0.99);  // the pixels do reach the box's edges
  CHECK(widest_y > 0.99);
}
