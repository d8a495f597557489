// SPDX-License-Identifier: MIT
// Pixel-format names and V4L2 fourcc codes (round trips, the kernel header's own codes where it is
// available, unknown names listing the known ones) and validate_frame on well-formed and broken
// frame views: short strides, short planes, wrong plane counts, missing data, empty sizes.
#include <doctest/doctest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "gs/capture/frame.h"

#if defined(GS_HAVE_V4L2)
#include <linux/videodev2.h>
#endif

namespace {

using gs::capture::FrameView;
using gs::capture::PixelFormat;

constexpr PixelFormat kAll[] = {PixelFormat::kRGB24, PixelFormat::kYUYV, PixelFormat::kNV12, PixelFormat::kMJPEG};

TEST_CASE("pixel format names parse back to the same format") {
  for (PixelFormat f : kAll) {
    const std::string name = gs::capture::pixel_format_name(f);
    CAPTURE(name);
    auto parsed = gs::capture::parse_pixel_format(name);
    REQUIRE(parsed.ok());
    CHECK(*parsed == f);
    std::string upper;
    for (char c : name) upper += char(c >= 'a' && c <= 'z' ? c - 'a' + 'A' : c);
    auto parsed_upper = gs::capture::parse_pixel_format(upper);
    REQUIRE(parsed_upper.ok());
    CHECK(*parsed_upper == f);
  }
  CHECK(std::string(gs::capture::pixel_format_name(PixelFormat::kYUYV)) == "yuyv");
  auto mjpg = gs::capture::parse_pixel_format("MJPG");  // the fourcc spelling is accepted too
  REQUIRE(mjpg.ok());
  CHECK(*mjpg == PixelFormat::kMJPEG);
}

TEST_CASE("unknown pixel format names are errors that list the known names") {
  for (const char* bad : {"", "yuv420", "rgb", "nv21", "yuyv "}) {
    CAPTURE(bad);
    auto r = gs::capture::parse_pixel_format(bad);
    REQUIRE(!r.ok());
    const std::string& m = r.status().message();
    for (PixelFormat f : kAll) CHECK(m.find(gs::capture::pixel_format_name(f)) != std::string::npos);
    CHECK(m.find(std::string("'") + bad + "'") != std::string::npos);
  }
}

TEST_CASE("fourcc codes are the V4L2 ones and round trip") {
  // Little-endian character codes, as v4l2_fourcc() builds them.
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kYUYV) == 0x56595559u);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kNV12) == 0x3231564eu);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kMJPEG) == 0x47504a4du);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kRGB24) == 0x33424752u);
#if defined(GS_HAVE_V4L2)
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kYUYV) == V4L2_PIX_FMT_YUYV);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kNV12) == V4L2_PIX_FMT_NV12);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kMJPEG) == V4L2_PIX_FMT_MJPEG);
  CHECK(gs::capture::pixel_format_fourcc(PixelFormat::kRGB24) == V4L2_PIX_FMT_RGB24);
#endif
  for (PixelFormat f : kAll) {
    PixelFormat back = f == PixelFormat::kRGB24 ? PixelFormat::kMJPEG : PixelFormat::kRGB24;
    REQUIRE(gs::capture::pixel_format_from_fourcc(gs::capture::pixel_format_fourcc(f), &back));
    CHECK(back == f);
  }
  PixelFormat untouched = PixelFormat::kNV12;
  CHECK(!gs::capture::pixel_format_from_fourcc(0x34325659u /* YV24 */, &untouched));
  CHECK(untouched == PixelFormat::kNV12);
  CHECK(gs::capture::fourcc_text(gs::capture::pixel_format_fourcc(PixelFormat::kYUYV)) == "YUYV");
  CHECK(gs::capture::fourcc_text(gs::capture::pixel_format_fourcc(PixelFormat::kMJPEG)) == "MJPG");
  CHECK(gs::capture::fourcc_text(0x0a000141u) == "A???");  // bytes 'A' 01 00 0A: unprintables as '?'
}

