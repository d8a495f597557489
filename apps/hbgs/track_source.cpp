// SPDX-License-Identifier: MIT
// gs_capture's frame sources as the tracking job's frame stream (track_source.h).
#include "track_source.h"

#include <filesystem>
#include <system_error>
#include <vector>

#include "gs/capture/convert.h"
#include "gs/capture/devices.h"
#include "gs/capture/ingest.h"
#include "gs/platform/clock.h"

namespace hbgs::cli {
namespace {

namespace cap = gs::capture;

constexpr int32_t kPollMs = 200;          // one acquire's wait
constexpr double kStalledSeconds = 5.0;   // a camera silent this long is an error

class CaptureStream final : public gs::jobs::FrameStream {
 public:
  CaptureStream(std::unique_ptr<cap::FrameSource> source, bool live) : source_(std::move(source)), live_(live) {}
  ~CaptureStream() override {
    give_back();
    (void)source_->stop();
  }
  std::string name() const override { return source_->name(); }
  bool live() const override { return live_; }

  gs::Status next(gs::jobs::StreamFrame* frame, bool* end) override {
    *end = false;
    GS_RETURN_IF_ERROR(give_back());
    const double start = gs::platform::now_seconds();
    for (;;) {
      gs::Expected<cap::AcquireResult> r = source_->acquire(kPollMs, &view_);
      if (!r.ok()) return r.status();
      if (*r == cap::AcquireResult::kEndOfStream) {
        *end = true;
        return gs::Status::Ok();
      }
      if (*r == cap::AcquireResult::kFrame) break;
      if (gs::platform::now_seconds() - start > kStalledSeconds)
        return gs::io_error(name() + ": no frame for " + std::to_string(int(kStalledSeconds)) + " s (camera stalled or disconnected)");
    }
    holding_ = true;
    converted_ = false;
    frame->width = view_.width;
    frame->height = view_.height;
    frame->time = double(view_.timestamp_ns) * 1e-9;
    frame->sequence = view_.sequence;
    return gs::Status::Ok();
  }

  gs::Status pixels(const uint8_t** rgb) override {
    if (!holding_) return gs::invalid_argument(name() + ": no current frame");
    const cap::FramePlane& p = view_.planes[0];
    if (view_.format == cap::PixelFormat::kRGB24 && p.stride == 3 * view_.width) {  // video and image folders: no copy
      *rgb = p.data;
      return gs::Status::Ok();
    }
    if (!converted_) {
      rgb_.resize(size_t(view_.width) * size_t(view_.height) * 3);  // allocates once: a camera keeps its size
      GS_RETURN_IF_ERROR(cap::frame_to_rgb(view_, rgb_.data(), 3 * view_.width));
      converted_ = true;
    }
    *rgb = rgb_.data();
    return gs::Status::Ok();
  }

 private:
  gs::Status give_back() {
    if (!holding_) return gs::Status::Ok();
    holding_ = false;
    return source_->release(view_);
  }

  std::unique_ptr<cap::FrameSource> source_;
  bool live_;
  cap::FrameView view_;
  bool holding_ = false, converted_ = false;
  std::vector<uint8_t> rgb_;
};

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// Configures a camera: the size asked for in the first pixel format it offers of YUYV, MJPEG, NV12.
gs::Status configure_camera(cap::FrameSource& source, int width, int height) {
  gs::Status first;
  for (cap::PixelFormat pf : {cap::PixelFormat::kYUYV, cap::PixelFormat::kMJPEG, cap::PixelFormat::kNV12}) {
    cap::FrameFormat want, got;
    want.width = width;
    want.height = height;
    want.format = pf;
    gs::Status st = source.configure(want, &got);
    if (st.ok()) return st;
    if (st.code() != gs::StatusCode::kUnsupported) return st;  // a missing device, no permission: say so at once
    if (first.ok()) first = st;
  }
  return first;
}

}  // namespace

gs::Expected<std::unique_ptr<gs::jobs::FrameStream>> open_capture_stream(const std::string& source, int width, int height) {
  std::error_code ec;
  std::unique_ptr<cap::FrameSource> src;
  bool live = true;
  if (starts_with(source, "libcamera:")) {
    gs::Expected<std::unique_ptr<cap::FrameSource>> s = cap::open_libcamera(source.substr(10));
    if (!s.ok()) return s.status();
    src = std::move(s).value();
  } else if (starts_with(source, "v4l2:") || starts_with(source, "/dev/") || std::filesystem::is_character_file(source, ec)) {
    gs::Expected<std::unique_ptr<cap::FrameSource>> s = cap::open_v4l2_device(starts_with(source, "v4l2:") ? source.substr(5) : source);
    if (!s.ok()) return s.status();
    src = std::move(s).value();
  } else {
    gs::Expected<std::unique_ptr<cap::FrameSource>> s = cap::open_input(source);
    if (!s.ok()) return s.status();
    src = std::move(s).value();
    live = false;
  }
  if (live) {
    GS_RETURN_IF_ERROR(configure_camera(*src, width, height));
  } else {
    cap::FrameFormat want, got;
    want.format = cap::PixelFormat::kRGB24;
    GS_RETURN_IF_ERROR(src->configure(want, &got));
  }
  GS_RETURN_IF_ERROR(src->start());
  return std::unique_ptr<gs::jobs::FrameStream>(new CaptureStream(std::move(src), live));
}

}  // namespace hbgs::cli
