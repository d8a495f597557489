// SPDX-License-Identifier: MIT
// Niantic's .spz, versions 2 and 3 (gs/io/splat_formats.h): one gzip stream holding a 16-byte
// header and the splats attribute by attribute. Written from the format description in
// nianticlabs/spz's README (all little-endian):
//   header     magic 0x5053474e ("NGSP"), version, numPoints (uint32); shDegree, fractionalBits,
//              flags (0x1 antialiased, 0x2 vendor extensions follow), reserved (uint8)
//   positions  3 x 24-bit two's complement fixed point, value = integer / 2^fractionalBits
//   alphas     uint8 sigmoid(logit) * 255
//   colours    uint8 dc * 0.15 * 255 + 127.5 (0.15 instead of SH_C0 leaves room outside [0, 1])
//   scales     uint8 (log scale + 10) * 16
//   rotations  v3: uint32, bits 30-31 the index (in x, y, z, w order) of the largest-magnitude
//              component of the unit quaternion, made positive and left out; then the other three
//              in index order, most significant first, 10 bits each (sign, 9-bit magnitude of
//              |c| * sqrt(2)); v2: uint8 x, y, z as (q + 1) * 127.5 with w >= 0 implied
//   sh         uint8 (c * 128 + 128) per coefficient (degree 1 first) and colour (inner), rounded
//              to a multiple of 2^(8 - bits) so gzip finds the repeated low bits
// The file's frame is RUB (y up, z backward); hbgs's is RDF, so y and z flip on the way in and out.
// Version 4 (ZSTD streams) and the vendor extension records are refused with a message.
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
#if GS_HAVE_ZLIB
#include <zlib.h>
#endif

