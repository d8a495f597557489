// SPDX-License-Identifier: MIT
// Pixel-format conversion: every SIMD table's YUYV/NV12 kernels against the reference bit for bit
// (odd sizes around the lane widths, padded strides, canaries in every row's padding and after the
// buffers), the reference itself against an independent float BT.601 conversion and against an
// RGB -> YUV -> RGB round trip, and frame_to_rgb for each format, including UVC-style MJPEG frames
// without a DHT segment, truncated and garbage JPEGs, and frames whose planes are too small.
#include <doctest/doctest.h>

#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "gs/capture/convert.h"
#include "gs/capture/frame.h"
#include "gs/metrics/image_metrics.h"
#include "gs/simd/convert.h"
#include "gs/simd/kernel_table.h"
#include "support/simd_isa.h"

namespace {

using gs::capture::FrameView;
using gs::capture::PixelFormat;

constexpr uint8_t kCanary = 0xA5;
constexpr size_t kTrailer = 64;  // canary bytes after the last output row

// Output image [h, stride] plus a trailer, all canary: the kernels must write exactly the first
// 3 w bytes of each row.
std::vector<uint8_t> canary_rgb(int w, int h, int stride) { return std::vector<uint8_t>(size_t(h) * size_t(stride) + kTrailer, kCanary); }

void check_canaries(const std::vector<uint8_t>& rgb, int w, int h, int stride) {
  for (int y = 0; y < h; ++y)
    for (int x = 3 * w; x < stride; ++x)
      if (rgb[size_t(y) * size_t(stride) + size_t(x)] != kCanary) {
        FAIL("row " << y << " padding byte " << x << " was written");
        return;
      }
  for (size_t i = size_t(h) * size_t(stride); i < rgb.size(); ++i)
    if (rgb[i] != kCanary) {
      FAIL("byte " << i - size_t(h) * size_t(stride) << " after the last row was written");
      return;
    }
}

// Exactly (h - 1) * stride + row_bytes random bytes (the last row unpadded), so a kernel that reads
// past its input's end trips the sanitisers; the padding bytes are random too.
std::vector<uint8_t> random_plane(std::mt19937_64& rng, int rows, int stride, int row_bytes) {
  std::vector<uint8_t> p(size_t(rows - 1) * size_t(stride) + size_t(row_bytes));
  for (uint8_t& b : p) b = uint8_t(rng() >> 56);
  return p;
}

size_t first_difference(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i] != b[i]) return i;
  return a.size();
}

struct Size {
  int w, h;
};
// Odd sizes, and widths at and around 2N and 4N pixels for N = 4, 8, 16 int32 lanes, where the
// vector loop hands over to the reference's strip.
const Size kSizes[] = {{1, 1},  {2, 1},  {3, 5},  {7, 2},   {8, 3},   {9, 3},    {15, 2},   {16, 4},   {17, 9},
                       {31, 3}, {32, 2}, {33, 31}, {63, 3}, {64, 2},  {65, 5},   {127, 3},  {129, 2},  {641, 479}};

GS_SIMD_TEST_CASE(yuyv_matches_ref, "SIMD yuyv_to_rgb equals the reference bit for bit") {
  const gs::simd::KernelTable* const tables[] = {kt};  // one ISA per case (support/simd_isa.h)
  std::mt19937_64 rng(20240905);
  for (const Size s : kSizes) {
    CAPTURE(s.w); CAPTURE(s.h);
    const int in_row = 4 * ((s.w + 1) / 2), in_stride = in_row + 5, out_stride = 3 * s.w + 7;  // odd paddings
    const auto yuyv = random_plane(rng, s.h, in_stride, in_row);
    auto ref = canary_rgb(s.w, s.h, out_stride);
    gs::simd::yuyv_to_rgb_ref(s.w, s.h, yuyv.data(), in_stride, ref.data(), out_stride);
    check_canaries(ref, s.w, s.h, out_stride);
    for (const auto* kt : tables) {
      CAPTURE(kt->isa);
      auto out = canary_rgb(s.w, s.h, out_stride);
      kt->yuyv_to_rgb(s.w, s.h, yuyv.data(), in_stride, out.data(), out_stride);
      const size_t d = first_difference(ref, out);
      CHECK_MESSAGE(d == ref.size(), "first differing byte " << d << " (row " << d / size_t(out_stride) << ")");
      check_canaries(out, s.w, s.h, out_stride);
    }
  }
}

