// SPDX-License-Identifier: MIT
// Niantic's .spz, versions 2 and 3 (one gzip stream, zlib) and 4 (ZSTD streams, libzstd)
// (gs/io/splat_formats.h). Written from the format description in nianticlabs/spz's README (all
// little-endian):
//   v2, v3     gzip of a 16-byte header and the attributes below, one after the other:
//              magic 0x5053474e ("NGSP"), version, numPoints (uint32); shDegree, fractionalBits,
//              flags (0x1 antialiased, 0x2 vendor extensions follow), reserved (uint8)
//   v4         a 32-byte header in the clear: magic, version, numPoints (uint32); shDegree,
//              fractionalBits, flags, numStreams (uint8); tocByteOffset (uint32); 12 reserved
//              bytes; vendor extension records up to tocByteOffset (flag 0x2); the table of
//              contents, numStreams x (compressed size, uncompressed size) as uint64; then each
//              attribute's bytes as its own ZSTD frame, empty attributes (SH at degree 0, all of
//              them for no splats) left out
//   positions  3 x 24-bit two's complement fixed point, value = integer / 2^fractionalBits
//   alphas     uint8 sigmoid(logit) * 255
//   colours    uint8 dc * 0.15 * 255 + 127.5 (0.15 instead of SH_C0 leaves room outside [0, 1])
//   scales     uint8 (log scale + 10) * 16
//   rotations  v3, v4: uint32, bits 30-31 the index (in x, y, z, w order) of the largest-magnitude
//              component of the unit quaternion, made positive and left out; then the other three
//              in index order, most significant first, 10 bits each (sign, 9-bit magnitude of
//              |c| * sqrt(2)); v2: uint8 x, y, z as (q + 1) * 127.5 with w >= 0 implied
//   sh         uint8 (c * 128 + 128) per coefficient (degree 1 first) and colour (inner), rounded
//              to a multiple of 2^(8 - bits) so the compressor finds the repeated low bits
// The file's frame is RUB (y up, z backward); hbgs's is RDF, so y and z flip on the way in and out.
// Vendor extension records are refused with a message (some change how the splats decode).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "../io_util.h"
#include "gs/io/splat_formats.h"
#include "gs/platform/file.h"
#include "splat_common.h"

#ifndef GS_HAVE_ZLIB
#define GS_HAVE_ZLIB 0
#endif
#ifndef GS_HAVE_ZSTD
#define GS_HAVE_ZSTD 0
#endif
#if GS_HAVE_ZLIB
#include <zlib.h>
#endif
#if GS_HAVE_ZSTD
#include <zstd.h>
#include <zstd_errors.h>
#endif