namespace gs::io {
namespace {

#if GS_HAVE_ZLIB

constexpr uint32_t kSpzMagic = 0x5053474e;  // "NGSP" as a little-endian uint32
constexpr size_t kHeaderBytes = 16;
constexpr uint8_t kFlagExtensions = 0x2;  // 0x1 (trained antialiased) changes nothing hbgs reads
constexpr float kColourScale = 0.15f;          // the format's DC colour scale
constexpr double kSqrtHalf = 0.70710678118654752440;

// Sign of each SH coefficient k = 1..15 (index k - 1) under the frame change (x, y, z) -> (x, -y, -z)
// between RDF and RUB: the real SH basis functions of 3DGS that are odd in y*z-parity flip
// (degree 1: y, z, x; degree 2: xy, yz, 3zz-1, xz, xx-yy; degree 3: y(3xx-yy), xyz, y(5zz-1),
// z(5zz-3), x(5zz-1), z(xx-yy), x(xx-3yy)).
constexpr float kShSignRdfRub[15] = {-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1};
// Position and quaternion-vector signs under the same frame change.
constexpr float kAxisSignRdfRub[3] = {1, -1, -1};

size_t rotation_bytes(uint32_t version) { return version >= 3 ? 4 : 3; }

// Bytes per splat after the header: position 9, alpha 1, colour 3, scale 3, rotation, SH.
size_t bytes_per_splat(uint32_t version, int sh_degree) {
  return 9 + 1 + 3 + 3 + rotation_bytes(version) + size_t(sh_coeff_count(sh_degree) - 1) * 3;
}

std::string version_hint(uint32_t version) {
  if (version == 4)
    return "version 4 (ZSTD streams, written by default by recent Niantic and PlayCanvas tools) is not read by hbgs; "
           "convert it to version 3 (for example splat-transform --spz-version 3)";
  if (version == 1) return "version 1 (float16 positions, never released) is not supported";
  return "unknown version " + std::to_string(version) + " (hbgs reads versions 2 and 3)";
}

std::string hex32(uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", v);
  return text;
}

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

struct Header {
  uint32_t version = 0, count = 0;
  int sh_degree = 0, fractional_bits = 0;
  uint8_t flags = 0;
};

Status parse_header(const uint8_t* h, const std::string& src, Header* out) {
  const uint32_t magic = detail::load_u32(h);
  if (magic != kSpzMagic)
    return parse_error(src + ": the gzip stream does not start with the .spz magic NGSP (0x5053474e); found " +
                       hex32(magic));
  out->version = detail::load_u32(h + 4);
  if (out->version != 2 && out->version != 3) return unsupported(src + ": .spz " + version_hint(out->version));
  out->count = detail::load_u32(h + 8);
  if (out->count > detail::kMaxSplats)
    return unsupported(src + ": header declares " + std::to_string(out->count) + " splats, more than the " +
                       std::to_string(detail::kMaxSplats) + " allowed");
  out->sh_degree = h[12];
  if (out->sh_degree == 4) return unsupported(src + ": SH degree 4 (hbgs renders degrees 0 to 3)");
  if (out->sh_degree > 4) return parse_error(src + ": SH degree " + std::to_string(out->sh_degree) + " (expected 0 to 4)");
  out->fractional_bits = h[13];
  if (out->fractional_bits > 31)
    return parse_error(src + ": " + std::to_string(out->fractional_bits) + " fractional bits (expected at most 31)");
  out->flags = h[14];
  if (out->flags & kFlagExtensions)
    return unsupported(src + ": the file carries vendor extension records (flag 0x2), which can change how the "
                             "splats decode; hbgs does not read them");
  return Status::Ok();
}

// The splats of a decompressed body (positions .. SH) of a header-described file.
GaussianCloud decode_body(const Header& h, const uint8_t* body) {
  const size_t n = h.count, K = size_t(sh_coeff_count(h.sh_degree));
  GaussianCloud c;
  c.sh_degree = h.sh_degree;
  c.resize(n);
  const uint8_t* positions = body;
  const uint8_t* alphas = positions + 9 * n;
  const uint8_t* colours = alphas + n;
  const uint8_t* scales = colours + 3 * n;
  const uint8_t* rotations = scales + 3 * n;
  const uint8_t* sh = rotations + rotation_bytes(h.version) * n;
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

Expected<GaussianCloud> parse(const uint8_t* data, size_t size, const std::string& src) {
  if (size >= 8 && detail::load_u32(data) == kSpzMagic)  // version 4 keeps its header outside compression
    return unsupported(src + ": .spz " + version_hint(detail::load_u32(data + 4)));
  if (size < 2 || data[0] != 0x1f || data[1] != 0x8b)
    return parse_error(src + ": not a .spz file (versions 2 and 3 are gzip streams, which start with 1f 8b)");
  GzipReader gz(data, size);
  if (!gz.ok()) return Status(StatusCode::kInternal, src + ": zlib inflateInit2 failed");

  uint8_t head[kHeaderBytes];
  size_t got = 0;
  GS_RETURN_IF_ERROR(gz.read(head, kHeaderBytes, &got, src));
  if (got < kHeaderBytes)
    return parse_error(src + ": the gzip stream holds " + std::to_string(got) + " bytes, less than the 16-byte .spz header");
  Header h;
  GS_RETURN_IF_ERROR(parse_header(head, src, &h));

  // Deflate expands a byte to at most 1032 (its best ratio, runs of one value), so a header whose
  // count needs more than that is refused before anything is allocated for it (a gzip bomb, or a
  // corrupt count).
  const uint64_t body_bytes = uint64_t(h.count) * bytes_per_splat(h.version, h.sh_degree);
  if (body_bytes + kHeaderBytes > 1032 * uint64_t(size) + 1024)
    return parse_error(src + ": the header declares " + std::to_string(h.count) + " splats (" +
                       std::to_string(body_bytes) + " bytes), more than " + std::to_string(size) +
                       " compressed bytes can hold (truncated file or corrupt count)");
  GS_RETURN_IF_ERROR(detail::check_cloud_fits(h.count, h.sh_degree, src));
  if (body_bytes >= std::numeric_limits<size_t>::max())
    return unsupported(src + ": " + std::to_string(body_bytes) + " bytes do not fit in this build's memory");
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
  GaussianCloud cloud = decode_body(h, body.data());
  GS_RETURN_IF_ERROR(detail::check_cloud_finite(cloud, src));
  return cloud;
}

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

Expected<std::vector<uint8_t>> encode(const GaussianCloud& cloud, const SpzWriteOptions& o) {
  GS_RETURN_IF_ERROR(detail::check_cloud_for_writing(cloud, ".spz"));
  if (o.version != 2 && o.version != 3)
    return invalid_argument(".spz: cannot write version " + std::to_string(o.version) + " (2 or 3)");
  if (o.sh1_bits < 1 || o.sh1_bits > 8 || o.sh_rest_bits < 1 || o.sh_rest_bits > 8)
    return invalid_argument(".spz: SH bits must be 1 to 8 (sh1_bits " + std::to_string(o.sh1_bits) + ", sh_rest_bits " +
                            std::to_string(o.sh_rest_bits) + ")");
  Expected<int> fractional_bits = choose_fractional_bits(cloud);
  if (!fractional_bits.ok()) return fractional_bits.status();
  const uint32_t version = uint32_t(o.version);
  const size_t n = cloud.size(), K = size_t(sh_coeff_count(cloud.sh_degree));
  const size_t body_bytes = n * bytes_per_splat(version, cloud.sh_degree);
  std::vector<uint8_t> raw(kHeaderBytes + body_bytes);
  uint8_t* p = raw.data();
  auto put_u32 = [](uint8_t* at, uint32_t v) {
    for (int b = 0; b < 4; ++b) at[b] = uint8_t(v >> (8 * b));
  };
  put_u32(p, kSpzMagic);
  put_u32(p + 4, version);
  put_u32(p + 8, uint32_t(n));
  p[12] = uint8_t(cloud.sh_degree);
  p[13] = uint8_t(*fractional_bits);
  p[14] = 0;  // flags: not antialiased, no extensions
  p[15] = 0;
  uint8_t* positions = p + kHeaderBytes;
  uint8_t* alphas = positions + 9 * n;
  uint8_t* colours = alphas + n;
  uint8_t* scales = colours + 3 * n;
  uint8_t* rotations = scales + 3 * n;
  uint8_t* sh = rotations + rotation_bytes(version) * n;
  for (size_t i = 0; i < 3 * n; ++i) {
    const double v = std::ldexp(double(cloud.means[i]) * kAxisSignRdfRub[i % 3], *fractional_bits);
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
  std::vector<uint8_t> out;
  GS_RETURN_IF_ERROR(gzip(raw, &out));
  return out;
}

#else

Status no_zlib(const std::string& what) {
  return unsupported(what + ": this build of hbgs has no zlib, so it cannot read or write .spz (gzip) files");
}

#endif  // GS_HAVE_ZLIB

}  // namespace

bool spz_supported() { return GS_HAVE_ZLIB != 0; }

Expected<GaussianCloud> parse_spz(const uint8_t* data, size_t size, const std::string& source) {
#if GS_HAVE_ZLIB
  return detail::guarded(source, [&]() { return parse(data, size, source); });
#else
  (void)data, (void)size;
  return no_zlib(source);
#endif
}

Expected<GaussianCloud> read_spz(const std::string& path) {
  return detail::read_and_parse(path, parse_spz);
}

Expected<std::vector<uint8_t>> encode_spz(const GaussianCloud& cloud, const SpzWriteOptions& options) {
#if GS_HAVE_ZLIB
  return detail::guarded(".spz", [&]() { return encode(cloud, options); });
#else
  (void)cloud, (void)options;
  return no_zlib(".spz");
#endif
}

Status write_spz(const std::string& path, const GaussianCloud& cloud, const SpzWriteOptions& options) {
  Expected<std::vector<uint8_t>> bytes = encode_spz(cloud, options);
  if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
  return platform::write_file_atomic(path, bytes->data(), bytes->size());
}

}  // namespace gs::io