GS_SIMD_TEST_CASE(nv12_matches_ref, "SIMD nv12_to_rgb equals the reference bit for bit") {
  const gs::simd::KernelTable* const tables[] = {kt};  // one ISA per case (support/simd_isa.h)
  std::mt19937_64 rng(977);
  for (const Size s : kSizes) {
    CAPTURE(s.w); CAPTURE(s.h);
    const int ch = (s.h + 1) / 2, uv_row = 2 * ((s.w + 1) / 2);
    const int y_stride = s.w + 3, uv_stride = uv_row + 9, out_stride = 3 * s.w + 5;
    const auto y = random_plane(rng, s.h, y_stride, s.w);
    const auto uv = random_plane(rng, ch, uv_stride, uv_row);
    auto ref = canary_rgb(s.w, s.h, out_stride);
    gs::simd::nv12_to_rgb_ref(s.w, s.h, y.data(), y_stride, uv.data(), uv_stride, ref.data(), out_stride);
    check_canaries(ref, s.w, s.h, out_stride);
    for (const auto* kt : tables) {
      CAPTURE(kt->isa);
      auto out = canary_rgb(s.w, s.h, out_stride);
      kt->nv12_to_rgb(s.w, s.h, y.data(), y_stride, uv.data(), uv_stride, out.data(), out_stride);
      const size_t d = first_difference(ref, out);
      CHECK_MESSAGE(d == ref.size(), "first differing byte " << d << " (row " << d / size_t(out_stride) << ")");
      check_canaries(out, s.w, s.h, out_stride);
    }
  }
}

// Independent BT.601 limited-range YCbCr -> R'G'B' in double, derived from Kr = 0.299, Kb = 0.114
// (Rec. ITU-R BT.601): E'Y = (Y - 16) / 219, E'Cb/Cr = (U/V - 128) / 224, then the inverse matrix.
void bt601_double(int y, int u, int v, double rgb[3]) {
  const double kr = 0.299, kb = 0.114, kg = 1 - kr - kb;
  const double ey = (y - 16) / 219.0, cb = (u - 128) / 224.0, cr = (v - 128) / 224.0;
  const double r = ey + 2 * (1 - kr) * cr;
  const double b = ey + 2 * (1 - kb) * cb;
  const double g = (ey - kr * r - kb * b) / kg;
  rgb[0] = 255 * r;
  rgb[1] = 255 * g;
  rgb[2] = 255 * b;
}

int to_u8(double x) { return int(std::lround(std::min(255.0, std::max(0.0, x)))); }

TEST_CASE("reference conversion is within one level of BT.601 in double precision") {
  // Every Y, and U and V on a grid of step 5 (0..255), as YUYV rows of 256 pixels: one row per
  // (U, V), Y = x. Measured: max |diff| 1, 95.1% of channel values exact (the 8-bit
  // coefficients are within 0.002 of the true ones, so the error is rounding plus < 0.3 level).
  const int w = 256;
  std::vector<int> us;
  for (int u = 0; u <= 255; u += 5) us.push_back(u);
  const int h = int(us.size() * us.size());
  std::vector<uint8_t> yuyv(size_t(h) * size_t(2 * w));
  for (int r = 0; r < h; ++r)
    for (int p = 0; p < w / 2; ++p) {
      uint8_t* q = &yuyv[size_t(r) * size_t(2 * w) + size_t(4 * p)];
      q[0] = uint8_t(2 * p);
      q[1] = uint8_t(us[size_t(r) / us.size()]);
      q[2] = uint8_t(2 * p + 1);
      q[3] = uint8_t(us[size_t(r) % us.size()]);
    }
  std::vector<uint8_t> rgb(size_t(h) * size_t(3 * w));
  gs::simd::yuyv_to_rgb_ref(w, h, yuyv.data(), 2 * w, rgb.data(), 3 * w);
  int max_diff = 0;
  size_t exact = 0, total = 0;
  for (int r = 0; r < h; ++r)
    for (int x = 0; x < w; ++x) {
      double f[3];
      bt601_double(x, us[size_t(r) / us.size()], us[size_t(r) % us.size()], f);
      for (int c = 0; c < 3; ++c) {
        const int d = std::abs(int(rgb[size_t(r) * size_t(3 * w) + size_t(3 * x + c)]) - to_u8(f[c]));
        max_diff = std::max(max_diff, d);
        exact += d == 0;
        ++total;
      }
    }
  MESSAGE("max |diff| " << max_diff << ", exact " << 100.0 * double(exact) / double(total) << "%");
  CHECK(max_diff <= 1);
  CHECK(double(exact) / double(total) > 0.9);
}