namespace gs::io {
namespace {

constexpr uint32_t kSpzMagic = 0x5053474e;  // "NGSP" as a little-endian uint32

std::string no_codec(int version) {
  if (version == 4)
    return "version 4 (ZSTD streams) needs libzstd, which this build of hbgs lacks; write or convert to version 3 "
           "(hbgs export --spz-version 3, splat-transform --spz-version 3) on a build that has it";
  return "versions 2 and 3 (gzip) need zlib, which this build of hbgs lacks";
}

#if GS_HAVE_ZLIB || GS_HAVE_ZSTD

constexpr size_t kGzipHeaderBytes = 16;  // v2, v3: inside the gzip stream
constexpr uint8_t kFlagExtensions = 0x2;  // 0x1 (trained antialiased) changes nothing hbgs reads
constexpr float kColourScale = 0.15f;          // the format's DC colour scale
using detail::kSqrtHalf;

// Sign of each SH coefficient k = 1..15 (index k - 1) under the frame change (x, y, z) -> (x, -y, -z)
// between RDF and RUB: the real SH basis functions of 3DGS that are odd in y*z-parity flip
// (degree 1: y, z, x; degree 2: xy, yz, 3zz-1, xz, xx-yy; degree 3: y(3xx-yy), xyz, y(5zz-1),
// z(5zz-3), x(5zz-1), z(xx-yy), x(xx-3yy)).
constexpr float kShSignRdfRub[15] = {-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1};
// Position and quaternion-vector signs under the same frame change.
constexpr float kAxisSignRdfRub[3] = {1, -1, -1};

size_t rotation_bytes(uint32_t version) { return version >= 3 ? 4 : 3; }

// The attributes in file order, and each one's bytes per splat.
enum Attribute { kPositions, kAlphas, kColours, kScales, kRotations, kSh, kAttributeCount };

void attribute_bytes_per_splat(uint32_t version, int sh_degree, size_t out[kAttributeCount]) {
  out[kPositions] = 9;
  out[kAlphas] = 1;
  out[kColours] = 3;
  out[kScales] = 3;
  out[kRotations] = rotation_bytes(version);
  out[kSh] = size_t(sh_coeff_count(sh_degree) - 1) * 3;
}

// Bytes per splat after the header: position 9, alpha 1, colour 3, scale 3, rotation, SH.
size_t bytes_per_splat(uint32_t version, int sh_degree) {
  size_t per[kAttributeCount];
  attribute_bytes_per_splat(version, sh_degree, per);
  size_t sum = 0;
  for (size_t b : per) sum += b;
  return sum;
}

std::string version_hint(uint32_t version) {
  if (version == 1) return "version 1 (float16 positions, never released) is not supported";
  return "unknown version " + std::to_string(version) + " (hbgs reads versions 2, 3 and 4)";
}

std::string hex32(uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", v);
  return text;
}

void put_u32(uint8_t* at, uint32_t v) {
  for (int b = 0; b < 4; ++b) at[b] = uint8_t(v >> (8 * b));
}

struct Header {
  uint32_t version = 0, count = 0;
  int sh_degree = 0, fractional_bits = 0;
  uint8_t flags = 0;
};

// The fields both header layouts share (count, SH degree, fractional bits, flags; the version is
// checked by the caller). `h` points at numPoints.
Status parse_common_fields(const uint8_t* h, const std::string& src, Header* out) {
  out->count = detail::load_u32(h);
  if (out->count > detail::kMaxSplats)
    return unsupported(src + ": header declares " + std::to_string(out->count) + " splats, more than the " +
                       std::to_string(detail::kMaxSplats) + " allowed");
  out->sh_degree = h[4];
  if (out->sh_degree == 4) return unsupported(src + ": SH degree 4 (hbgs renders degrees 0 to 3)");
  if (out->sh_degree > 4) return parse_error(src + ": SH degree " + std::to_string(out->sh_degree) + " (expected 0 to 4)");
  out->fractional_bits = h[5];
  if (out->fractional_bits > 31)
    return parse_error(src + ": " + std::to_string(out->fractional_bits) + " fractional bits (expected at most 31)");
  out->flags = h[6];
  if (out->flags & kFlagExtensions)
    return unsupported(src + ": the file carries vendor extension records (flag 0x2), which can change how the "
                             "splats decode; hbgs does not read them");
  return Status::Ok();
}

// The splats of a header-described file from its attribute arrays (each count x its bytes per splat).
GaussianCloud decode_attributes(const Header& h, const uint8_t* const attributes[kAttributeCount]) {
  const size_t n = h.count, K = size_t(sh_coeff_count(h.sh_degree));
  GaussianCloud c;
  c.sh_degree = h.sh_degree;
  c.resize(n);
  const uint8_t* positions = attributes[kPositions];
  const uint8_t* alphas = attributes[kAlphas];
  const uint8_t* colours = attributes[kColours];
  const uint8_t* scales = attributes[kScales];
  const uint8_t* rotations = attributes[kRotations];
  const uint8_t* sh = attributes[kSh];
  for (size_t i = 0; i < 3 * n; ++i) {
    uint32_t bits = uint32_t(detail::load_le(positions + 3 * i, 3));
    const int32_t fixed = int32_t(bits ^ 0x800000u) - 0x800000;  // sign-extend 24 bits
    c.means[i] = float(std::ldexp(double(fixed), -h.fractional_bits)) * kAxisSignRdfRub[i % 3];
    c.sh[(i / 3) * K * 3 + i % 3] = (float(colours[i]) / 255.0f - 0.5f) / kColourScale;
    c.log_scales[i] = float(scales[i]) / 16.0f - 10.0f;
  }
  for (size_t i = 0; i < n; ++i) {
    c.opacity_logits[i] = detail::logit_from_alpha8(alphas[i]);
    float xyzw[4];  // the file's component order
    if (h.version >= 3) {
      uint32_t comp = detail::load_u32(rotations + 4 * i);
      const int largest = int(comp >> 30);
      double sum_sq = 0;
      for (int k = 3; k >= 0; --k) {
        if (k == largest) continue;
        const double v = kSqrtHalf * double(comp & 511u) / 511.0;
        xyzw[k] = float((comp >> 9) & 1u ? -v : v);
        sum_sq += double(xyzw[k]) * xyzw[k];
        comp >>= 10;
      }
      xyzw[largest] = float(std::sqrt(std::max(0.0, 1.0 - sum_sq)));
    } else {
      double sum_sq = 0;
      for (int k = 0; k < 3; ++k) {
        xyzw[k] = float(rotations[3 * i + size_t(k)]) / 127.5f - 1.0f;
        sum_sq += double(xyzw[k]) * xyzw[k];
      }
      xyzw[3] = float(std::sqrt(std::max(0.0, 1.0 - sum_sq)));
    }
    // Back to RDF and to hbgs's (w, x, y, z); unit length (a smallest-three code can hold three
    // components whose squares exceed 1, and the v2 w is clamped at 0).
    const float wxyz[4] = {xyzw[3], xyzw[0] * kAxisSignRdfRub[0], xyzw[1] * kAxisSignRdfRub[1], xyzw[2] * kAxisSignRdfRub[2]};
    double q[4];
    detail::normalized_quaternion(wxyz, q);  // never zero: the largest component is at least 0.5
    for (int k = 0; k < 4; ++k) c.quats[4 * i + size_t(k)] = float(q[k]);
    for (size_t k = 1; k < K; ++k)
      for (size_t ch = 0; ch < 3; ++ch)
        c.sh[(i * K + k) * 3 + ch] =
            (float(sh[(i * (K - 1) + (k - 1)) * 3 + ch]) - 128.0f) / 128.0f * kShSignRdfRub[k - 1];
  }
  return c;
}

// Where each attribute starts in a contiguous body (v2, v3: one after the other, in file order).
void attribute_offsets(const Header& h, size_t offsets[kAttributeCount]) {
  size_t per[kAttributeCount];
  attribute_bytes_per_splat(h.version, h.sh_degree, per);
  size_t at = 0;
  for (int a = 0; a < kAttributeCount; ++a) {
    offsets[a] = at;
    at += per[a] * h.count;
  }
}

// The attribute bytes a header declares, refused before anything is allocated for them when they
// exceed `limit` (the most the file's compressed bytes can expand to: a bomb, or a corrupt count)
// or this build's memory.
Expected<uint64_t> declared_body_bytes(const Header& h, uint64_t limit, size_t file_size, const std::string& src) {
  const uint64_t body_bytes = uint64_t(h.count) * bytes_per_splat(h.version, h.sh_degree);
  if (body_bytes > limit)
    return parse_error(src + ": the header declares " + std::to_string(h.count) + " splats (" +
                       std::to_string(body_bytes) + " bytes), more than " + std::to_string(file_size) +
                       " compressed bytes can hold (truncated file or corrupt count)");
  GS_RETURN_IF_ERROR(detail::check_cloud_fits(h.count, h.sh_degree, src));
  if (body_bytes >= std::numeric_limits<size_t>::max())
    return unsupported(src + ": " + std::to_string(body_bytes) + " bytes do not fit in this build's memory");
  return body_bytes;
}

// The splats of a decompressed body; every value checked finite.
Expected<GaussianCloud> finish(const Header& h, const uint8_t* body, const std::string& src) {
  size_t offsets[kAttributeCount];
  attribute_offsets(h, offsets);
  const uint8_t* attributes[kAttributeCount];
  for (int a = 0; a < kAttributeCount; ++a) attributes[a] = body + offsets[a];
  GaussianCloud cloud = decode_attributes(h, attributes);
  GS_RETURN_IF_ERROR(detail::check_cloud_finite(cloud, src));
  return cloud;
}

#endif  // GS_HAVE_ZLIB || GS_HAVE_ZSTD

#if GS_HAVE_ZLIB

// A zlib inflate stream for a gzip member; ends itself.
class GzipReader {
 public:
  GzipReader(const uint8_t* data, size_t size) {
    stream_.next_in = const_cast<Bytef*>(data);
    stream_.avail_in = 0;
    remaining_in_ = size;
    ok_ = inflateInit2(&stream_, 16 + MAX_WBITS) == Z_OK;  // 16: gzip wrapper only
  }
  ~GzipReader() {
    if (ok_) inflateEnd(&stream_);
  }
  GzipReader(const GzipReader&) = delete;
  GzipReader& operator=(const GzipReader&) = delete;
  bool ok() const { return ok_; }
  bool ended() const { return ended_; }
  size_t unread_input() const { return remaining_in_ + stream_.avail_in; }