// A view over `bytes` with the given plane layout; data pointers into one shared buffer.
FrameView view(PixelFormat f, int w, int h, const std::vector<uint8_t>& bytes, int planes, size_t size0, int stride0,
               size_t size1 = 0, int stride1 = 0) {
  FrameView v;
  v.width = w;
  v.height = h;
  v.format = f;
  v.num_planes = planes;
  v.planes[0] = {bytes.data(), size0, stride0};
  v.planes[1] = {bytes.data(), size1, stride1};
  return v;
}

TEST_CASE("validate_frame accepts minimal layouts and catches short strides and sizes") {
  const std::vector<uint8_t> buf(4096, 0);
  using gs::capture::validate_frame;
  // YUYV 5x3: a row is 3 pairs = 12 bytes; the last row need not be padded.
  CHECK(validate_frame(view(PixelFormat::kYUYV, 5, 3, buf, 1, 2 * 16 + 12, 16)).ok());
  CHECK(!validate_frame(view(PixelFormat::kYUYV, 5, 3, buf, 1, 2 * 16 + 11, 16)).ok());
  CHECK(!validate_frame(view(PixelFormat::kYUYV, 5, 3, buf, 1, 4096, 10)).ok());  // 10 < 12
  // RGB24 7x2: 21 bytes a row.
  CHECK(validate_frame(view(PixelFormat::kRGB24, 7, 2, buf, 1, 42, 21)).ok());
  CHECK(!validate_frame(view(PixelFormat::kRGB24, 7, 2, buf, 1, 41, 21)).ok());
  CHECK(!validate_frame(view(PixelFormat::kRGB24, 7, 2, buf, 1, 4096, 20)).ok());
  // NV12 5x3: luma rows of 5, chroma 2 rows of 3 pairs = 6 bytes.
  CHECK(validate_frame(view(PixelFormat::kNV12, 5, 3, buf, 2, 15, 5, 12, 6)).ok());
  const gs::Status short_uv = validate_frame(view(PixelFormat::kNV12, 5, 3, buf, 2, 15, 5, 11, 6));
  CHECK(!short_uv.ok());
  CHECK(short_uv.message().find("plane 1") != std::string::npos);
  const gs::Status narrow_uv = validate_frame(view(PixelFormat::kNV12, 5, 3, buf, 2, 15, 5, 100, 5));
  CHECK(!narrow_uv.ok());
  CHECK(narrow_uv.message().find("stride 5") != std::string::npos);
  CHECK(!validate_frame(view(PixelFormat::kNV12, 5, 3, buf, 2, 14, 5, 12, 6)).ok());
  // MJPEG only needs bytes.
  CHECK(validate_frame(view(PixelFormat::kMJPEG, 640, 480, buf, 1, 100, 0)).ok());
  CHECK(!validate_frame(view(PixelFormat::kMJPEG, 640, 480, buf, 1, 0, 0)).ok());
}

TEST_CASE("validate_frame catches wrong plane counts missing data and empty sizes") {
  const std::vector<uint8_t> buf(4096, 0);
  using gs::capture::validate_frame;
  CHECK(!validate_frame(view(PixelFormat::kNV12, 4, 4, buf, 1, 16, 4)).ok());
  CHECK(!validate_frame(view(PixelFormat::kYUYV, 4, 4, buf, 2, 64, 8, 64, 8)).ok());
  CHECK(!validate_frame(view(PixelFormat::kRGB24, 4, 4, buf, 0, 48, 12)).ok());
  const gs::Status planes = validate_frame(view(PixelFormat::kNV12, 4, 4, buf, 3, 16, 4, 8, 4));
  CHECK(!planes.ok());
  CHECK(planes.message().find("expected 2") != std::string::npos);
  FrameView no_data = view(PixelFormat::kRGB24, 4, 4, buf, 1, 48, 12);
  no_data.planes[0].data = nullptr;
  CHECK(!validate_frame(no_data).ok());
  CHECK(!validate_frame(view(PixelFormat::kRGB24, 0, 4, buf, 1, 48, 12)).ok());
  CHECK(!validate_frame(view(PixelFormat::kRGB24, 4, -1, buf, 1, 48, 12)).ok());
}

}  // namespace
