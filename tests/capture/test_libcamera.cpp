// SPDX-License-Identifier: MIT
// libcamera source tests that hold on any machine: listing cameras never crashes and is stable,
// and asking for a camera that does not exist is an error that names it and says what exists
// (here: nothing; on a board with cameras: their ids). The capture loop itself needs a camera.
#include <doctest/doctest.h>

#include <string>

#include "gs/capture/libcamera_source.h"

namespace gs::capture {
namespace {

bool contains(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

TEST_CASE("libcamera camera list is stable and well formed") {
  auto first = list_libcamera_cameras();
  REQUIRE_MESSAGE(first.ok(), first.status().to_string());
  auto second = list_libcamera_cameras();  // the shared manager is reused, not started twice
  REQUIRE_MESSAGE(second.ok(), second.status().to_string());
  REQUIRE(first->size() == second->size());
  for (size_t i = 0; i < first->size(); ++i) {
    CHECK_FALSE((*first)[i].id.empty());
    CHECK((*first)[i].id == (*second)[i].id);
  }
  MESSAGE("libcamera sees " << first->size() << " camera(s)");
}

TEST_CASE("libcamera unknown camera id is an error that names it and lists what exists") {
  auto cams = list_libcamera_cameras();
  REQUIRE(cams.ok());
  LibcameraSource src("nonexistent");
  CHECK(std::string(src.name()) == "libcamera:nonexistent");
  FrameFormat req, actual;
  req.format = PixelFormat::kYUYV;
  const Status st = src.configure(req, &actual);
  REQUIRE_FALSE(st.ok());
  CHECK(contains(st.message(), "'nonexistent'"));
  if (cams->empty()) {
    CHECK(contains(st.message(), "no cameras found"));
  } else {
    CHECK(contains(st.message(), "available"));
    for (const CameraInfo& c : *cams) CHECK(contains(st.message(), c.id));
  }
  // The unconfigured source refuses to run and stops cleanly.
  CHECK_FALSE(src.start().ok());
  FrameView frame;
  CHECK_FALSE(src.acquire(10, &frame).ok());
  CHECK_FALSE(src.release(frame).ok());
  CHECK(src.stop().ok());
}

TEST_CASE("libcamera camera index past the end of the list is an error") {
  auto cams = list_libcamera_cameras();
  REQUIRE(cams.ok());
  const std::string index = std::to_string(cams->size());  // one past the last valid index
  LibcameraSource src(index);
  FrameFormat req, actual;
  req.format = PixelFormat::kNV12;
  const Status st = src.configure(req, &actual);
  REQUIRE_FALSE(st.ok());
  CHECK(contains(st.message(), "'" + index + "'"));
}

}  // namespace
}  // namespace gs::capture