// Smooth RGB test pattern [h, w, 3]: slow ramps and a low-frequency sinusoid, inside the range
// limited-range YUV can represent, so the round trip loses only quantisation and chroma siting.
std::vector<uint8_t> smooth_pattern(int w, int h) {
  std::vector<uint8_t> rgb(size_t(w) * size_t(h) * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double fx = double(x) / w, fy = double(y) / h;
      const double v[3] = {30 + 190 * fx, 40 + 170 * fy, 128 + 90 * std::sin(6.0 * fx + 4.0 * fy)};
      for (int c = 0; c < 3; ++c) rgb[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)] = uint8_t(to_u8(v[c]));
    }
  return rgb;
}

// BT.601 limited-range forward transform (double), rounded to bytes.
void rgb_to_yuv(const uint8_t* p, double* y, double* u, double* v) {
  const double r = p[0] / 255.0, g = p[1] / 255.0, b = p[2] / 255.0;
  const double ey = 0.299 * r + 0.587 * g + 0.114 * b;
  *y = 16 + 219 * ey;
  *u = 128 + 224 * (b - ey) / 1.772;
  *v = 128 + 224 * (r - ey) / 1.402;
}

double psnr(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  REQUIRE(a.size() == b.size());
  return gs::metrics::psnr_u8(a.data(), b.data(), a.size());
}

TEST_CASE("RGB to YUV to RGB round trip through the reference keeps a smooth image") {
  const int w = 97, h = 61;  // odd: the last column/row uses a half-used chroma sample
  const auto src = smooth_pattern(w, h);
  const int cw = (w + 1) / 2, ch = (h + 1) / 2;
  std::vector<double> Y(size_t(w) * size_t(h)), U(Y.size()), V(Y.size());
  for (size_t i = 0; i < Y.size(); ++i) rgb_to_yuv(&src[3 * i], &Y[i], &U[i], &V[i]);
  auto px = [&](int x, int y) { return size_t(std::min(y, h - 1)) * size_t(w) + size_t(std::min(x, w - 1)); };
  auto b = [](double x) { return uint8_t(to_u8(x)); };
  // YUYV: chroma averaged over each horizontal pair.
  std::vector<uint8_t> yuyv(size_t(h) * size_t(4 * cw));
  for (int y = 0; y < h; ++y)
    for (int p = 0; p < cw; ++p) {
      uint8_t* q = &yuyv[size_t(y) * size_t(4 * cw) + size_t(4 * p)];
      const size_t a = px(2 * p, y), c = px(2 * p + 1, y);
      q[0] = b(Y[a]);
      q[1] = b(0.5 * (U[a] + U[c]));
      q[2] = b(Y[c]);
      q[3] = b(0.5 * (V[a] + V[c]));
    }
  // NV12: chroma averaged over each 2x2 block.
  std::vector<uint8_t> yp(size_t(w) * size_t(h)), uv(size_t(ch) * size_t(2 * cw));
  for (size_t i = 0; i < yp.size(); ++i) yp[i] = b(Y[i]);
  for (int y = 0; y < ch; ++y)
    for (int p = 0; p < cw; ++p) {
      const size_t k[4] = {px(2 * p, 2 * y), px(2 * p + 1, 2 * y), px(2 * p, 2 * y + 1), px(2 * p + 1, 2 * y + 1)};
      uv[size_t(y) * size_t(2 * cw) + size_t(2 * p)] = b(0.25 * (U[k[0]] + U[k[1]] + U[k[2]] + U[k[3]]));
      uv[size_t(y) * size_t(2 * cw) + size_t(2 * p) + 1] = b(0.25 * (V[k[0]] + V[k[1]] + V[k[2]] + V[k[3]]));
    }
  std::vector<uint8_t> back_yuyv(src.size()), back_nv12(src.size());
  gs::simd::yuyv_to_rgb_ref(w, h, yuyv.data(), 4 * cw, back_yuyv.data(), 3 * w);
  gs::simd::nv12_to_rgb_ref(w, h, yp.data(), w, uv.data(), 2 * cw, back_nv12.data(), 3 * w);
  const double p422 = psnr(src, back_yuyv), p420 = psnr(src, back_nv12);
  MESSAGE("round-trip PSNR: YUYV " << p422 << " dB, NV12 " << p420 << " dB");
  // Measured 45.9 dB (YUYV) and 42.9 dB (NV12) on this pattern; a wrong coefficient, a swapped U/V
  // or a chroma sample taken from the wrong pair drops it far below 40.
  CHECK(p422 > 42.0);
  CHECK(p420 > 40.0);
}

