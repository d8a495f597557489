// SPDX-License-Identifier: MIT
// Splat format tests (gs/io/splat_formats.h): round trips of .splat, .spz (v2, v3, v4) and
// compressed.ply within each format's stated quantisation bound per field, SH degrees 0-3; .spz v4
// holding v3's bytes in its ZSTD streams; the dispatcher; malformed files (truncated at every byte,
// wrong magic and version, counts beyond the data, gzip and ZSTD garbage and bombs, tables of
// contents that disagree, NaN) refused with a message naming the problem; renders of a
// round-tripped cloud against the original's.
#include <cstring>
#include <random>

#include "gs/io/ply.h"
#include "gs/io/splat_formats.h"
#include "gs/platform/file.h"
#include "io_test_util.h"
#include "splat_test_util.h"

#if GS_TEST_HAVE_ZLIB
#include <zlib.h>
#endif
#if GS_TEST_HAVE_ZSTD
#include <zstd.h>
#endif

namespace gs::io {
namespace {

using test::check_error;

// Largest error per field between a cloud and its round trip. b's splat j holds a's splat
// order[j] (identity when order is empty).
struct Errors {
  double position = 0, log_scale = 0, opacity = 0, colour = 0, rotation_deg = 0, sh1 = 0, sh_rest = 0;
};

Errors measure(const GaussianCloud& a, const GaussianCloud& b, const std::vector<uint32_t>& order = {}) {
  Errors e;
  REQUIRE(a.size() == b.size());
  const size_t Ka = size_t(sh_coeff_count(a.sh_degree)), Kb = size_t(sh_coeff_count(b.sh_degree));
  for (size_t j = 0; j < b.size(); ++j) {
    const size_t i = order.empty() ? j : order[j];
    for (size_t c = 0; c < 3; ++c) {
      e.position = std::max(e.position, std::fabs(double(a.means[3 * i + c]) - b.means[3 * j + c]));
      e.log_scale = std::max(e.log_scale, std::fabs(double(a.log_scales[3 * i + c]) - b.log_scales[3 * j + c]));
      // colour = 0.5 + SH_C0 * dc: the rendered DC colour
      e.colour = std::max(e.colour, test::kShC0 * std::fabs(double(a.sh[i * Ka * 3 + c]) - b.sh[j * Kb * 3 + c]));
    }
    e.opacity = std::max(e.opacity, std::fabs(test::sigmoid(a.opacity_logits[i]) - test::sigmoid(b.opacity_logits[j])));
    e.rotation_deg = std::max(e.rotation_deg, test::rotation_angle_deg(&a.quats[4 * i], &b.quats[4 * j]));
    for (size_t k = 1; k < std::min(Ka, Kb); ++k)
      for (size_t c = 0; c < 3; ++c) {
        const double d = std::fabs(double(a.sh[(i * Ka + k) * 3 + c]) - b.sh[(j * Kb + k) * 3 + c]);
        (k < 4 ? e.sh1 : e.sh_rest) = std::max(k < 4 ? e.sh1 : e.sh_rest, d);
      }
  }
  return e;
}

void print(const char* what, const Errors& e) {
  MESSAGE(std::string(what) << ": max error position " << e.position << ", log scale " << e.log_scale << ", opacity " << e.opacity
               << ", colour " << e.colour << ", rotation " << e.rotation_deg << " deg, SH1 " << e.sh1 << ", SH2-3 "
               << e.sh_rest);
}

std::vector<uint8_t> bytes_of(const Expected<std::vector<uint8_t>>& e) {
  REQUIRE_MESSAGE(e.ok(), e.status().to_string());
  return *e;
}

Expected<GaussianCloud> parse_as(SplatFormat f, const std::vector<uint8_t>& b, const std::string& name = "t") {
  switch (f) {
    case SplatFormat::kPly: return parse_splat_ply(b.data(), b.size(), name);
    case SplatFormat::kCompressedPly: return parse_compressed_ply(b.data(), b.size(), name);
    case SplatFormat::kAntimatterSplat: return parse_antimatter_splat(b.data(), b.size(), name);
    case SplatFormat::kSpz: return parse_spz(b.data(), b.size(), name);
  }
  return invalid_argument("?");
}

// 1e-5: float32 rounding of values of order 1-10 (a few ULPs) in the decoders.
constexpr double kFloatSlack = 1e-5;

// Builds without zlib or libzstd (cross builds) have no .spz of those versions: their cases report
// themselves skipped.
bool skip_without_spz(int version) {
  if (spz_version_supported(version)) return false;
  MESSAGE("[SKIPPED: this build has no " << (version == 4 ? "libzstd" : "zlib") << ", so no .spz version " << version << "]");
  return true;
}

SpzWriteOptions spz_version(int version) {
  SpzWriteOptions o;
  o.version = version;
  return o;
}

#if GS_TEST_HAVE_ZLIB
// gzip and gunzip through zlib directly, to build .spz files field by field and to look inside
// the writer's output.
std::vector<uint8_t> gzip(const std::vector<uint8_t>& raw) {
  z_stream s{};
  REQUIRE(deflateInit2(&s, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) == Z_OK);
  std::vector<uint8_t> out(deflateBound(&s, uLong(raw.size())) + 64);
  s.next_in = const_cast<Bytef*>(raw.data());
  s.avail_in = uInt(raw.size());
  s.next_out = out.data();
  s.avail_out = uInt(out.size());
  REQUIRE(deflate(&s, Z_FINISH) == Z_STREAM_END);
  out.resize(out.size() - s.avail_out);
  deflateEnd(&s);
  return out;
}

std::vector<uint8_t> gunzip(const std::vector<uint8_t>& gz) {
  z_stream s{};
  REQUIRE(inflateInit2(&s, 16 + MAX_WBITS) == Z_OK);
  std::vector<uint8_t> out(1 << 20);
  s.next_in = const_cast<Bytef*>(gz.data());
  s.avail_in = uInt(gz.size());
  s.next_out = out.data();
  s.avail_out = uInt(out.size());
  REQUIRE(inflate(&s, Z_FINISH) == Z_STREAM_END);
  out.resize(out.size() - s.avail_out);
  inflateEnd(&s);
  return out;
}

// A .spz of a 16-byte header with these fields and body_bytes zero bytes after it.
Expected<GaussianCloud> parse_spz_header_case(uint32_t magic, uint32_t version, uint32_t count, uint8_t degree,
                                              uint8_t flags, size_t body_bytes) {
  std::vector<uint8_t> raw(16 + body_bytes, 0);
  for (int b = 0; b < 4; ++b) {
    raw[size_t(b)] = uint8_t(magic >> (8 * b));
    raw[4 + size_t(b)] = uint8_t(version >> (8 * b));
    raw[8 + size_t(b)] = uint8_t(count >> (8 * b));
  }
  raw[12] = degree;
  raw[13] = 12;
  raw[14] = flags;
  const std::vector<uint8_t> gz = gzip(raw);
  return parse_spz(gz.data(), gz.size(), "h.spz");
}
#endif

#if GS_TEST_HAVE_ZSTD
std::vector<uint8_t> zstd_frame(const uint8_t* data, size_t size) {
  std::vector<uint8_t> out(ZSTD_compressBound(size));
  const size_t n = ZSTD_compress(out.data(), out.size(), data, size, 3);
  REQUIRE_FALSE(ZSTD_isError(n));
  out.resize(n);
  return out;
}

void put_le(std::vector<uint8_t>* b, size_t at, uint64_t v, int bytes) {
  for (int k = 0; k < bytes; ++k) (*b)[at + size_t(k)] = uint8_t(v >> (8 * k));
}

// A version-4 file from its header fields and the streams' contents, each compressed by libzstd
// directly; `toc_sizes`, when not empty, replaces the uncompressed sizes the table declares.
struct V4Case {
  uint32_t version = 4, count = 1;
  uint8_t degree = 0, flags = 0;
  int stream_count = -1;  // -1: as many as `streams`
  uint32_t toc_at = 32;
  std::vector<std::vector<uint8_t>> streams;
  std::vector<uint64_t> toc_sizes;
};
std::vector<uint8_t> make_v4(const V4Case& k) {
  const size_t streams = k.stream_count < 0 ? k.streams.size() : size_t(k.stream_count);
  std::vector<uint8_t> b(std::max<size_t>(k.toc_at, 32) + 16 * k.streams.size(), 0);
  put_le(&b, 0, 0x5053474e, 4);
  put_le(&b, 4, k.version, 4);
  put_le(&b, 8, k.count, 4);
  b[12] = k.degree;
  b[13] = 12;
  b[14] = k.flags;
  b[15] = uint8_t(streams);
  put_le(&b, 16, k.toc_at, 4);
  for (size_t s = 0; s < k.streams.size(); ++s) {
    const std::vector<uint8_t> frame = zstd_frame(k.streams[s].data(), k.streams[s].size());
    const size_t entry = std::max<size_t>(k.toc_at, 32) + 16 * s;
    put_le(&b, entry, frame.size(), 8);
    put_le(&b, entry + 8, s < k.toc_sizes.size() ? k.toc_sizes[s] : k.streams[s].size(), 8);
    b.insert(b.end(), frame.begin(), frame.end());
  }
  return b;
}

// One splat's streams at SH degree 0: positions 9, alphas 1, colours 3, scales 3, rotations 4 bytes.
std::vector<std::vector<uint8_t>> one_splat_streams(size_t count = 1) {
  return {std::vector<uint8_t>(9 * count, 0), std::vector<uint8_t>(count, 200), std::vector<uint8_t>(3 * count, 128),
          std::vector<uint8_t>(3 * count, 100), std::vector<uint8_t>(4 * count, 0xc0)};
}
#endif

TEST_CASE(".splat round trip: float32 position and scale with 8-bit colour and alpha and rotation") {
  for (int degree : {0, 3}) {
    const GaussianCloud c = test::make_test_cloud(500, degree, 11u + uint32_t(degree));
    const std::vector<uint8_t> bytes = bytes_of(encode_antimatter_splat(c));
    CHECK(bytes.size() == 32 * c.size());
    auto back = parse_antimatter_splat(bytes.data(), bytes.size(), "t.splat");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    CHECK(back->sh_degree == 0);
    const Errors e = measure(c, *back);
    print(".splat", e);
    CHECK(e.position == 0);                            // float32 as is
    CHECK(e.log_scale <= 1e-6);                        // log(exp(s)) in float32
    CHECK(e.opacity <= 0.5 / 255 + 1e-7);              // half an 8-bit step
    CHECK(e.colour <= 0.5 / 255 + 1e-7);               // half a step while 0 <= colour <= 1
    CHECK(e.rotation_deg <= 0.91);                     // components to 1/256: 2 asin(2/256) = 0.90 deg
  }
}

TEST_CASE(".spz round trip at SH degrees 0 to 3: versions 4, 3 and 2") {
  for (int version : {4, 3, 2})
    for (int degree = 0; degree <= 3; ++degree) {
      if (skip_without_spz(version)) break;
      const GaussianCloud c = test::make_test_cloud(400, degree, 100u + uint32_t(degree));
      SpzWriteOptions o;
      o.version = version;
      const std::vector<uint8_t> bytes = bytes_of(encode_spz(c, o));
      auto back = parse_spz(bytes.data(), bytes.size(), "t.spz");
      REQUIRE_MESSAGE(back.ok(), back.status().to_string());
      REQUIRE(back->sh_degree == degree);
      const Errors e = measure(c, *back);
      print((".spz v" + std::to_string(version)).c_str(), e);
      // Position: half a fixed-point step; the writer takes the most fractional bits the largest
      // coordinate (6.5 here, so 20 bits) allows: 2^-21 = 4.8e-7.
      CHECK(e.position <= std::ldexp(1.0, -21) + 1e-7);
      CHECK(e.log_scale <= 1.0 / 32 + 1e-6);       // steps of 1/16 in [-10, 5.94]
      CHECK(e.opacity <= 0.5 / 255 + 1e-7);
      CHECK(e.colour <= 0.5 / 255 * test::kShC0 / 0.15 + 1e-6);  // steps of 1 / (0.15 * 255) in dc
      if (version >= 3) CHECK(e.rotation_deg <= 0.4);  // 10-bit smallest three (analysis in README)
      CHECK(e.sh1 <= 1.0 / 32 + 1e-6);             // 5 bits: steps of 1/16
      CHECK(e.sh_rest <= 1.0 / 16 + 1e-6);         // 4 bits: steps of 1/8
      if (version == 2) {
        // x, y, z of the unit quaternion with w >= 0, to half a step of 2/255 each.
        for (size_t i = 0; i < c.size(); ++i) {
          double n = 0;
          for (int k = 0; k < 4; ++k) n += double(c.quats[4 * i + size_t(k)]) * c.quats[4 * i + size_t(k)];
          const double s = (c.quats[4 * i] < 0 ? -1.0 : 1.0) / std::sqrt(n);
          const double sb = back->quats[4 * i] < 0 ? -1.0 : 1.0;
          for (int k = 1; k < 4; ++k)
            REQUIRE(std::fabs(s * c.quats[4 * i + size_t(k)] - sb * back->quats[4 * i + size_t(k)]) <= 1.0 / 255 + 1e-3);
        }
      }
      // 8 bits everywhere: SH steps of 1/128.
      o.sh1_bits = o.sh_rest_bits = 8;
      const std::vector<uint8_t> fine = bytes_of(encode_spz(c, o));
      auto fine_back = parse_spz(fine.data(), fine.size(), "fine.spz");
      REQUIRE(fine_back.ok());
      const Errors ef = measure(c, *fine_back);
      CHECK(ef.sh1 <= 1.0 / 256 + 1e-6);
      CHECK(ef.sh_rest <= 1.0 / 256 + 1e-6);
    }
}

TEST_CASE(".spz stores RUB: y and z flip with their quaternion and SH signs") {
  if (skip_without_spz(3)) return;
  // One splat at (1, 2, 3) rotated 90 degrees about y, with degree-1 SH terms 0.5 (y), 0.25 (z), 0.125 (x).
  GaussianCloud c;
  c.sh_degree = 1;
  c.resize(1);
  c.means = {1, 2, 3};
  c.log_scales = {-1, -2, -3};
  c.quats = {float(std::sqrt(0.5)), 0, float(std::sqrt(0.5)), 0};
  c.opacity_logits = {0};
  c.sh = {0, 0, 0, 0.5f, 0.5f, 0.5f, 0.25f, 0.25f, 0.25f, 0.125f, 0.125f, 0.125f};
  const std::vector<uint8_t> bytes = bytes_of(encode_spz(c, spz_version(3)));
  auto back = parse_spz(bytes.data(), bytes.size(), "frame.spz");
  REQUIRE(back.ok());
  // hbgs's coordinates come back (the flips cancel) ...
  for (size_t k = 0; k < 3; ++k) CHECK(std::fabs(back->means[k] - c.means[k]) < 1e-6);
  CHECK(test::rotation_angle_deg(c.quats.data(), back->quats.data()) < 0.2);
  for (size_t ch = 0; ch < 3; ++ch) {
    CHECK(back->sh[3 + ch] == 0.5f);
    CHECK(back->sh[6 + ch] == 0.25f);
    CHECK(back->sh[9 + ch] == 0.125f);
  }
#if GS_TEST_HAVE_ZLIB
  // ... and the file holds them in RUB: header, then x, y, z as 24-bit fixed point.
  const std::vector<uint8_t> raw = gunzip(bytes);
  REQUIRE(raw.size() == 16 + 9 + 1 + 3 + 3 + 4 + 9);
  const int bits = raw[13];
  CHECK(bits == 21);  // the most that keep 3 inside +-2^23
  auto fixed = [&](size_t at) {
    const uint32_t v = uint32_t(raw[at]) | uint32_t(raw[at + 1]) << 8 | uint32_t(raw[at + 2]) << 16;
    return double(int32_t(v ^ 0x800000u) - 0x800000) / double(1 << bits);
  };
  CHECK(fixed(16) == 1.0);
  CHECK(fixed(19) == -2.0);
  CHECK(fixed(22) == -3.0);
  // Rotation: in RUB (x, y, z, w) = (0, -0.707, 0, 0.707); the largest magnitude (first of the two
  // equal ones: y, index 1) is made positive, so w is stored negative with the full magnitude 511.
  const size_t rot = 16 + 9 + 1 + 3 + 3;
  const uint32_t word = uint32_t(raw[rot]) | uint32_t(raw[rot + 1]) << 8 | uint32_t(raw[rot + 2]) << 16 |
                        uint32_t(raw[rot + 3]) << 24;
  CHECK((word >> 30) == 1u);
  CHECK((word & 1023u) == (1u << 9 | 511u));  // w: sign bit and magnitude
  CHECK(((word >> 10) & 1023u) == 0u);          // z
  CHECK(((word >> 20) & 1023u) == 0u);          // x
  // SH: the y and z terms change sign, x keeps it; (c * 128 + 128) to a multiple of 8.
  const size_t sh = rot + 4;
  CHECK(raw[sh] == 64);       // -0.5
  CHECK(raw[sh + 3] == 96);   // -0.25
  CHECK(raw[sh + 6] == 144);  // +0.125
#endif
}

#if GS_TEST_HAVE_ZLIB && GS_TEST_HAVE_ZSTD
TEST_CASE(".spz version 4: a plain header, a table of contents and v3's attribute bytes as ZSTD frames") {
  if (skip_without_spz(4) || skip_without_spz(3)) return;
  for (int degree : {0, 2}) {
    const GaussianCloud c = test::make_test_cloud(300, degree, 40u + uint32_t(degree));
    const std::vector<uint8_t> v3 = gunzip(bytes_of(encode_spz(c, spz_version(3))));
    const std::vector<uint8_t> v4 = bytes_of(encode_spz(c));  // the default version
    REQUIRE(v4.size() >= 32);
    auto u32 = [&](size_t at) { return uint32_t(v4[at]) | uint32_t(v4[at + 1]) << 8 | uint32_t(v4[at + 2]) << 16 | uint32_t(v4[at + 3]) << 24; };
    auto u64 = [&](size_t at) { return uint64_t(u32(at)) | uint64_t(u32(at + 4)) << 32; };
    CHECK(u32(0) == 0x5053474eu);
    CHECK(u32(4) == 4u);
    CHECK(u32(8) == 300u);
    CHECK(v4[12] == degree);
    CHECK(v4[13] == v3[13]);  // the same fractional bits
    CHECK(v4[14] == 0);       // flags
    const size_t streams = v4[15];
    CHECK(streams == (degree == 0 ? 5u : 6u));  // the empty SH attribute is left out
    CHECK(u32(16) == 32u);                       // no extension records: the table follows the header
    for (size_t k = 20; k < 32; ++k) CHECK(v4[k] == 0);
    // Each stream decompresses (libzstd directly) to the next attribute of v3's body, in order.
    const size_t per[6] = {9, 1, 3, 3, 4, size_t(sh_coeff_count(degree) - 1) * 3};
    size_t at = 32 + 16 * streams, body = 16;
    for (size_t s = 0; s < streams; ++s) {
      const uint64_t packed = u64(32 + 16 * s), raw = u64(32 + 16 * s + 8);
      CAPTURE(s);
      REQUIRE(raw == per[s] * 300);
      REQUIRE(at + packed <= v4.size());
      std::vector<uint8_t> out(raw);
      REQUIRE(ZSTD_decompress(out.data(), out.size(), v4.data() + at, packed) == raw);
      CHECK(std::equal(out.begin(), out.end(), v3.begin() + long(body)));
      at += packed, body += raw;
    }
    CHECK(at == v4.size());
    CHECK(body == v3.size());
    // And the two read back identically.
    auto a = parse_spz(v4.data(), v4.size(), "v4.spz");
    REQUIRE_MESSAGE(a.ok(), a.status().to_string());
    const std::vector<uint8_t> v3_file = bytes_of(encode_spz(c, spz_version(3)));
    auto b = parse_spz(v3_file.data(), v3_file.size(), "v3.spz");
    REQUIRE(b.ok());
    CHECK(a->means == b->means);
    CHECK(a->quats == b->quats);
    CHECK(a->sh == b->sh);
    CHECK(a->log_scales == b->log_scales);
    CHECK(a->opacity_logits == b->opacity_logits);
    MESSAGE("SH degree " << degree << ": v3 " << v3_file.size() << " bytes, v4 " << v4.size() << " bytes");
  }
}
#endif

#if GS_TEST_HAVE_ZSTD
TEST_CASE("malformed .spz version 4: header, table of contents, streams and ZSTD data") {
  if (skip_without_spz(4)) return;
  V4Case ok;
  ok.streams = one_splat_streams();
  {
    const std::vector<uint8_t> b = make_v4(ok);
    auto r = parse_spz(b.data(), b.size(), "ok.spz");
    REQUIRE_MESSAGE(r.ok(), r.status().to_string());
    CHECK(r->size() == 1);
    CHECK(std::fabs(test::sigmoid(r->opacity_logits[0]) - 200.0 / 255) < 1e-6);
  }
  // A file written by another tool may put bytes between the header and the table (tocByteOffset).
  V4Case later = ok;
  later.toc_at = 40;
  {
    const std::vector<uint8_t> b = make_v4(later);
    CHECK(parse_spz(b.data(), b.size(), "later.spz").ok());
  }
  auto error_of = [](const V4Case& k, const char* name) {
    const std::vector<uint8_t> b = make_v4(k);
    return parse_spz(b.data(), b.size(), name).status();
  };
  V4Case k = ok;
  k.version = 3;
  check_error(error_of(k, "v3plain.spz"), {"v3plain.spz", "version-3 header in the clear", "1f 8b"});
  k = ok, k.version = 5;
  check_error(error_of(k, "v5.spz"), {"v5.spz", "version 5"});
  k = ok, k.flags = 2;
  check_error(error_of(k, "ext.spz"), {"ext.spz", "extension"});
  k = ok, k.degree = 4;
  check_error(error_of(k, "deg.spz"), {"deg.spz", "SH degree 4"});
  k = ok, k.stream_count = 6;
  check_error(error_of(k, "n.spz"), {"n.spz", "6 streams", "5 non-empty"});
  k = ok, k.toc_at = 8;
  check_error(error_of(k, "toc.spz"), {"toc.spz", "table of contents", "byte 8"});
  k = ok, k.toc_sizes = {9, 1, 3, 3, 3};  // rotations declared 3 bytes, v4 has 4
  check_error(error_of(k, "size.spz"), {"size.spz", "stream 4 (rotations)", "declares 3 bytes", "need 4"});
  k = ok, k.count = 2;  // the table says one splat's sizes
  check_error(error_of(k, "count.spz"), {"count.spz", "stream 0 (positions)", "2 splats need 18"});
  // A frame shorter than the table says: it decompresses to fewer bytes.
  k = ok, k.streams[2] = {128, 128}, k.toc_sizes = {9, 1, 3, 3, 4};
  check_error(error_of(k, "short.spz"), {"short.spz", "stream 2 (colours)", "decompresses to 2 bytes"});
  // Longer than the table says.
  k = ok, k.streams[1] = {1, 2}, k.toc_sizes = {9, 1, 3, 3, 4};
  check_error(error_of(k, "long.spz"), {"long.spz", "stream 1 (alphas)", "more than the 1 bytes"});
  // A count no file this small can hold (refused before allocating its 2.3 GB).
  k = ok, k.count = 100'000'000;
  k.toc_sizes = {900'000'000, 100'000'000, 300'000'000, 300'000'000, 400'000'000};
  check_error(error_of(k, "bomb.spz"), {"bomb.spz", "100000000 splats", "compressed bytes"});
  // Bytes after the last stream; a stream running past the end; garbage in place of a frame.
  std::vector<uint8_t> b = make_v4(ok);
  b.push_back(0);
  check_error(parse_spz(b.data(), b.size(), "tail.spz").status(), {"tail.spz", "1 bytes follow the last stream"});
  b.resize(b.size() - 3);
  check_error(parse_spz(b.data(), b.size(), "cut.spz").status(), {"cut.spz", "stream 4 (rotations,", "runs past the end"});
  b = make_v4(ok);
  const size_t first_frame = 32 + 16 * 5;
  for (size_t at = first_frame; at < first_frame + 4; ++at) b[at] ^= 0x55;  // the frame's magic number
  check_error(parse_spz(b.data(), b.size(), "garbage.spz").status(), {"garbage.spz", "stream 0 (positions)", "corrupt ZSTD"});
  check_error(parse_spz(b.data(), 20, "short.spz").status(), {"short.spz", "20 bytes", "32-byte"});
  // No splats: no streams at all, read back as an empty cloud.
  V4Case empty;
  empty.count = 0;
  const std::vector<uint8_t> e = make_v4(empty);
  CHECK(e.size() == 32);
  auto r = parse_spz(e.data(), e.size(), "empty.spz");
  REQUIRE_MESSAGE(r.ok(), r.status().to_string());
  CHECK(r->size() == 0);
  const std::vector<uint8_t> written = bytes_of(encode_spz(GaussianCloud{}));
  CHECK(written.size() == 32);
  CHECK(parse_spz(written.data(), written.size(), "empty.spz").ok());
}
#endif

// compressed.ply: the bound of each field is half a step of its chunk's range.
TEST_CASE("compressed.ply round trip at SH degrees 0 to 3 within each chunk's quantisation") {
  for (int degree = 0; degree <= 3; ++degree) {
    const size_t n = 1000;  // 4 chunks, the last one partial
    const GaussianCloud c = test::make_test_cloud(n, degree, 200u + uint32_t(degree));
    std::vector<uint32_t> order;
    const std::vector<uint8_t> bytes = bytes_of(encode_compressed_ply(c, &order));
    REQUIRE(order.size() == n);
    CHECK(is_compressed_ply(bytes.data(), bytes.size()));
    auto back = parse_compressed_ply(bytes.data(), bytes.size(), "t.compressed.ply");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    REQUIRE(back->sh_degree == degree);
    const Errors e = measure(c, *back, order);
    print("compressed.ply", e);
    const size_t K = size_t(sh_coeff_count(degree));
    for (size_t first = 0; first < n; first += 256) {
      const size_t last = std::min(n, first + 256);
      double lo[9], hi[9];  // position, log scale, colour per axis / channel
      for (int k = 0; k < 9; ++k) lo[k] = 1e30, hi[k] = -1e30;
      for (size_t j = first; j < last; ++j)
        for (size_t a = 0; a < 3; ++a) {
          const size_t i = order[j];
          const double v[3] = {c.means[3 * i + a], c.log_scales[3 * i + a], 0.5 + test::kShC0 * c.sh[i * K * 3 + a]};
          for (size_t f = 0; f < 3; ++f) lo[3 * f + a] = std::min(lo[3 * f + a], v[f]), hi[3 * f + a] = std::max(hi[3 * f + a], v[f]);
        }
      for (size_t j = first; j < last; ++j) {
        const size_t i = order[j];
        for (size_t a = 0; a < 3; ++a) {
          const double steps = a == 1 ? 1023 : 2047;  // 11/10/11 bits
          CHECK(std::fabs(c.means[3 * i + a] - back->means[3 * j + a]) <= (hi[a] - lo[a]) / steps / 2 + kFloatSlack);
          CHECK(std::fabs(c.log_scales[3 * i + a] - back->log_scales[3 * j + a]) <=
                (hi[3 + a] - lo[3 + a]) / steps / 2 + kFloatSlack);
          CHECK(test::kShC0 * std::fabs(c.sh[i * K * 3 + a] - back->sh[j * K * 3 + a]) <=
                (hi[6 + a] - lo[6 + a]) / 255 / 2 + kFloatSlack);
        }
      }
    }
    CHECK(e.opacity <= 0.5 / 255 + 1e-7);
    CHECK(e.rotation_deg <= 0.4);                  // 10-bit smallest three
    CHECK(e.sh1 <= 1.0 / 64 + 1e-6);               // 8 bits over [-4, 4]: steps of 1/32
    CHECK(e.sh_rest <= 1.0 / 64 + 1e-6);
  }
}

TEST_CASE("compressed.ply reads the older 12-property chunks (colour bytes are the colour)") {
  const GaussianCloud c = test::make_test_cloud(300, 0, 7);
  std::vector<uint32_t> order;
  std::vector<uint8_t> bytes = bytes_of(encode_compressed_ply(c, &order));
  // Rewrite the file without min_r..max_b and with absolute colour bytes.
  const std::string text(bytes.begin(), bytes.end());
  const size_t head_end = text.find("end_header\n") + 11;
  std::string head = text.substr(0, head_end);
  for (const char* p : {"min_r", "min_g", "min_b", "max_r", "max_g", "max_b"})
    head.erase(head.find(std::string("property float ") + p + "\n"), std::strlen("property float \n") + std::strlen(p));
  const size_t chunks = 2, n = c.size();
  std::vector<uint8_t> out(head.begin(), head.end());
  const uint8_t* chunk_data = bytes.data() + head_end;
  for (size_t k = 0; k < chunks; ++k) out.insert(out.end(), chunk_data + k * 72, chunk_data + k * 72 + 48);
  const uint8_t* vertex = chunk_data + chunks * 72;
  for (size_t j = 0; j < n; ++j) {
    uint32_t words[4];
    std::memcpy(words, vertex + 16 * j, 16);
    const size_t i = order[j];
    uint32_t colour = words[3] & 255u;
    for (int ch = 0; ch < 3; ++ch)
      colour |= uint32_t(std::lround(std::clamp(0.5 + test::kShC0 * c.sh[3 * i + size_t(ch)], 0.0, 1.0) * 255)) << (24 - 8 * ch);
    words[3] = colour;
    const uint8_t* w = reinterpret_cast<const uint8_t*>(words);
    out.insert(out.end(), w, w + 16);
  }
  auto back = parse_compressed_ply(out.data(), out.size(), "old.compressed.ply");
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  const Errors e = measure(c, *back, order);
  CHECK(e.colour <= 0.5 / 255 + 1e-6);
}

TEST_CASE("read_gaussians and write_gaussians: every format by name and content") {
  test::TempDir dir;
  const GaussianCloud c = test::make_test_cloud(300, 2, 5);
  struct Case {
    const char* name;
    SplatFormat format;
  };
  for (const Case& k : {Case{"a.ply", SplatFormat::kPly}, Case{"b.compressed.ply", SplatFormat::kCompressedPly},
                        Case{"c.SPLAT", SplatFormat::kAntimatterSplat}, Case{"d.spz", SplatFormat::kSpz}}) {
    const std::string path = dir / k.name;
    if (k.format == SplatFormat::kSpz && !spz_version_supported(4)) {  // the default version
      check_error(write_gaussians(path, c), {"d.spz", "libzstd"});
      continue;
    }
    REQUIRE_MESSAGE(write_gaussians(path, c).ok(), k.name);
    SplatFormat read_as = SplatFormat::kPly;
    auto back = read_gaussians(path, &read_as);
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    CHECK(read_as == k.format);
    CHECK(back->size() == c.size());
    if (k.format == SplatFormat::kPly) {  // exact
      CHECK(back->means == c.means);
      CHECK(back->sh == c.sh);
      CHECK(back->quats == c.quats);
    }
  }
  // The content decides where there is a magic number: a compressed.ply named .ply, a .spz named .bin.
  const std::vector<uint8_t> compressed = test::read_bytes(dir / "b.compressed.ply");
  test::write_bytes(dir / "plain_name.ply", compressed);
  SplatFormat f = SplatFormat::kPly;
  REQUIRE(read_gaussians(dir / "plain_name.ply", &f).ok());
  CHECK(f == SplatFormat::kCompressedPly);
  if (spz_version_supported(4)) {
    test::write_bytes(dir / "scene.bin", test::read_bytes(dir / "d.spz"));
    REQUIRE(read_gaussians(dir / "scene.bin", &f).ok());
    CHECK(f == SplatFormat::kSpz);
  }
  // No magic and no known name: refused with the list.
  test::write_bytes(dir / "scene.dat", test::read_bytes(dir / "c.SPLAT"));
  check_error(read_gaussians(dir / "scene.dat").status(), {"scene.dat", ".splat", ".spz", ".compressed.ply"});
  check_error(write_gaussians(dir / "x.obj", c), {"x.obj", "unknown splat file extension", ".spz"});
  CHECK(splat_format_from_extension("A.Compressed.PLY").ok());
  CHECK(*splat_format_from_extension("A.Compressed.PLY") == SplatFormat::kCompressedPly);
  // Writers refuse clouds they cannot store, naming the splat and field; nothing is written.
  GaussianCloud bad = c;
  bad.means[3 * 7 + 1] = NAN;
  for (const char* name : {"n.ply", "n.compressed.ply", "n.splat", "n.spz"}) {
    if (std::string(name) == "n.spz" && !spz_version_supported(4)) continue;
    check_error(write_gaussians(dir / name, bad), {name, "splat 7", "position"});
    CHECK_FALSE(platform::file_exists(dir / name));
  }
  bad = c;
  bad.quats[4 * 3] = bad.quats[4 * 3 + 1] = bad.quats[4 * 3 + 2] = bad.quats[4 * 3 + 3] = 0;
  check_error(write_gaussians(dir / "z.splat", bad), {"splat 3", "zero"});
  bad = c;
  bad.sh.pop_back();
  check_error(write_gaussians(dir / "s.splat", bad), {"SH coefficient", "values"});
}

// Every prefix of a small valid file is refused with a message naming the file (and never crashes
// or reads out of bounds: the ASan build runs this too).
void check_every_truncation(SplatFormat f, const std::vector<uint8_t>& bytes, const char* name) {
  for (size_t cut = 0; cut < bytes.size(); ++cut) {
    const std::vector<uint8_t> part(bytes.begin(), bytes.begin() + long(cut));
    auto r = parse_as(f, part, name);
    if (r.ok()) {
      // Only a .splat can lose whole records and stay valid.
      REQUIRE(f == SplatFormat::kAntimatterSplat);
      REQUIRE(cut % 32 == 0);
      continue;
    }
    REQUIRE_MESSAGE(test::contains(r.status().message(), name), r.status().message());
  }
}

TEST_CASE("malformed splat files: truncated at every byte") {
  const GaussianCloud c = test::make_test_cloud(5, 1, 3);
  check_every_truncation(SplatFormat::kAntimatterSplat, bytes_of(encode_antimatter_splat(c)), "cut.splat");
  for (int version : {2, 3, 4})
    if (spz_version_supported(version))
      check_every_truncation(SplatFormat::kSpz, bytes_of(encode_spz(c, spz_version(version))), "cut.spz");
  check_every_truncation(SplatFormat::kCompressedPly, bytes_of(encode_compressed_ply(c)), "cut.compressed.ply");
  check_every_truncation(SplatFormat::kPly, bytes_of(encode_gaussians(c, SplatFormat::kPly)), "cut.ply");
}

TEST_CASE("malformed .spz: magic, version, counts, gzip garbage and bombs") {
  if (skip_without_spz(3)) return;
  check_error(parse_spz(nullptr, 0, "e.spz").status(), {"e.spz", "gzip"});
  const std::string text = "hello, not gzip";
  check_error(parse_spz(reinterpret_cast<const uint8_t*>(text.data()), text.size(), "t.spz").status(), {"t.spz", "1f 8b"});
  // A gzip magic followed by garbage.
  std::vector<uint8_t> garbage = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3};
  std::mt19937 rng(1);
  for (int k = 0; k < 64; ++k) garbage.push_back(uint8_t(rng()));
  check_error(parse_spz(garbage.data(), garbage.size(), "g.spz").status(), {"g.spz", "gzip"});
  // A version-4 header inside gzip (version 4 keeps it in the clear); other versions.
#if GS_TEST_HAVE_ZLIB
  check_error(parse_spz_header_case(0x5053474e, 4, 1, 0, 0, 30).status(), {"version-4 header inside a gzip stream"});
  check_error(parse_spz_header_case(0x5053474e, 1, 1, 0, 0, 30).status(), {"version 1"});
  check_error(parse_spz_header_case(0x5053474e, 9, 1, 0, 0, 30).status(), {"version 9"});
  check_error(parse_spz_header_case(0x12345678, 3, 1, 0, 0, 30).status(), {"NGSP", "0x12345678"});
  check_error(parse_spz_header_case(0x5053474e, 3, 1, 5, 0, 30).status(), {"SH degree 5"});
  check_error(parse_spz_header_case(0x5053474e, 3, 1, 4, 0, 30).status(), {"SH degree 4"});
  check_error(parse_spz_header_case(0x5053474e, 3, 1, 0, 2, 30).status(), {"extension"});
  // Counts beyond the data: one splat short, one byte over, and a count no gzip stream of this size
  // can hold (refused before allocating its 4 GB).
  check_error(parse_spz_header_case(0x5053474e, 3, 2, 0, 0, 20).status(), {"truncated", "2 splats", "40 bytes"});
  check_error(parse_spz_header_case(0x5053474e, 3, 1, 0, 0, 21).status(), {"more than the 20 bytes"});
  check_error(parse_spz_header_case(0x5053474e, 3, 100'000'000, 3, 0, 20).status(), {"100000000", "compressed bytes"});
  check_error(parse_spz_header_case(0x5053474e, 3, 200'000'000, 0, 0, 20).status(), {"200000000"});
  // A real bomb: 3 splats declared, 16 MB of zeros after them (16 kB compressed).
  {
    std::vector<uint8_t> raw(16 + 60 + (16u << 20), 0);
    raw[0] = 'N', raw[1] = 'G', raw[2] = 'S', raw[3] = 'P', raw[4] = 3, raw[8] = 3, raw[13] = 12;
    const std::vector<uint8_t> bomb = gzip(raw);
    check_error(parse_spz(bomb.data(), bomb.size(), "bomb.spz").status(), {"bomb.spz", "more than the 60 bytes"});
  }
#endif
  // Trailing bytes after the gzip stream (and after v4's last stream).
  const GaussianCloud c = test::make_test_cloud(3, 0, 1);
  for (int version : {3, 4}) {
    if (!spz_version_supported(version)) continue;
    CAPTURE(version);
    std::vector<uint8_t> ok = bytes_of(encode_spz(c, spz_version(version)));
    ok.push_back(0);
    check_error(parse_spz(ok.data(), ok.size(), "tail.spz").status(), {"tail.spz", "1 bytes follow"});
    // A flipped bit inside the compressed data: a gzip or ZSTD error, a CRC mismatch or other
    // splats, never a crash.
    ok.pop_back();
    for (size_t at = 10; at < ok.size(); at += 3) {
      std::vector<uint8_t> flipped = ok;
      flipped[at] ^= 0x10;
      auto r = parse_spz(flipped.data(), flipped.size(), "flip.spz");
      if (!r.ok()) CHECK(test::contains(r.status().message(), "flip.spz"));
    }
  }
}

TEST_CASE("malformed .splat and compressed.ply: sizes, counts, layouts and NaN") {
  const GaussianCloud c = test::make_test_cloud(300, 1, 9);
  // .splat: not a whole number of records; empty; NaN position; negative scale.
  std::vector<uint8_t> s = bytes_of(encode_antimatter_splat(c));
  check_error(parse_antimatter_splat(s.data(), s.size() - 5, "a.splat").status(), {"a.splat", "32-byte", "27 bytes over"});
  check_error(parse_antimatter_splat(s.data(), 0, "a.splat").status(), {"a.splat", "empty"});
  std::vector<uint8_t> nan_splat = s;
  const float nan = NAN, negative = -1.0f;
  std::memcpy(&nan_splat[32 * 4 + 4], &nan, 4);
  check_error(parse_antimatter_splat(nan_splat.data(), nan_splat.size(), "n.splat").status(), {"n.splat", "record 4", "position 1"});
  std::vector<uint8_t> neg_splat = s;
  std::memcpy(&neg_splat[32 * 2 + 16], &negative, 4);
  check_error(parse_antimatter_splat(neg_splat.data(), neg_splat.size(), "s.splat").status(), {"record 2", "scale 1"});
  // A record with a zero rotation (four 128s) reads as unrotated, as the viewers draw it.
  std::vector<uint8_t> zero_rot = s;
  for (int k = 0; k < 4; ++k) zero_rot[28 + size_t(k)] = 128;
  auto z = parse_antimatter_splat(zero_rot.data(), zero_rot.size(), "z.splat");
  REQUIRE(z.ok());
  CHECK(z->quats[0] == 1.0f);

  // compressed.ply: counts that disagree, an unknown layout, NaN chunk bounds, extra bytes.
  const std::vector<uint8_t> p = bytes_of(encode_compressed_ply(c));
  const std::string text(p.begin(), p.end());
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    t.replace(t.find(from), from.size(), to);
    return std::vector<uint8_t>(t.begin(), t.end());
  };
  auto parse_text = [](const std::vector<uint8_t>& b) { return parse_compressed_ply(b.data(), b.size(), "c.ply"); };
  check_error(parse_text(with("element chunk 2", "element chunk 3")).status(), {"c.ply", "300 vertices need 2 chunks"});
  check_error(parse_text(with("element vertex 300", "element vertex 600")).status(), {"c.ply", "need 3 chunks"});
  check_error(parse_text(with("element sh 300", "element sh 299")).status(), {"c.ply", "'sh' has 299 entries"});
  check_error(parse_text(with("element vertex 300", "element vertex 400")).status(), {"c.ply", "'sh' has 300 entries"});
  check_error(parse_text(with("property uint packed_scale", "property int packed_scale")).status(), {"packed_scale", "int32"});
  check_error(parse_text(with("property float max_z", "property float max_w")).status(), {"c.ply", "max_z"});
  check_error(parse_text(with("binary_little_endian", "binary_big_endian")).status(), {"c.ply", "binary_big_endian"});
  check_error(parse_text(with("element vertex 300", "element vertex 99999999999")).status(), {"c.ply", "99999999999"});
  std::vector<uint8_t> longer = p;
  longer.push_back(0);
  check_error(parse_compressed_ply(longer.data(), longer.size(), "l.ply").status(), {"l.ply", "follow it"});
  std::vector<uint8_t> nan_chunk = p;
  const size_t head = text.find("end_header\n") + 11;
  std::memcpy(&nan_chunk[head + 72 + 4 * 4], &nan, 4);  // chunk 1, max_y
  check_error(parse_compressed_ply(nan_chunk.data(), nan_chunk.size(), "n.ply").status(), {"n.ply", "chunk 1", "max_y"});

