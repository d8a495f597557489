// SPDX-License-Identifier: MIT
// antimatter15's .splat (the format of the WebGL viewer antimatter15/splat and many web viewers):
// a headerless array of 32-byte little-endian records, read and written (gs/io/splat_formats.h).
//   bytes  0-11  position x, y, z      float32
//   bytes 12-23  scale x, y, z         float32, linear (exp of the log scale)
//   bytes 24-27  red, green, blue, alpha  uint8: colour 0.5 + SH_C0 * dc, alpha sigmoid(logit)
//   bytes 28-31  rotation w, x, y, z   uint8: normalised quaternion as q * 128 + 128
#include <cmath>
#include <cstring>

#include "../io_util.h"
#include "gs/io/splat_formats.h"
#include "gs/platform/file.h"
#include "splat_common.h"

namespace gs::io {
namespace {

constexpr size_t kRecordBytes = 32;

Expected<GaussianCloud> parse_antimatter_unguarded(const uint8_t* data, size_t size, const std::string& src) {
  if (size == 0) return parse_error(src + ": empty file (a .splat holds 32 bytes per splat)");
  if (size % kRecordBytes != 0)
    return parse_error(src + ": " + std::to_string(size) + " bytes is not a whole number of 32-byte .splat records (" +
                       std::to_string(size / kRecordBytes) + " records and " + std::to_string(size % kRecordBytes) +
                       " bytes over: truncated?)");
  const uint64_t n = size / kRecordBytes;
  if (n > detail::kMaxSplats)
    return unsupported(src + ": " + std::to_string(n) + " splats, more than the " + std::to_string(detail::kMaxSplats) +
                       " allowed");
  GaussianCloud cloud;
  cloud.sh_degree = 0;
  cloud.resize(size_t(n));
  for (size_t i = 0; i < size_t(n); ++i) {
    const uint8_t* r = data + i * kRecordBytes;
    const std::string at = src + ": record " + std::to_string(i) + " (byte " + std::to_string(i * kRecordBytes) + "): ";
    for (int c = 0; c < 3; ++c) {
      const float p = detail::load_f32(r + 4 * c);
      const float s = detail::load_f32(r + 12 + 4 * c);
      if (!std::isfinite(p)) return parse_error(at + "position " + std::to_string(c) + " is " + std::to_string(p));
      if (!(s > 0) || !std::isfinite(s))
        return parse_error(at + "scale " + std::to_string(c) + " is " + std::to_string(s) +
                           " (expected a positive finite standard deviation)");
      cloud.means[3 * i + size_t(c)] = p;
      cloud.log_scales[3 * i + size_t(c)] = std::log(s);
      cloud.sh[3 * i + size_t(c)] = float((double(r[24 + c]) / 255.0 - 0.5) / detail::kShC0);
    }
    cloud.opacity_logits[i] = detail::logit_from_alpha8(r[27]);
    // 128 is zero; a record of four 128s has no rotation: identity, as the viewers draw it.
    double q[4];
    float raw[4];
    for (int c = 0; c < 4; ++c) raw[c] = (float(r[28 + c]) - 128.0f) / 128.0f;
    detail::normalized_quaternion(raw, q);
    for (int c = 0; c < 4; ++c) cloud.quats[4 * i + size_t(c)] = float(q[c]);
  }
  return cloud;
}

}  // namespace

Expected<GaussianCloud> parse_antimatter_splat(const uint8_t* data, size_t size, const std::string& source) {
  return detail::guarded(source, [&]() { return parse_antimatter_unguarded(data, size, source); });
}

Expected<GaussianCloud> read_antimatter_splat(const std::string& path) {
  return detail::read_and_parse(path, parse_antimatter_unguarded);
}

Expected<std::vector<uint8_t>> encode_antimatter_splat(const GaussianCloud& cloud) {
  GS_RETURN_IF_ERROR(detail::check_cloud_for_writing(cloud, ".splat"));
  if (cloud.size() == 0) return invalid_argument(".splat: no splats to write (an empty .splat is not readable)");
  return detail::guarded(".splat", [&]() -> Expected<std::vector<uint8_t>> {
    const size_t n = cloud.size(), K = size_t(sh_coeff_count(cloud.sh_degree));
    std::vector<uint8_t> out;
    out.reserve(n * kRecordBytes);
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) detail::append_f32(out, cloud.means[3 * i + size_t(c)]);
      for (int c = 0; c < 3; ++c) {
        const float log_scale = cloud.log_scales[3 * i + size_t(c)];
        const float scale = std::exp(log_scale);
        if (!(scale > 0) || !std::isfinite(scale))
          return invalid_argument(".splat: splat " + std::to_string(i) + ": log scale " + std::to_string(log_scale) +
                                  " is outside what a float32 scale holds (about -103 to 88)");
        detail::append_f32(out, scale);
      }
      for (size_t c = 0; c < 3; ++c)
        out.push_back(uint8_t(detail::quantize_clamped((0.5 + detail::kShC0 * cloud.sh[i * K * 3 + c]) * 255.0, 255)));
      out.push_back(uint8_t(detail::quantize_clamped(detail::sigmoid(cloud.opacity_logits[i]) * 255.0, 255)));
      double q[4];
      detail::normalized_quaternion(&cloud.quats[4 * i], q);  // non-zero: checked above
      for (int c = 0; c < 4; ++c) out.push_back(uint8_t(detail::quantize_clamped(q[c] * 128.0 + 128.0, 255)));
    }
    return out;
  });
}

Status write_antimatter_splat(const std::string& path, const GaussianCloud& cloud) {
  Expected<std::vector<uint8_t>> bytes = encode_antimatter_splat(cloud);
  if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
  return platform::write_file_atomic(path, bytes->data(), bytes->size());
}

}  // namespace gs::io