  // Inflates up to n bytes into out; *produced says how many came (fewer only at the stream's end).
  Status read(uint8_t* out, size_t n, size_t* produced, const std::string& src) {
    *produced = 0;
    while (*produced < n && !ended_) {
      if (stream_.avail_in == 0 && remaining_in_ > 0) {
        const size_t take = std::min<size_t>(remaining_in_, 1u << 30);
        stream_.avail_in = uInt(take);
        remaining_in_ -= take;
      }
      const size_t want = std::min<size_t>(n - *produced, 1u << 30);
      stream_.next_out = out + *produced;
      stream_.avail_out = uInt(want);
      const int rc = inflate(&stream_, Z_NO_FLUSH);
      *produced += want - stream_.avail_out;
      if (rc == Z_STREAM_END) {
        ended_ = true;
      } else if (rc == Z_BUF_ERROR && stream_.avail_in == 0 && remaining_in_ == 0) {
        return parse_error(src + ": the gzip stream is truncated (it ends before its end marker and checksum)");
      } else if (rc == Z_DATA_ERROR || rc == Z_NEED_DICT) {
        return parse_error(src + ": corrupt gzip data (zlib: " + (stream_.msg ? stream_.msg : "data error") + ")");
      } else if (rc == Z_MEM_ERROR) {
        return Status(StatusCode::kInternal, src + ": out of memory while inflating");
      } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
        return Status(StatusCode::kInternal, src + ": zlib inflate failed with code " + std::to_string(rc));
      }
    }
    return Status::Ok();
  }

