// SPDX-License-Identifier: MIT
// LibcameraSource: a camera driven through libcamera (Raspberry Pi camera modules, UVC webcams on
// the libcamera stack) behind the FrameSource interface. Buffers come from libcamera's
// FrameBufferAllocator and are mmapped at configure; one Request per buffer is queued at start; the
// completion callback (on libcamera's thread) only pushes the request's index into a fixed-size
// lock-free single-producer/single-consumer ring and signals an eventfd; acquire waits on that with
// a timeout, and release re-queues the request with its buffer. Delivered formats: YUYV, NV12, MJPEG.
// libcamera allows one CameraManager per process, so every source and list_libcamera_cameras()
// share one, started on first use. These declarations exist only when gs_capture was built with
// libcamera (GS_HAVE_LIBCAMERA); written against Debian 12's libcamera 0.0.3.
#pragma once

#ifdef GS_HAVE_LIBCAMERA

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gs/capture/frame_source.h"

namespace gs::capture {

struct CameraInfo {
  std::string id;     // libcamera's stable id, e.g. "/base/soc/i2c0mux/i2c@1/imx219@10"
  std::string model;  // the Model property, e.g. "imx219"; empty when the camera does not say
};

// The cameras libcamera sees now; an empty list (not an error) when there are none. Sets
// LIBCAMERA_LOG_LEVELS=*:ERROR for the process unless it is already set, so libcamera's INFO/WARN
// chatter ("No IPA found") stays out of the output.
Expected<std::vector<CameraInfo>> list_libcamera_cameras();

class LibcameraSource : public FrameSource {
 public:
  // Upper bound on the buffers requested from libcamera; it also sizes the completion ring.
  static constexpr uint32_t kMaxBuffers = 16;

  // camera: a libcamera id, or a decimal index into list_libcamera_cameras().
  explicit LibcameraSource(std::string camera);
  ~LibcameraSource() override;
  LibcameraSource(const LibcameraSource&) = delete;
  LibcameraSource& operator=(const LibcameraSource&) = delete;

  const char* name() const override { return name_.c_str(); }  // "libcamera:<camera>"
  // Finds and acquires the camera (an unknown camera is an error listing the available ones),
  // generates a VideoRecording configuration, applies the requested format (YUYV, NV12 or MJPEG;
  // RGB24 is not offered) and size (0 = the camera's default) and fps (0 = default), validates,
  // configures, allocates and maps the buffers and creates one request per buffer.
  Status configure(const FrameFormat& requested, FrameFormat* actual) override;
  Status start() override;  // starts the camera and queues every request
  Expected<AcquireResult> acquire(int32_t timeout_ms, FrameView* frame) override;
  Status release(const FrameView& frame) override;  // re-queues the frame's request
  Status stop() override;

 private:
  struct Impl;
  std::string camera_, name_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gs::capture

#endif  // GS_HAVE_LIBCAMERA