// ---- frame_to_rgb ----------------------------------------------------------------------------

FrameView one_plane(PixelFormat f, int w, int h, const std::vector<uint8_t>& data, int stride) {
  FrameView v;
  v.width = w;
  v.height = h;
  v.format = f;
  v.num_planes = 1;
  v.planes[0] = {data.data(), data.size(), stride};
  return v;
}

TEST_CASE("frame_to_rgb converts rgb24 yuyv and nv12 frames") {
  std::mt19937_64 rng(5);
  const int w = 45, h = 23, out_stride = 3 * w + 11;
  SUBCASE("rgb24 is a strided copy") {
    const int stride = 3 * w + 4;
    const auto src = random_plane(rng, h, stride, 3 * w);
    auto out = canary_rgb(w, h, out_stride);
    REQUIRE(gs::capture::frame_to_rgb(one_plane(PixelFormat::kRGB24, w, h, src, stride), out.data(), out_stride).ok());
    for (int y = 0; y < h; ++y)
      CHECK(std::memcmp(&out[size_t(y) * out_stride], &src[size_t(y) * stride], size_t(3 * w)) == 0);
    check_canaries(out, w, h, out_stride);
  }
  SUBCASE("yuyv matches the reference") {
    const int stride = 4 * ((w + 1) / 2) + 8;
    const auto src = random_plane(rng, h, stride, 4 * ((w + 1) / 2));
    auto out = canary_rgb(w, h, out_stride), ref = out;
    REQUIRE(gs::capture::frame_to_rgb(one_plane(PixelFormat::kYUYV, w, h, src, stride), out.data(), out_stride).ok());
    gs::simd::yuyv_to_rgb_ref(w, h, src.data(), stride, ref.data(), out_stride);
    CHECK(out == ref);
  }
  SUBCASE("nv12 matches the reference") {
    const auto y = random_plane(rng, h, w, w);
    const auto uv = random_plane(rng, (h + 1) / 2, w + 1, w + 1);
    FrameView v = one_plane(PixelFormat::kNV12, w, h, y, w);
    v.num_planes = 2;
    v.planes[1] = {uv.data(), uv.size(), w + 1};
    auto out = canary_rgb(w, h, out_stride), ref = out;
    REQUIRE(gs::capture::frame_to_rgb(v, out.data(), out_stride).ok());
    gs::simd::nv12_to_rgb_ref(w, h, y.data(), w, uv.data(), w + 1, ref.data(), out_stride);
    CHECK(out == ref);
  }
}

