// SPDX-License-Identifier: MIT
// The fixed-point forward rasteriser (gs/simd/qsplat.h): every SIMD variant bit-exact with the
// reference on random and hard tiles (chunk and lane boundaries, border tiles, saturation, huge,
// tiny and needle-thin splats, opacities at the 1/255 edge, far-away centres), canaries outside the
// tile, the integer helpers against exact arithmetic, and the measured error budget of the
// fixed-point forward against the float reference.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <random>
#include <vector>

#include "gs/simd/kernel_table.h"
#include "gs/simd/qsplat.h"
#include "gs/simd/ref.h"
#include "support/simd_isa.h"

namespace {

using gs::simd::kSplatStride;
using gs::simd::QSplat;
constexpr float kCanary = -12345.0f;

enum class Kind { kMixed, kHuge, kTiny, kNeedle, kEdgeOpacity, kFar };

// Float records around tile (tx, ty), front to back (depth increasing), with support fields.
std::vector<float> float_splats(std::mt19937_64& rng, int count, float x0, float y0, float max_sigma, float min_op, Kind kind) {
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<float> s(size_t(count) * kSplatStride);
  for (int i = 0; i < count; ++i) {
    float* r = &s[size_t(i) * kSplatStride];
    float sx = 0.3f + max_sigma * u(rng), sy = 0.3f + max_sigma * u(rng), rho = 0.9f * (2 * u(rng) - 1);
    float mx = x0 - 4 + 24 * u(rng), my = y0 - 4 + 24 * u(rng), op = min_op + (1 - min_op) * u(rng);
    const Kind k = kind == Kind::kMixed ? Kind(i % 6) : kind;
    if (k == Kind::kHuge) sx = 200 + 2000 * u(rng), sy = 200 + 2000 * u(rng);
    if (k == Kind::kTiny) sx = sy = 0.3f + 0.2f * u(rng);
    if (k == Kind::kNeedle) sx = 0.3f, sy = 40 + 100 * u(rng), rho = 0.999f * (u(rng) < 0.5f ? -1 : 1);
    if (k == Kind::kEdgeOpacity) op = (1.0f + 0.02f * (u(rng) - 0.5f)) / 255.0f;
    if (k == Kind::kFar) mx = x0 + (u(rng) < 0.5f ? -1 : 1) * (300 + 3000 * u(rng)), sx = 100 + 1000 * u(rng);
    const float cxx = sx * sx + 0.3f, cyy = sy * sy + 0.3f, cxy = rho * sx * sy, det = cxx * cyy - cxy * cxy;
    r[gs::simd::kSplatMx] = mx;
    r[gs::simd::kSplatMy] = my;
    r[gs::simd::kSplatA] = cyy / det;
    r[gs::simd::kSplatB] = -cxy / det;
    r[gs::simd::kSplatC] = cxx / det;
    r[gs::simd::kSplatOpacity] = op;
    for (int c = 0; c < 3; ++c) r[gs::simd::kSplatR + c] = u(rng);
    r[gs::simd::kSplatDepth] = 1.0f + float(i);
    gs::simd::splat_support(r + gs::simd::kSplatA, r[gs::simd::kSplatOpacity], r + gs::simd::kSplatTwoTau);
  }
  return s;
}

std::vector<QSplat> to_fixed(const std::vector<float>& f, float depth_scale) {
  std::vector<QSplat> q(f.size() / kSplatStride);
  for (size_t i = 0; i < q.size(); ++i) gs::simd::qsplat_from_record(&f[i * kSplatStride], depth_scale, &q[i]);
  return q;
}

struct Outputs {
  std::vector<float> rgb, T, depth;
  std::vector<int32_t> last;
  explicit Outputs(size_t pixels) : rgb(3 * pixels, kCanary), T(pixels, kCanary), depth(pixels, kCanary), last(pixels, -7) {}
};

gs::simd::QRasterParams qparams(int w, int h, float depth_scale) {
  gs::simd::QRasterParams p{};
  p.width = w;
  p.height = h;
  const float bg[3] = {0.2f, 0.3f, 0.1f};
  for (int c = 0; c < 3; ++c) p.background[c] = gs::simd::q15_from_unit(bg[c]);
  p.depth_scale = depth_scale;
  return p;
}

void check_tile(const gs::simd::KernelTable* kt, int width, int height, int tx, int ty, int count, float max_sigma,
                float min_op, Kind kind, uint64_t seed) {
  CAPTURE(kt->isa); CAPTURE(count); CAPTURE(tx); CAPTURE(ty); CAPTURE(seed); CAPTURE(int(kind));
  std::mt19937_64 rng(seed);
  const float depth_scale = float(count + 2);
  const std::vector<QSplat> q = to_fixed(float_splats(rng, count, float(tx * 16), float(ty * 16), max_sigma, min_op, kind), depth_scale);
  const gs::simd::QRasterParams p = qparams(width, height, depth_scale);
  const size_t P = size_t(width) * height;
  Outputs ref(P), out(P);
  gs::simd::qraster_fwd_tile_ref(&p, tx, ty, q.data(), count, ref.rgb.data(), ref.T.data(), ref.last.data(), ref.depth.data());
  kt->qraster_fwd_tile(&p, tx, ty, q.data(), count, out.rgb.data(), out.T.data(), out.last.data(), out.depth.data());
  // Bit-exact: every output, and canaries untouched outside the tile.
  REQUIRE(std::memcmp(out.rgb.data(), ref.rgb.data(), out.rgb.size() * sizeof(float)) == 0);
  REQUIRE(std::memcmp(out.T.data(), ref.T.data(), out.T.size() * sizeof(float)) == 0);
  REQUIRE(std::memcmp(out.depth.data(), ref.depth.data(), out.depth.size() * sizeof(float)) == 0);
  REQUIRE(out.last == ref.last);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      if (x / 16 != tx || y / 16 != ty) REQUIRE(out.T[size_t(y) * width + x] == kCanary);
  // Without a depth output (the image-only blend): the same image.
  Outputs nod(P);
  kt->qraster_fwd_tile(&p, tx, ty, q.data(), count, nod.rgb.data(), nod.T.data(), nod.last.data(), nullptr);
  REQUIRE(std::memcmp(nod.rgb.data(), ref.rgb.data(), nod.rgb.size() * sizeof(float)) == 0);
  REQUIRE(nod.last == ref.last);
}

}  // namespace