  // The 3DGS PLY reader refuses NaN too now (through the dispatcher and directly).
  GaussianCloud ply_cloud = test::make_test_cloud(4, 0, 2);
  std::vector<uint8_t> ply = encode_splat_ply(ply_cloud);
  const size_t ply_head = std::string(ply.begin(), ply.end()).find("end_header\n") + 11;
  std::memcpy(&ply[ply_head + 17 * 4 * 1 + 4], &nan, 4);  // vertex 1 (17 floats at degree 0), y
  check_error(parse_gaussians(ply.data(), ply.size(), "nan.ply").status(), {"nan.ply", "splat 1", "position 1"});
}

TEST_CASE("the fuzz seed corpora of the splat formats are valid files") {
  // fuzz/make_splat_corpus.py writes them from the layouts' descriptions (not with hbgs's writers),
  // so reading them also checks the readers against an independent writer.
  namespace fs = std::filesystem;
  const std::string corpus = std::string(GS_SOURCE_DIR) + "/fuzz/corpus/";
  size_t files = 0;
  for (const char* harness : {"splat", "spz", "compressed_ply"}) {
    if (std::string(harness) == "spz" && !spz_supported()) continue;  // seeds of every version
    for (const auto& entry : fs::directory_iterator(corpus + harness)) {
      std::vector<uint8_t> b = test::read_bytes(entry.path().string());
      REQUIRE_FALSE(b.empty());
      const std::string name = entry.path().filename().string();
      // spz and compressed_ply seeds start with the harness's selector byte; an odd one before a
      // .spz means the rest is the decompressed stream.
      if (std::string(harness) == "spz" && (b[0] & 1)) {
#if GS_TEST_HAVE_ZLIB
        b = gzip(std::vector<uint8_t>(b.begin() + 1, b.end()));
        b.insert(b.begin(), 0);
#else
        continue;
#endif
      }
      Expected<GaussianCloud> r = std::string(harness) == "splat" ? parse_antimatter_splat(b.data(), b.size(), name)
                                  : std::string(harness) == "spz" ? parse_spz(b.data() + 1, b.size() - 1, name)
                                                                  : parse_gaussians(b.data() + 1, b.size() - 1, name);
      CHECK_MESSAGE(r.ok(), r.status().to_string());
      if (r.ok()) CHECK(r->size() > 0);
      ++files;
    }
  }
  CHECK(files >= (spz_supported() ? 10u : 6u));
}