 private:
  z_stream stream_{};
  size_t remaining_in_ = 0;
  bool ok_ = false;
  bool ended_ = false;
};

// Versions 2 and 3: one gzip stream.
Expected<GaussianCloud> parse_gzip(const uint8_t* data, size_t size, const std::string& src) {
  GzipReader gz(data, size);
  if (!gz.ok()) return Status(StatusCode::kInternal, src + ": zlib inflateInit2 failed");

  uint8_t head[kGzipHeaderBytes];
  size_t got = 0;
  GS_RETURN_IF_ERROR(gz.read(head, kGzipHeaderBytes, &got, src));
  if (got < kGzipHeaderBytes)
    return parse_error(src + ": the gzip stream holds " + std::to_string(got) + " bytes, less than the 16-byte .spz header");
  const uint32_t magic = detail::load_u32(head);
  if (magic != kSpzMagic)
    return parse_error(src + ": the gzip stream does not start with the .spz magic NGSP (0x5053474e); found " +
                       hex32(magic));
  Header h;
  h.version = detail::load_u32(head + 4);
  if (h.version == 4)
    return parse_error(src + ": a version-4 header inside a gzip stream (version 4 keeps its header in the clear)");
  if (h.version != 2 && h.version != 3) return unsupported(src + ": .spz " + version_hint(h.version));
  GS_RETURN_IF_ERROR(parse_common_fields(head + 8, src, &h));

  // Deflate expands a byte to at most 1032 (its best ratio, runs of one value), so a header whose
  // count needs more than that is refused before anything is allocated for it.
  Expected<uint64_t> declared = declared_body_bytes(h, 1032 * uint64_t(size) + 1024 - kGzipHeaderBytes, size, src);
  if (!declared.ok()) return declared.status();
  const uint64_t body_bytes = *declared;
  std::vector<uint8_t> body(size_t(body_bytes) + 1);  // + 1: a byte past the declared end means more data
  GS_RETURN_IF_ERROR(gz.read(body.data(), body.size(), &got, src));
  if (got < body_bytes)
    return parse_error(src + ": truncated: " + std::to_string(h.count) + " splats of " +
                       std::to_string(bytes_per_splat(h.version, h.sh_degree)) + " bytes need " +
                       std::to_string(body_bytes) + " bytes after the header, the gzip stream holds " + std::to_string(got));
  if (got > body_bytes)
    return parse_error(src + ": the gzip stream holds more than the " + std::to_string(body_bytes) + " bytes that " +
                       std::to_string(h.count) + " splats need (is the splat count wrong?)");
  if (!gz.ended()) {
    uint8_t probe = 0;  // reaching the end verifies gzip's CRC and length trailer
    GS_RETURN_IF_ERROR(gz.read(&probe, 1, &got, src));
    if (got != 0 || !gz.ended())
      return parse_error(src + ": the gzip stream holds more than the " + std::to_string(body_bytes) + " bytes that " +
                         std::to_string(h.count) + " splats need (is the splat count wrong?)");
  }
  if (gz.unread_input() != 0)
    return parse_error(src + ": " + std::to_string(gz.unread_input()) + " bytes follow the end of the gzip stream");
  return finish(h, body.data(), src);
}

Status gzip(const std::vector<uint8_t>& in, std::vector<uint8_t>* out) {
  z_stream s{};
  if (deflateInit2(&s, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    return Status(StatusCode::kInternal, ".spz: zlib deflateInit2 failed");
  out->resize(size_t(deflateBound(&s, uLong(std::min<size_t>(in.size(), 1u << 30)))) + 64);
  size_t in_pos = 0, out_pos = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (s.avail_in == 0 && in_pos < in.size()) {
      const size_t take = std::min<size_t>(in.size() - in_pos, 1u << 30);
      s.next_in = const_cast<Bytef*>(in.data() + in_pos);
      s.avail_in = uInt(take);
      in_pos += take;
    }
    if (out_pos == out->size()) out->resize(out->size() * 2);
    const size_t room = std::min<size_t>(out->size() - out_pos, 1u << 30);
    s.next_out = out->data() + out_pos;
    s.avail_out = uInt(room);
    rc = deflate(&s, in_pos == in.size() ? Z_FINISH : Z_NO_FLUSH);
    out_pos += room - s.avail_out;
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      deflateEnd(&s);
      return Status(StatusCode::kInternal, ".spz: zlib deflate failed with code " + std::to_string(rc));
    }
  }
  deflateEnd(&s);
  out->resize(out_pos);
  return Status::Ok();
}

#endif  // GS_HAVE_ZLIB

#if GS_HAVE_ZSTD

constexpr size_t kPlainHeaderBytes = 32;  // v4: in the clear
constexpr size_t kTocEntryBytes = 16;
const char* const kAttributeNames[kAttributeCount] = {"positions", "alphas", "colours", "scales", "rotations", "SH"};
// ZSTD level of the version-4 writer: Niantic's own, 12. On a 73k-splat SH-3 export of a trained
// model: level 3 0.3 % larger, level 19 0.7 % smaller at 3x the time (README "Splat file formats").
constexpr int kZstdLevel = 12;

// ZSTD's best ratio is far above deflate's (a 128 kB block of one byte value costs 4 bytes), so the
// bound on what a count may declare is Niantic's: at most 1024 bytes of attributes per file byte.
constexpr uint64_t kMaxZstdRatio = 1024;

// Version 4: a plain header, a table of contents and one ZSTD frame per non-empty attribute.
Expected<GaussianCloud> parse_zstd(const uint8_t* data, size_t size, const std::string& src) {
  if (size < kPlainHeaderBytes)
    return parse_error(src + ": " + std::to_string(size) + " bytes, less than the 32-byte version-4 .spz header");
  Header h;
  h.version = detail::load_u32(data + 4);
  if (h.version == 2 || h.version == 3)
    return parse_error(src + ": a version-" + std::to_string(h.version) +
                       " header in the clear (versions 2 and 3 are gzip streams, which start with 1f 8b)");
  if (h.version != 4) return unsupported(src + ": .spz " + version_hint(h.version));
  GS_RETURN_IF_ERROR(parse_common_fields(data + 8, src, &h));
  const size_t streams = data[15];
  const uint64_t toc_at = detail::load_u32(data + 16);

  size_t per[kAttributeCount];
  attribute_bytes_per_splat(h.version, h.sh_degree, per);
  int present[kAttributeCount];  // the attributes that have a stream, in file order
  size_t expected_streams = 0;
  for (int a = 0; a < kAttributeCount; ++a)
    if (per[a] > 0 && h.count > 0) present[expected_streams++] = a;
  if (streams != expected_streams)
    return parse_error(src + ": " + std::to_string(streams) + " streams, but " + std::to_string(h.count) +
                       " splats at SH degree " + std::to_string(h.sh_degree) + " have " + std::to_string(expected_streams) +
                       " non-empty attributes");
  if (toc_at < kPlainHeaderBytes || toc_at + streams * kTocEntryBytes > size)
    return parse_error(src + ": the table of contents (at byte " + std::to_string(toc_at) + ", " +
                       std::to_string(streams * kTocEntryBytes) + " bytes) is not inside the header's 32 bytes to the file's " +
                       std::to_string(size));

  Expected<uint64_t> declared = declared_body_bytes(h, kMaxZstdRatio * uint64_t(size), size, src);
  if (!declared.ok()) return declared.status();
  const uint64_t body_bytes = *declared;

  // The table: every size as the header implies, the frames exactly filling the rest of the file.
  uint64_t frame_at[kAttributeCount] = {}, frame_bytes[kAttributeCount] = {};
  uint64_t at = toc_at + streams * kTocEntryBytes;
  for (size_t s = 0; s < streams; ++s) {
    const int a = present[s];
    const uint8_t* entry = data + toc_at + s * kTocEntryBytes;
    const uint64_t compressed = detail::load_u64(entry), uncompressed = detail::load_u64(entry + 8);
    if (uncompressed != per[a] * uint64_t(h.count))
      return parse_error(src + ": stream " + std::to_string(s) + " (" + kAttributeNames[a] + ") declares " +
                         std::to_string(uncompressed) + " bytes, " + std::to_string(h.count) + " splats need " +
                         std::to_string(per[a] * uint64_t(h.count)));
    if (compressed > size - at)
      return parse_error(src + ": stream " + std::to_string(s) + " (" + kAttributeNames[a] + ", " +
                         std::to_string(compressed) + " compressed bytes at byte " + std::to_string(at) +
                         ") runs past the end of the file (" + std::to_string(size) + " bytes; truncated?)");
    frame_at[a] = at;
    frame_bytes[a] = compressed;
    at += compressed;
  }
  if (at != size)
    return parse_error(src + ": " + std::to_string(size - at) + " bytes follow the last stream");

  std::vector<uint8_t> body(static_cast<size_t>(body_bytes));
  size_t offsets[kAttributeCount];
  attribute_offsets(h, offsets);
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  if (dctx == nullptr) return Status(StatusCode::kInternal, src + ": ZSTD_createDCtx failed (out of memory?)");
  Status st = Status::Ok();
  for (size_t s = 0; s < streams && st.ok(); ++s) {
    const int a = present[s];
    const size_t want = per[a] * size_t(h.count);
    const size_t got = ZSTD_decompressDCtx(dctx, body.data() + offsets[a], want, data + frame_at[a], size_t(frame_bytes[a]));
    if (ZSTD_isError(got) && ZSTD_getErrorCode(got) == ZSTD_error_dstSize_tooSmall)
      st = parse_error(src + ": stream " + std::to_string(s) + " (" + kAttributeNames[a] +
                       ") decompresses to more than the " + std::to_string(want) + " bytes the table of contents says");
    else if (ZSTD_isError(got))
      st = parse_error(src + ": stream " + std::to_string(s) + " (" + kAttributeNames[a] + "): corrupt ZSTD data (zstd: " +
                       ZSTD_getErrorName(got) + ")");
    else if (got != want)
      st = parse_error(src + ": stream " + std::to_string(s) + " (" + kAttributeNames[a] + ") decompresses to " +
                       std::to_string(got) + " bytes, the table of contents says " + std::to_string(want));
  }
  ZSTD_freeDCtx(dctx);
  GS_RETURN_IF_ERROR(st);
  return finish(h, body.data(), src);
}

#endif  // GS_HAVE_ZSTD

Expected<GaussianCloud> parse_spz_unguarded(const uint8_t* data, size_t size, const std::string& src) {
  if (size >= 4 && detail::load_u32(data) == kSpzMagic) {  // version 4 keeps its header outside compression
#if GS_HAVE_ZSTD
    return parse_zstd(data, size, src);
#else
    return unsupported(src + ": .spz " + no_codec(4));
#endif
  }
  if (size < 2 || data[0] != 0x1f || data[1] != 0x8b)
    return parse_error(src + ": not a .spz file (versions 2 and 3 are gzip streams, which start with 1f 8b; "
                             "version 4 starts with NGSP)");
#if GS_HAVE_ZLIB
  return parse_gzip(data, size, src);
#else
  return unsupported(src + ": .spz " + no_codec(3));
#endif
}

#if GS_HAVE_ZLIB || GS_HAVE_ZSTD

// Fractional bits for positions: the most that keep every coordinate inside the signed 24-bit range.
Expected<int> choose_fractional_bits(const GaussianCloud& cloud) {
  double largest = 0;
  for (float v : cloud.means) largest = std::max(largest, std::fabs(double(v)));
  const double limit = double((1 << 23) - 1);
  for (int bits = 23; bits >= 0; --bits)
    if (std::ldexp(largest, bits) <= limit - 0.5) return bits;
  return invalid_argument(".spz: coordinate " + std::to_string(largest) +
                          " is outside the +-8388606 a 24-bit fixed-point position holds");
}

// The attributes of every splat, one after the other in file order, into body (bytes_per_splat x n).
void encode_attributes(const GaussianCloud& cloud, const SpzWriteOptions& o, uint32_t version, int fractional_bits,
                       uint8_t* body) {
  const size_t n = cloud.size(), K = size_t(sh_coeff_count(cloud.sh_degree));
  Header h;
  h.version = version;
  h.count = uint32_t(n);
  h.sh_degree = cloud.sh_degree;
  size_t offsets[kAttributeCount];
  attribute_offsets(h, offsets);
  uint8_t* positions = body + offsets[kPositions];
  uint8_t* alphas = body + offsets[kAlphas];
  uint8_t* colours = body + offsets[kColours];
  uint8_t* scales = body + offsets[kScales];
  uint8_t* rotations = body + offsets[kRotations];
  uint8_t* sh = body + offsets[kSh];
  for (size_t i = 0; i < 3 * n; ++i) {
    const double v = std::ldexp(double(cloud.means[i]) * kAxisSignRdfRub[i % 3], fractional_bits);
    const uint32_t fixed = uint32_t(int32_t(std::lround(v)));
    for (int b = 0; b < 3; ++b) positions[3 * i + size_t(b)] = uint8_t(fixed >> (8 * b));
    colours[i] = uint8_t(detail::quantize_clamped(cloud.sh[(i / 3) * K * 3 + i % 3] * (kColourScale * 255.0) + 127.5, 255));
    scales[i] = uint8_t(detail::quantize_clamped((double(cloud.log_scales[i]) + 10.0) * 16.0, 255));
  }
  const uint32_t bucket1 = 1u << (8 - o.sh1_bits), bucket_rest = 1u << (8 - o.sh_rest_bits);
  for (size_t i = 0; i < n; ++i) {
    alphas[i] = uint8_t(detail::quantize_clamped(detail::sigmoid(cloud.opacity_logits[i]) * 255.0, 255));
    double q[4];
    detail::normalized_quaternion(&cloud.quats[4 * i], q);  // non-zero: checked above
    double xyzw[4] = {q[1] * kAxisSignRdfRub[0], q[2] * kAxisSignRdfRub[1], q[3] * kAxisSignRdfRub[2], q[0]};
    if (version >= 3) {
      int largest = 0;
      for (int k = 1; k < 4; ++k)
        if (std::fabs(xyzw[k]) > std::fabs(xyzw[largest])) largest = k;
      const bool negate = xyzw[largest] < 0;  // -q is the same rotation: make the left-out one positive
      uint32_t comp = uint32_t(largest);
      for (int k = 0; k < 4; ++k) {
        if (k == largest) continue;
        const double v = negate ? -xyzw[k] : xyzw[k];
        const uint32_t magnitude = detail::quantize_clamped(std::fabs(v) / kSqrtHalf * 511.0, 511);
        comp = (comp << 10) | (uint32_t(v < 0) << 9) | magnitude;
      }
      put_u32(rotations + 4 * i, comp);
    } else {
      const double sign = xyzw[3] < 0 ? -1.0 : 1.0;  // w >= 0 is implied by the format
      for (int k = 0; k < 3; ++k)
        rotations[3 * i + size_t(k)] = uint8_t(detail::quantize_clamped((sign * xyzw[k] + 1.0) * 127.5, 255));
    }
    for (size_t k = 1; k < K; ++k) {
      const double bucket = double(k < 4 ? bucket1 : bucket_rest);
      for (size_t ch = 0; ch < 3; ++ch) {
        const double v = double(cloud.sh[(i * K + k) * 3 + ch]) * kShSignRdfRub[k - 1];
        sh[(i * (K - 1) + (k - 1)) * 3 + ch] =
            uint8_t(detail::quantize_clamped(std::round(v * 128.0 / bucket) * bucket + 128.0, 255));
      }
    }
  }
}

// The header fields after version both layouts share: numPoints, shDegree, fractionalBits, flags.
void put_common_fields(uint8_t* at, const GaussianCloud& cloud, int fractional_bits) {
  put_u32(at, uint32_t(cloud.size()));
  at[4] = uint8_t(cloud.sh_degree);
  at[5] = uint8_t(fractional_bits);
  at[6] = 0;  // flags: not antialiased, no extensions
}

#endif  // GS_HAVE_ZLIB || GS_HAVE_ZSTD

#if GS_HAVE_ZSTD
// Version 4: header, table of contents, then each non-empty attribute as its own ZSTD frame.
Status zstd_streams(const GaussianCloud& cloud, int fractional_bits, const std::vector<uint8_t>& body,
                    std::vector<uint8_t>* out) {
  size_t per[kAttributeCount];
  attribute_bytes_per_splat(4, cloud.sh_degree, per);
  const size_t n = cloud.size();
  size_t streams = 0;
  for (size_t b : per) streams += b > 0 && n > 0;
  out->assign(kPlainHeaderBytes + streams * kTocEntryBytes, 0);
  put_u32(out->data(), kSpzMagic);
  put_u32(out->data() + 4, 4);
  put_common_fields(out->data() + 8, cloud, fractional_bits);
  (*out)[15] = uint8_t(streams);
  put_u32(out->data() + 16, uint32_t(kPlainHeaderBytes));  // no extension records: the table follows
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  if (cctx == nullptr) return Status(StatusCode::kInternal, ".spz: ZSTD_createCCtx failed (out of memory?)");
  size_t offset = 0, entry = kPlainHeaderBytes;
  Status st = Status::Ok();
  for (int a = 0; a < kAttributeCount && st.ok(); ++a) {
    const size_t bytes = per[a] * n;
    if (bytes == 0) continue;
    const size_t at = out->size();
    out->resize(at + ZSTD_compressBound(bytes));
    const size_t packed = ZSTD_compressCCtx(cctx, out->data() + at, out->size() - at, body.data() + offset, bytes, kZstdLevel);
    if (ZSTD_isError(packed)) {
      st = Status(StatusCode::kInternal, std::string(".spz: ZSTD compression of the ") + kAttributeNames[a] +
                                             " failed: " + ZSTD_getErrorName(packed));
      break;
    }
    out->resize(at + packed);
    for (int b = 0; b < 8; ++b) {
      (*out)[entry + size_t(b)] = uint8_t(uint64_t(packed) >> (8 * b));
      (*out)[entry + 8 + size_t(b)] = uint8_t(uint64_t(bytes) >> (8 * b));
    }
    entry += kTocEntryBytes;
    offset += bytes;
  }
  ZSTD_freeCCtx(cctx);
  return st;
}
#endif  // GS_HAVE_ZSTD

Expected<std::vector<uint8_t>> encode(const GaussianCloud& cloud, const SpzWriteOptions& o) {
  if (o.version < 2 || o.version > 4)
    return invalid_argument(".spz: cannot write version " + std::to_string(o.version) + " (2, 3 or 4)");
  if (!spz_version_supported(o.version)) return unsupported(".spz: " + no_codec(o.version));
#if GS_HAVE_ZLIB || GS_HAVE_ZSTD
  GS_RETURN_IF_ERROR(detail::check_cloud_for_writing(cloud, ".spz"));
  if (o.sh1_bits < 1 || o.sh1_bits > 8 || o.sh_rest_bits < 1 || o.sh_rest_bits > 8)
    return invalid_argument(".spz: SH bits must be 1 to 8 (sh1_bits " + std::to_string(o.sh1_bits) + ", sh_rest_bits " +
                            std::to_string(o.sh_rest_bits) + ")");
  Expected<int> fractional_bits = choose_fractional_bits(cloud);
  if (!fractional_bits.ok()) return fractional_bits.status();
  const uint32_t version = uint32_t(o.version);
  std::vector<uint8_t> out;
  if (version == 4) {
#if GS_HAVE_ZSTD
    std::vector<uint8_t> body(cloud.size() * bytes_per_splat(version, cloud.sh_degree));
    encode_attributes(cloud, o, version, *fractional_bits, body.data());
    GS_RETURN_IF_ERROR(zstd_streams(cloud, *fractional_bits, body, &out));
#endif
  } else {
#if GS_HAVE_ZLIB
    std::vector<uint8_t> raw(kGzipHeaderBytes + cloud.size() * bytes_per_splat(version, cloud.sh_degree));
    put_u32(raw.data(), kSpzMagic);
    put_u32(raw.data() + 4, version);
    put_common_fields(raw.data() + 8, cloud, *fractional_bits);
    raw[15] = 0;  // reserved
    encode_attributes(cloud, o, version, *fractional_bits, raw.data() + kGzipHeaderBytes);
    GS_RETURN_IF_ERROR(gzip(raw, &out));
#endif
  }
  return out;
#else
  (void)cloud;
  return unsupported(".spz: " + no_codec(o.version));
#endif
}

}  // namespace

bool spz_version_supported(int version) {
  if (version == 2 || version == 3) return GS_HAVE_ZLIB != 0;
  if (version == 4) return GS_HAVE_ZSTD != 0;
  return false;
}

bool spz_supported() { return spz_version_supported(2) && spz_version_supported(3) && spz_version_supported(4); }

Expected<GaussianCloud> parse_spz(const uint8_t* data, size_t size, const std::string& source) {
  return detail::guarded(source, [&]() { return parse_spz_unguarded(data, size, source); });
}

Expected<GaussianCloud> read_spz(const std::string& path) {
  return detail::read_and_parse(path, parse_spz);
}

Expected<std::vector<uint8_t>> encode_spz(const GaussianCloud& cloud, const SpzWriteOptions& options) {
  return detail::guarded(".spz", [&]() { return encode(cloud, options); });
}

Status write_spz(const std::string& path, const GaussianCloud& cloud, const SpzWriteOptions& options) {
  Expected<std::vector<uint8_t>> bytes = encode_spz(cloud, options);
  if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
  return platform::write_file_atomic(path, bytes->data(), bytes->size());
}

}  // namespace gs::io