GS_SIMD_TEST_CASE(qraster_chunks, "fixed-point raster kernels are bit-exact with the reference across chunks and lanes") {
  for (int count : {0, 1, 3, 15, 16, 17, 127, 128, 129, 255, 256, 300})
    check_tile(kt, 48, 40, 1, 1, count, 3.0f, 0.05f, Kind::kMixed, 2000 + uint64_t(count));
}

GS_SIMD_TEST_CASE(qraster_border, "fixed-point raster kernels: border tiles with partial sizes and a 1x1 image") {
  check_tile(kt, 37, 21, 2, 1, 60, 4.0f, 0.05f, Kind::kMixed, 17);  // 5x5 corner tile
  check_tile(kt, 37, 21, 0, 1, 60, 4.0f, 0.05f, Kind::kMixed, 18);  // 16x5
  check_tile(kt, 37, 21, 2, 0, 60, 4.0f, 0.05f, Kind::kMixed, 19);  // 5x16
  check_tile(kt, 1, 1, 0, 0, 20, 2.0f, 0.05f, Kind::kMixed, 20);    // 1x1
}

GS_SIMD_TEST_CASE(qraster_hard, "fixed-point raster kernels: saturated tiles, huge, tiny, needle, edge-opacity and far splats") {
  check_tile(kt, 32, 32, 1, 0, 400, 8.0f, 0.7f, Kind::kMixed, 21);  // stops early
  for (Kind k : {Kind::kHuge, Kind::kTiny, Kind::kNeedle, Kind::kEdgeOpacity, Kind::kFar})
    for (uint64_t seed = 0; seed < 4; ++seed) check_tile(kt, 48, 48, 1, 1, 90, 3.0f, 0.02f, k, 30 + seed + 10 * uint64_t(k));
}