std::vector<uint8_t> encode_jpeg(const std::vector<uint8_t>& rgb, int w, int h, int quality) {
  std::vector<uint8_t> jpg;
  auto sink = [](void* ctx, void* data, int size) {
    auto* out = static_cast<std::vector<uint8_t>*>(ctx);
    out->insert(out->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
  };
  REQUIRE(stbi_write_jpg_to_func(sink, &jpg, w, h, 3, rgb.data(), quality) != 0);
  return jpg;
}

// Marker segments before the first SOS, as (marker byte, offset, total length with FF xx).
struct Segment {
  uint8_t marker;
  size_t at, len;
};
std::vector<Segment> header_segments(const std::vector<uint8_t>& j) {
  std::vector<Segment> segs;
  size_t pos = 2;
  while (pos + 4 <= j.size() && j[pos] == 0xff) {
    const uint8_t m = j[pos + 1];
    const size_t len = 2 + (size_t(j[pos + 2]) << 8 | j[pos + 3]);
    segs.push_back({m, pos, len});
    if (m == 0xda) break;
    pos += len;
  }
  return segs;
}

// What a UVC camera sends: the same JPEG with its DHT segments removed.
std::vector<uint8_t> strip_dht(const std::vector<uint8_t>& j) {
  std::vector<uint8_t> out(j.begin(), j.begin() + 2);
  size_t end = 2;
  for (const Segment& s : header_segments(j)) {
    if (s.marker != 0xc4) out.insert(out.end(), j.begin() + long(s.at), j.begin() + long(s.at + s.len));
    end = s.at + s.len;
  }
  out.insert(out.end(), j.begin() + long(end), j.end());
  return out;
}

TEST_CASE("frame_to_rgb decodes MJPEG frames with and without a DHT segment identically") {
  const int w = 50, h = 38;  // not a multiple of the 8x8 / 16x16 MCU
  const auto src = smooth_pattern(w, h);
  const auto jpg = encode_jpeg(src, w, h, 90);
  const auto uvc = strip_dht(jpg);
  int dht_in_jpg = 0, dht_in_uvc = 0;
  for (const Segment& s : header_segments(jpg)) dht_in_jpg += s.marker == 0xc4;
  for (const Segment& s : header_segments(uvc)) dht_in_uvc += s.marker == 0xc4;
  REQUIRE(dht_in_jpg >= 1);
  REQUIRE(dht_in_uvc == 0);
  REQUIRE(uvc.size() < jpg.size());

  const int stride = 3 * w + 2;
  auto a = canary_rgb(w, h, stride), b = a;
  const auto ra = gs::capture::frame_to_rgb(one_plane(PixelFormat::kMJPEG, w, h, jpg, 0), a.data(), stride);
  const auto rb = gs::capture::frame_to_rgb(one_plane(PixelFormat::kMJPEG, w, h, uvc, 0), b.data(), stride);
  REQUIRE_MESSAGE(ra.ok(), ra.to_string());
  REQUIRE_MESSAGE(rb.ok(), rb.to_string());
  CHECK(a == b);
  check_canaries(b, w, h, stride);
  std::vector<uint8_t> packed(src.size());
  for (int y = 0; y < h; ++y) std::memcpy(&packed[size_t(y) * 3 * w], &b[size_t(y) * stride], size_t(3 * w));
  const double p = psnr(src, packed);
  MESSAGE("MJPEG (quality 90) PSNR " << p << " dB");
  CHECK(p > 30.0);  // it really decoded the picture, not a flat grey

  // The helper itself: a no-op on a JPEG that has tables, one 420-byte DHT otherwise.
  CHECK(gs::capture::insert_default_huffman_tables(jpg.data(), jpg.size()) == jpg);
  const auto fixed = gs::capture::insert_default_huffman_tables(uvc.data(), uvc.size());
  CHECK(fixed.size() == uvc.size() + 420);
  int dht = 0;
  for (const Segment& s : header_segments(fixed)) dht += s.marker == 0xc4;
  CHECK(dht == 1);
}

TEST_CASE("default Huffman tables are complete prefix codes over the baseline symbols") {
  const std::vector<uint8_t> rgb(8 * 8 * 3, 100);
  const auto uvc = strip_dht(encode_jpeg(rgb, 8, 8, 90));
  const auto fixed = gs::capture::insert_default_huffman_tables(uvc.data(), uvc.size());
  const Segment* dht = nullptr;
  const auto segs = header_segments(fixed);
  for (const Segment& s : segs)
    if (s.marker == 0xc4) dht = &s;
  REQUIRE(dht != nullptr);
  // Baseline symbol sets: DC categories 0..11; AC run << 4 | size (size 1..10) plus EOB and ZRL.
  std::set<int> dc_syms, ac_syms = {0x00, 0xf0};
  for (int c = 0; c < 12; ++c) dc_syms.insert(c);
  for (int r = 0; r < 16; ++r)
    for (int s = 1; s <= 10; ++s) ac_syms.insert(r << 4 | s);
  std::set<int> seen_tables;
  size_t pos = dht->at + 4;
  while (pos < dht->at + dht->len) {
    const int tc_th = fixed[pos];
    seen_tables.insert(tc_th);
    double kraft = 0;
    int count = 0;
    for (int l = 1; l <= 16; ++l) {
      count += fixed[pos + size_t(l)];
      kraft += fixed[pos + size_t(l)] * std::ldexp(1.0, -l);
    }
    std::set<int> syms(fixed.begin() + long(pos + 17), fixed.begin() + long(pos + 17 + size_t(count)));
    CAPTURE(tc_th);
    CHECK(int(syms.size()) == count);  // no repeated symbol
    CHECK(syms == ((tc_th >> 4) == 0 ? dc_syms : ac_syms));
    // JPEG forbids the all-ones code, so the Kraft sum is below 1; the Annex K tables leave exactly
    // that one code unused (sum 1 - 2^-16) for AC and a few short codes for DC.
    CHECK(kraft < 1.0);
    CHECK(kraft > 0.99);
    pos += size_t(17 + count);
  }
  CHECK(pos == dht->at + dht->len);
  CHECK(seen_tables == std::set<int>{0x00, 0x01, 0x10, 0x11});
}

TEST_CASE("frame_to_rgb reports corrupt MJPEG and mismatched sizes") {
  const int w = 40, h = 24;
  const auto jpg = encode_jpeg(smooth_pattern(w, h), w, h, 85);
  std::vector<uint8_t> out(size_t(w) * size_t(h) * 3 + kTrailer, kCanary);
  auto run = [&](const std::vector<uint8_t>& bytes, int fw, int fh) {
    return gs::capture::frame_to_rgb(one_plane(PixelFormat::kMJPEG, fw, fh, bytes, 0), out.data(), 3 * w);
  };
  REQUIRE(run(jpg, w, h).ok());
  for (size_t n : {size_t(1), size_t(3), size_t(40), jpg.size() / 2, jpg.size() - 2}) {
    CAPTURE(n);
    const std::vector<uint8_t> cut(jpg.begin(), jpg.begin() + long(n));
    const gs::Status st = run(cut, w, h);
    CHECK(!st.ok());
    CHECK(st.message().find("mjpeg") != std::string::npos);
  }
  const gs::Status garbage = run(std::vector<uint8_t>(500, 0x37), w, h);
  CHECK(!garbage.ok());
  CHECK(garbage.message().find("corrupt JPEG") != std::string::npos);
  std::vector<uint8_t> bad_segment = jpg;
  bad_segment[4] = 0xff;  // first segment's length now runs past the end of the data
  CHECK(!run(bad_segment, w, h).ok());
  const gs::Status size = run(jpg, w - 2, h);  // the stream said a different size
  CHECK(!size.ok());
  CHECK(size.message().find("40x24") != std::string::npos);
}

TEST_CASE("frame_to_rgb rejects frames whose planes are too small") {
  const int w = 9, h = 5;
  std::vector<uint8_t> out(size_t(3 * w * h), 0);
  const std::vector<uint8_t> yuyv(size_t(4 * 5 * h - 1), 16);  // one byte short of 5 pairs x 5 rows
  CHECK(!gs::capture::frame_to_rgb(one_plane(PixelFormat::kYUYV, w, h, yuyv, 20), out.data(), 3 * w).ok());
  const std::vector<uint8_t> yuyv_ok(size_t(4 * 5 * h), 16);
  CHECK(gs::capture::frame_to_rgb(one_plane(PixelFormat::kYUYV, w, h, yuyv_ok, 20), out.data(), 3 * w).ok());
  CHECK(!gs::capture::frame_to_rgb(one_plane(PixelFormat::kYUYV, w, h, yuyv_ok, 18), out.data(), 3 * w).ok());
  CHECK(!gs::capture::frame_to_rgb(one_plane(PixelFormat::kYUYV, w, h, yuyv_ok, 20), out.data(), 3 * w - 1).ok());
  // NV12 with its chroma plane missing, then one chroma row short.
  const std::vector<uint8_t> luma(size_t(w * h), 16), chroma(size_t(10 * 2), 128);
  FrameView nv = one_plane(PixelFormat::kNV12, w, h, luma, w);
  CHECK(!gs::capture::frame_to_rgb(nv, out.data(), 3 * w).ok());
  nv.num_planes = 2;
  nv.planes[1] = {chroma.data(), chroma.size(), 10};
  const gs::Status short_uv = gs::capture::frame_to_rgb(nv, out.data(), 3 * w);
  CHECK(!short_uv.ok());
  CHECK(short_uv.message().find("plane 1") != std::string::npos);
}

}  // namespace
