// SPDX-License-Identifier: MIT
// The one entry point over every splat file format (gs/io/splat_formats.h): reading picks the
// format from the content where it has a magic number and from the name otherwise; writing picks
// it from the name.
#include <algorithm>
#include <cctype>

#include "../io_util.h"
#include "gs/io/ply.h"
#include "gs/io/splat_formats.h"
#include "gs/platform/file.h"
#include "splat_common.h"

namespace gs::io {
namespace {

std::string lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool starts_with(const uint8_t* data, size_t size, const char* magic, size_t magic_size) {
  return size >= magic_size && std::equal(magic, magic + magic_size, reinterpret_cast<const char*>(data));
}

Status unrecognised(const std::string& source) {
  return unsupported(source + ": not a Gaussian splat file hbgs reads (no PLY or gzip header, and the name does not "
                              "end in .splat); supported: " +
                     std::string(supported_splat_extensions()));
}

}  // namespace

const char* splat_format_name(SplatFormat format) {
  switch (format) {
    case SplatFormat::kPly: return "3DGS PLY";
    case SplatFormat::kCompressedPly: return "compressed.ply";
    case SplatFormat::kAntimatterSplat: return ".splat";
    case SplatFormat::kSpz: return ".spz";
  }
  return "?";
}

const char* supported_splat_extensions() {
  return ".ply (3DGS), .compressed.ply (PlayCanvas), .splat (antimatter15), .spz (Niantic, versions 2 to 4)";
}

Expected<SplatFormat> splat_format_from_extension(const std::string& path) {
  const std::string name = lowercase(path);
  if (ends_with(name, ".compressed.ply")) return SplatFormat::kCompressedPly;
  if (ends_with(name, ".ply")) return SplatFormat::kPly;
  if (ends_with(name, ".splat")) return SplatFormat::kAntimatterSplat;
  if (ends_with(name, ".spz")) return SplatFormat::kSpz;
  return invalid_argument(path + ": unknown splat file extension; supported: " + std::string(supported_splat_extensions()));
}

Expected<GaussianCloud> parse_gaussians(const uint8_t* data, size_t size, const std::string& source, SplatFormat* format) {
  const std::string name = lowercase(source);
  SplatFormat f;
  if (starts_with(data, size, "ply\n", 4) || starts_with(data, size, "ply\r\n", 5)) {
    f = is_compressed_ply(data, size) ? SplatFormat::kCompressedPly : SplatFormat::kPly;
  } else if (ends_with(name, ".splat")) {
    f = SplatFormat::kAntimatterSplat;  // no magic number: a record starts with a float
  } else if (starts_with(data, size, "\x1f\x8b", 2) || starts_with(data, size, "NGSP", 4) || ends_with(name, ".spz")) {
    f = SplatFormat::kSpz;
  } else if (ends_with(name, ".ply")) {
    f = SplatFormat::kPly;  // its reader says what is wrong with the header
  } else {
    return unrecognised(source);
  }
  if (format) *format = f;
  switch (f) {
    case SplatFormat::kPly: return parse_splat_ply(data, size, source);
    case SplatFormat::kCompressedPly: return parse_compressed_ply(data, size, source);
    case SplatFormat::kAntimatterSplat: return parse_antimatter_splat(data, size, source);
    case SplatFormat::kSpz: return parse_spz(data, size, source);
  }
  return unrecognised(source);
}

Expected<GaussianCloud> read_gaussians(const std::string& path, SplatFormat* format) {
  return detail::read_and_parse(path, [&](const uint8_t* data, size_t size, const std::string& source) {
    return parse_gaussians(data, size, source, format);
  });
}

Expected<std::vector<uint8_t>> encode_gaussians(const GaussianCloud& cloud, SplatFormat format,
                                                const SplatWriteOptions& options) {
  switch (format) {
    case SplatFormat::kPly: {
      GS_RETURN_IF_ERROR(detail::check_cloud_for_writing(cloud, "3DGS PLY"));
      std::vector<uint8_t> bytes = encode_splat_ply(cloud);
      if (bytes.empty()) return Status(StatusCode::kInternal, "3DGS PLY: encoding failed (out of memory?)");
      return bytes;
    }
    case SplatFormat::kCompressedPly: return encode_compressed_ply(cloud);
    case SplatFormat::kAntimatterSplat: return encode_antimatter_splat(cloud);
    case SplatFormat::kSpz: return encode_spz(cloud, options.spz);
  }
  return invalid_argument("unknown splat format");
}

Status write_gaussians(const std::string& path, const GaussianCloud& cloud, const SplatWriteOptions& options) {
  Expected<SplatFormat> format = splat_format_from_extension(path);
  if (!format.ok()) return format.status();
  Expected<std::vector<uint8_t>> bytes = encode_gaussians(cloud, *format, options);
  if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
  return platform::write_file_atomic(path, bytes->data(), bytes->size());
}

}  // namespace gs::io