// Integer records built directly, over the whole documented range of each field rather than what
// the float conversion produces: centres up to 4096 px away, |kappa| up to 2^14, s and r from 0 to
// 2^25, any ylim, opacity and extents. The kernels compute a splat's row values in int32 lanes when
// its row centres are within 128 px of the tile and in int64 otherwise; both sides of that split,
// and of the saturations inside it, must give the reference's bits.
GS_SIMD_TEST_CASE(qraster_integer_records, "fixed-point raster kernels are bit-exact on integer records over the full field ranges") {
  for (uint64_t seed = 0; seed < 24; ++seed) {
    std::mt19937_64 rng(900 + seed);
    auto pick = [&](int64_t lo, int64_t hi) { return std::uniform_int_distribution<int64_t>(lo, hi)(rng); };
    const int count = 40 + int(seed * 5);
    std::vector<QSplat> q(static_cast<size_t>(count));
    for (QSplat& r : q) {
      const int64_t reach = seed % 3 == 0 ? (int64_t(1) << 20) : (seed % 3 == 1 ? (int64_t(1) << 15) : (int64_t(1) << 13));
      r.mx = int32_t(24 * 256 + pick(-reach, reach));  // around tile (1, 1)
      r.my = int32_t(24 * 256 + pick(-reach, reach));
      const int kind = int(pick(0, 4));
      r.kappa = int32_t(kind == 0 ? pick(-(int64_t(1) << 30), int64_t(1) << 30) : pick(-(int64_t(1) << 17), int64_t(1) << 17));
      r.s = int32_t(kind == 1 ? pick(0, 64) : (kind == 4 ? pick(0, int64_t(1) << 17) : pick(0, int64_t(1) << 25)));
      r.r = int32_t(kind == 2 || kind == 4 ? pick(0, 64) : pick(0, int64_t(1) << 25));
      if (kind == 4) {  // a wide splat whose row centres are about 128 px from column 0: either side of the int32 split
        r.mx = int32_t(16 * 256 + 128 + (pick(0, 1) ? 1 : -1) * ((int64_t(1) << 15) + pick(-600, 600)));
        r.kappa = int32_t(pick(-2000, 2000));
        r.ext_x = int32_t(pick(int64_t(1) << 15, int64_t(1) << 16));
      }
      r.ylim = int32_t(pick(-2, 11349));
      r.opacity = int32_t(pick(0, 32767));
      for (int32_t& c : r.rgb) c = int32_t(pick(0, 32767));
      r.depth = int32_t(pick(0, 32767));
      if (kind != 4) r.ext_x = int32_t(pick(-1, int64_t(1) << 16));
      r.ext_y = int32_t(pick(-1, int64_t(1) << 16));
    }
    CAPTURE(seed);
    const gs::simd::QRasterParams p = qparams(48, 48, 1.0f);
    Outputs ref(48 * 48), out(48 * 48);
    gs::simd::qraster_fwd_tile_ref(&p, 1, 1, q.data(), count, ref.rgb.data(), ref.T.data(), ref.last.data(), ref.depth.data());
    kt->qraster_fwd_tile(&p, 1, 1, q.data(), count, out.rgb.data(), out.T.data(), out.last.data(), out.depth.data());
    REQUIRE(std::memcmp(out.rgb.data(), ref.rgb.data(), out.rgb.size() * sizeof(float)) == 0);
    REQUIRE(std::memcmp(out.T.data(), ref.T.data(), out.T.size() * sizeof(float)) == 0);
    REQUIRE(std::memcmp(out.depth.data(), ref.depth.data(), out.depth.size() * sizeof(float)) == 0);
    REQUIRE(out.last == ref.last);
  }
}

