// SPDX-License-Identifier: MIT
// Frames as the capture layer hands them out: a borrowed view of up to three planes with their
// strides, the pixel format, a timestamp and a sequence number. Views point into a source's own
// buffers (an mmapped V4L2 ring, a decoder's frame) and stay valid until FrameSource::release.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "gs/status.h"

namespace gs::capture {

enum class PixelFormat : uint8_t {
  kRGB24,  // one plane, [H, W, 3], R G B bytes
  kYUYV,   // one plane, packed 4:2:2: Y0 U Y1 V per two pixels (odd widths: last pair half used)
  kNV12,   // two planes: Y [H, W], interleaved UV [ceil(H/2), ceil(W/2) * 2] (U first)
  kMJPEG,  // one plane holding a whole JPEG image (UVC style, possibly without a DHT segment)
};

const char* pixel_format_name(PixelFormat format);  // "rgb24", "yuyv", "nv12", "mjpeg"
uint32_t pixel_format_fourcc(PixelFormat format);    // V4L2 fourcc code (V4L2_PIX_FMT_*)
// Accepts the names above, case-insensitive; an unknown name is an error that lists the known ones.
Expected<PixelFormat> parse_pixel_format(const std::string& name);
// The format with this V4L2 fourcc; false when hbgs does not handle it.
bool pixel_format_from_fourcc(uint32_t fourcc, PixelFormat* out);
// "YUYV" style printable form of a fourcc, for messages.
std::string fourcc_text(uint32_t fourcc);

struct FramePlane {
  const uint8_t* data = nullptr;
  size_t size = 0;     // bytes valid at data (for MJPEG: the JPEG's length)
  int32_t stride = 0;  // bytes per row (0 for MJPEG)
};

struct FrameView {
  int32_t width = 0, height = 0;  // pixels
  PixelFormat format = PixelFormat::kRGB24;
  int32_t num_planes = 0;
  FramePlane planes[3];
  int64_t timestamp_ns = 0;  // source clock (V4L2 buffer timestamp, video PTS), nanoseconds
  uint64_t sequence = 0;     // frame counter of the source; gaps mean dropped frames
  int32_t buffer_index = -1; // which of the source's buffers holds the frame (for release)
};

// What configure() asks for; a source may adjust size and rate and says what it chose.
struct FrameFormat {
  int32_t width = 0, height = 0;  // 0: the source's default / native size
  PixelFormat format = PixelFormat::kYUYV;
  double fps = 0.0;               // 0: the source's default
};

// Checks that a view's planes are large enough for its size and format (strides cover the row,
// sizes cover all rows); used by the converters and by tests. Returns a message naming the plane.
Status validate_frame(const FrameView& frame);

}  // namespace gs::capture
