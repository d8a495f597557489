// SPDX-License-Identifier: MIT
// Pixel-format names, V4L2 fourcc codes and frame-view validation.
#include "gs/capture/frame.h"

#include <cctype>

namespace gs::capture {
namespace {

constexpr uint32_t make_fourcc(char a, char b, char c, char d) {
  return uint32_t(uint8_t(a)) | (uint32_t(uint8_t(b)) << 8) | (uint32_t(uint8_t(c)) << 16) | (uint32_t(uint8_t(d)) << 24);
}

struct FormatInfo {
  PixelFormat format;
  const char* name;
  uint32_t fourcc;  // the same codes as V4L2_PIX_FMT_* in linux/videodev2.h
};
constexpr FormatInfo kFormats[] = {
    {PixelFormat::kRGB24, "rgb24", make_fourcc('R', 'G', 'B', '3')},
    {PixelFormat::kYUYV, "yuyv", make_fourcc('Y', 'U', 'Y', 'V')},
    {PixelFormat::kNV12, "nv12", make_fourcc('N', 'V', '1', '2')},
    {PixelFormat::kMJPEG, "mjpeg", make_fourcc('M', 'J', 'P', 'G')},
};

const FormatInfo& info(PixelFormat f) {
  for (const FormatInfo& i : kFormats)
    if (i.format == f) return i;
  return kFormats[0];
}

Status check_plane(const FrameView& f, int index, int64_t min_stride, int64_t rows) {
  const FramePlane& p = f.planes[index];
  const std::string where = std::string(pixel_format_name(f.format)) + " frame " + std::to_string(f.width) + "x" +
                            std::to_string(f.height) + ", plane " + std::to_string(index);
  if (p.data == nullptr) return invalid_argument(where + ": no data");
  if (p.stride < min_stride)
    return invalid_argument(where + ": stride " + std::to_string(p.stride) + " bytes is less than the " +
                            std::to_string(min_stride) + " a row needs");
  const uint64_t need = uint64_t(rows - 1) * uint64_t(p.stride) + uint64_t(min_stride);
  if (p.size < need)
    return invalid_argument(where + ": " + std::to_string(p.size) + " bytes, needs at least " + std::to_string(need));
  return Status::Ok();
}

}  // namespace

const char* pixel_format_name(PixelFormat format) { return info(format).name; }
uint32_t pixel_format_fourcc(PixelFormat format) { return info(format).fourcc; }

Expected<PixelFormat> parse_pixel_format(const std::string& name) {
  std::string lower;
  for (char c : name) lower += char(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "mjpg") lower = "mjpeg";
  for (const FormatInfo& i : kFormats)
    if (lower == i.name) return i.format;
  return invalid_argument("unknown pixel format '" + name + "' (known: rgb24, yuyv, nv12, mjpeg)");
}

bool pixel_format_from_fourcc(uint32_t fourcc, PixelFormat* out) {
  for (const FormatInfo& i : kFormats)
    if (i.fourcc == fourcc) {
      *out = i.format;
      return true;
    }
  return false;
}

std::string fourcc_text(uint32_t fourcc) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = char((fourcc >> (8 * i)) & 0xff);
    s += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return s;
}

Status validate_frame(const FrameView& f) {
  if (f.width <= 0 || f.height <= 0)
    return invalid_argument("frame size " + std::to_string(f.width) + "x" + std::to_string(f.height) + " is empty");
  const int64_t w = f.width, h = f.height, cw = (w + 1) / 2, ch = (h + 1) / 2;
  const int expected_planes = f.format == PixelFormat::kNV12 ? 2 : 1;
  if (f.num_planes != expected_planes)
    return invalid_argument(std::string(pixel_format_name(f.format)) + " frame has " + std::to_string(f.num_planes) +
                            " planes, expected " + std::to_string(expected_planes));
  switch (f.format) {
    case PixelFormat::kRGB24: return check_plane(f, 0, 3 * w, h);
    case PixelFormat::kYUYV: return check_plane(f, 0, 4 * cw, h);
    case PixelFormat::kNV12:
      GS_RETURN_IF_ERROR(check_plane(f, 0, w, h));
      return check_plane(f, 1, 2 * cw, ch);
    case PixelFormat::kMJPEG:
      if (f.planes[0].data == nullptr || f.planes[0].size == 0) return invalid_argument("mjpeg frame is empty");
      return Status::Ok();
  }
  return invalid_argument("unknown pixel format");
}

}  // namespace gs::capture