TEST_CASE("fixed-point helpers: mulhrs, saturating adds and the alpha polynomial against exact arithmetic") {
  using namespace gs::simd;
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> d(-32767, 32767);
  for (int i = 0; i < 200000; ++i) {
    const int a = d(rng), b = d(rng);
    const int64_t exact = (int64_t(a) * b + 16384) >> 15;  // floor((ab + 2^14) / 2^15)
    REQUIRE(q_mulhrs(int16_t(a), int16_t(b)) == int16_t(exact));
    REQUIRE(q_adds(int16_t(a), int16_t(b)) == int16_t(std::clamp(a + b, -32768, 32767)));
    REQUIRE(q_subs(int16_t(a), int16_t(b)) == int16_t(std::clamp(a - b, -32768, 32767)));
  }
  // alpha = o exp(-y) within 4e-4 absolute for every y the kernels evaluate (y <= ln 255) and o.
  double worst = 0;
  for (int y = 0; y <= int(std::log(255.0) * 2048); ++y)
    for (int o : {129, 4000, 16384, 32767}) {
      const double want = std::min(o / 32767.0 * std::exp(-y / 2048.0), 32439 / 32767.0);
      worst = std::max(worst, std::fabs(q_alpha(int16_t(y), int16_t(o)) / 32767.0 - want));
    }
  MESSAGE("fixed-point alpha: max |error| " << worst);
  CHECK(worst < 4e-4);
}

// The error budget of the fixed-point forward against the float reference, measured on random
// tiles: per-channel colour error in 8-bit levels (max and mean), transmittance error.
TEST_CASE("fixed-point raster: error budget against the float reference") {
  double max_level = 0, sum_level = 0, max_T = 0;
  size_t n = 0, over_half = 0;
  for (uint64_t seed = 0; seed < 40; ++seed) {
    std::mt19937_64 rng(500 + seed);
    const int count = 20 + int(seed * 7);
    const std::vector<float> f = float_splats(rng, count, 16, 16, 4.0f, 0.05f, seed % 2 ? Kind::kMixed : Kind::kTiny);
    const std::vector<QSplat> q = to_fixed(f, float(count + 2));
    const gs::simd::QRasterParams qp = qparams(48, 48, float(count + 2));
    gs::simd::RasterParams fp{48, 48, {0.2f, 0.3f, 0.1f}};
    for (int c = 0; c < 3; ++c) fp.background[c] = float(qp.background[c]) / 32767.0f;
    Outputs a(48 * 48), b(48 * 48);
    gs::simd::qraster_fwd_tile_ref(&qp, 1, 1, q.data(), count, a.rgb.data(), a.T.data(), a.last.data(), a.depth.data());
    gs::simd::raster_fwd_tile_ref<float>(&fp, 1, 1, f.data(), count, b.rgb.data(), b.T.data(), b.last.data(), b.depth.data());
    for (int y = 16; y < 32; ++y)
      for (int x = 16; x < 32; ++x) {
        const size_t i = size_t(y) * 48 + x;
        for (int c = 0; c < 3; ++c) {
          const double e = std::fabs(double(a.rgb[3 * i + c]) - b.rgb[3 * i + c]) * 255.0;
          max_level = std::max(max_level, e);
          sum_level += e;
          over_half += e > 0.5 ? 1 : 0;
          ++n;
        }
        max_T = std::max(max_T, std::fabs(double(a.T[i]) - b.T[i]));
      }
  }
  MESSAGE("fixed vs float forward: colour error max " << max_level << " mean " << sum_level / double(n)
                                                      << " 8-bit levels; " << over_half << " of " << n
                                                      << " values over half a level; transmittance max " << max_T);
  CHECK(sum_level / double(n) < 0.05);
  CHECK(max_level < 3.0);
  CHECK(double(over_half) < 0.002 * double(n));
}