TEST_CASE("renders after a round trip through each format match the original") {
  // PSNR bounds a few dB under the values measured with this scene (printed below; at SH degree
  // 0 / 3: .splat (against the cloud cut to SH degree 0, all it stores) 61.7 / 61.6, .spz 51.3 /
  // 36.5, compressed.ply 50.7 / 46.2 dB). A wrong convention gives far less (checked below).
  const Camera cam = test::splat_test_camera();
  for (int degree : {0, 3}) {
    const GaussianCloud c = test::make_test_cloud(2000, degree, 300u + uint32_t(degree));
    const std::vector<float> reference = test::render_cloud(c, cam);
    REQUIRE_FALSE(reference.empty());
    // .splat keeps the DC colour only: its round trip is compared with the cloud cut to SH degree 0.
    GaussianCloud dc_only = c;
    dc_only.sh_degree = 0;
    dc_only.sh.resize(c.size() * 3);
    const size_t K = size_t(sh_coeff_count(degree));
    for (size_t i = 0; i < c.size(); ++i)
      for (size_t ch = 0; ch < 3; ++ch) dc_only.sh[3 * i + ch] = c.sh[i * K * 3 + ch];
    const std::vector<float> reference_dc = test::render_cloud(dc_only, cam);
    struct Case {
      SplatFormat format;
      double min_psnr;
    };
    for (const Case& k : {Case{SplatFormat::kPly, 1e9}, Case{SplatFormat::kAntimatterSplat, 50.0},
                          Case{SplatFormat::kSpz, 33.0}, Case{SplatFormat::kCompressedPly, 40.0}}) {
      if (k.format == SplatFormat::kSpz && !spz_version_supported(4)) continue;  // the default version
      const std::vector<uint8_t> bytes = bytes_of(encode_gaussians(c, k.format));
      auto back = parse_as(k.format, bytes, "render");
      REQUIRE(back.ok());
      const bool dc = k.format == SplatFormat::kAntimatterSplat;
      const double db = test::psnr(dc ? reference_dc : reference, test::render_cloud(*back, cam));
      MESSAGE("SH degree " << degree << ", " << std::string(splat_format_name(k.format)) << ": " << bytes.size() / double(c.size())
                           << " bytes per splat, render PSNR " << db << " dB" << std::string(dc ? " (against SH degree 0)" : ""));
      CHECK(db >= k.min_psnr);
    }
    // The bounds separate right from wrong: the quaternion read in the wrong order (x, y, z, w),
    // or y flipped as an RUB/RDF mix-up would, render far below them.
    GaussianCloud wrong_order = c, flipped = c;
    for (size_t i = 0; i < c.size(); ++i) {
      for (size_t k = 0; k < 4; ++k) wrong_order.quats[4 * i + k] = c.quats[4 * i + (k + 1) % 4];
      flipped.means[3 * i + 1] = -c.means[3 * i + 1];
    }
    const double wrong_db = test::psnr(reference, test::render_cloud(wrong_order, cam));
    const double flipped_db = test::psnr(reference, test::render_cloud(flipped, cam));
    MESSAGE("SH degree " << degree << ": quaternion order wrong " << wrong_db << " dB, y flipped " << flipped_db << " dB");
    CHECK(wrong_db < 30);  // under every format's bound
    CHECK(flipped_db < 20);
  }
}

}  // namespace
}  // namespace gs::io