// The record conversion rounds with inline forms of std::lround and std::ceil (the libm calls
// were a fifth of its time); it must equal the plain transcription below on random records and on
// values at and around halves, negatives, NaN, infinities and the clamps.
namespace {
int32_t round_clamp_libm(double v, double lo, double hi) {
  if (!(v >= lo)) return int32_t(lo);
  if (v > hi) return int32_t(hi);
  return int32_t(std::lround(v));
}
QSplat qsplat_from_record_libm(const float* rec, float depth_scale) {
  using namespace gs::simd;
  const double a = rec[kSplatA], b = rec[kSplatB], c = rec[kSplatC], o = rec[kSplatOpacity];
  QSplat q{};
  q.mx = round_clamp_libm(double(rec[kSplatMx]) * 256.0, -2147483647.0, 2147483647.0);
  q.my = round_clamp_libm(double(rec[kSplatMy]) * 256.0, -2147483647.0, 2147483647.0);
  const double det = a * c - b * b;
  const bool usable = a > 0 && det > 0 && o * 255.0 >= 1.0 && rec[kSplatExtX] >= 0 && rec[kSplatExtX] < 1e6f &&
                      rec[kSplatExtY] < 1e6f;
  if (usable) {
    q.kappa = round_clamp_libm(b / a * 65536.0, -1073741824.0, 1073741824.0);
    q.s = round_clamp_libm(std::sqrt(a / 2) * 16777216.0, 0, 33554432.0);
    q.r = round_clamp_libm(std::sqrt(std::max(0.0, (c - b * b / a) / 2)) * 16777216.0, 0, 33554432.0);
    q.ylim = round_clamp_libm(std::log(255.0 * std::min(o, 1.0)) * 2048.0, 0, 32767.0);
    q.ext_x = round_clamp_libm(std::ceil(double(rec[kSplatExtX]) * 256.0), 0, 268435456.0);
    q.ext_y = round_clamp_libm(std::ceil(double(rec[kSplatExtY]) * 256.0), 0, 268435456.0);
  } else {
    q.ylim = -1;
    q.ext_x = q.ext_y = -1;
  }
  q.opacity = round_clamp_libm(o * kQOne, 0, kQOne);
  for (int k = 0; k < 3; ++k) q.rgb[k] = round_clamp_libm(double(rec[kSplatR + k]) * kQOne, 0, kQOne);
  q.depth = depth_scale > 0 ? round_clamp_libm(double(rec[kSplatDepth]) / depth_scale * kQOne, 0, kQOne) : 0;
  return q;
}
}  // namespace

TEST_CASE("qsplat_from_record equals its libm transcription (lround, ceil) on random and edge records") {
  std::mt19937_64 rng(91);
  std::uniform_real_distribution<float> u(0, 1);
  const float specials[] = {0.0f, -0.0f, 0.5f / 256, -0.5f / 256, 1.5f / 256, -1.5f / 256, 2.5f / 256, 1.0f / 512,
                            -1.0f / 512, 0.49999997f / 256, 1e-30f, -1e-30f, 8388608.5f, -8388608.5f, 1e6f, 9.9e5f,
                            3e9f, -3e9f, INFINITY, -INFINITY, NAN, 0.5f / 32767, 1.5f / 32767, 1.0f, 1.0000001f};
  for (int n = 0; n < 200000; ++n) {
    std::vector<float> f = float_splats(rng, 1, 0, 0, 6.0f, 0.002f, Kind(n % 6));
    float* r = f.data();
    if (n % 4 == 0)  // a special value in a random field (centre, colour, opacity, extents, depth)
      r[std::uniform_int_distribution<int>(0, kSplatStride - 1)(rng)] =
          specials[std::uniform_int_distribution<size_t>(0, std::size(specials) - 1)(rng)];
    if (n % 4 == 1)  // exact halves of the Q8 and Q15 grids
      for (int k : {gs::simd::kSplatMx, gs::simd::kSplatMy}) r[k] = (std::floor(r[k] * 256) + 0.5f) / 256;
    const float depth_scale = n % 10 == 0 ? 0.0f : 5.0f + 20.0f * u(rng);
    QSplat got;
    gs::simd::qsplat_from_record(r, depth_scale, &got);
    const QSplat want = qsplat_from_record_libm(r, depth_scale);
    CAPTURE(n);
    REQUIRE(std::memcmp(&got, &want, sizeof(QSplat)) == 0);
  }
  for (float v : specials) CHECK(gs::simd::q15_from_unit(v) == round_clamp_libm(double(v) * 32767, 0, 32767));
}
