// SPDX-License-Identifier: MIT
// V4L2 capture: a FrameSource over a /dev/videoN node using memory-mapped streaming I/O (the
// kernel's capture.c pattern), and the device listing behind `hbgs capture --list`. All buffers are
// requested and mapped at configure(), so acquire() and release() are one poll + one ioctl each and
// allocate nothing. Single-planar capture only (V4L2_BUF_TYPE_VIDEO_CAPTURE): NV12 arrives as one
// buffer whose UV plane follows the Y plane, which is how UVC cameras and most USB devices deliver it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/capture/frame_source.h"
#include "gs/capture/v4l2_device.h"
#include "gs/status.h"

namespace gs::capture {

class V4l2Source final : public FrameSource {
 public:
  // ops must outlive the source. ring_size is the number of buffers asked for (clamped to [2, 32]);
  // the driver may grant a different count, which buffer_count() reports after configure().
  V4l2Source(std::string path, V4l2Device& ops, int32_t ring_size = 4);
  ~V4l2Source() override;  // stop()s
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  const char* name() const override { return name_.c_str(); }  // "v4l2:<path>"
  // Opens the device, checks it can capture and stream, negotiates the format (an unoffered one is
  // an `unsupported` error listing the offered fourccs), sets the frame rate when requested.fps > 0
  // and the driver supports it (otherwise actual->fps is 0: unknown), then requests and maps the
  // ring. Configuring again tears the previous configuration down first.
  Status configure(const FrameFormat& requested, FrameFormat* actual) override;
  Status start() override;  // queues every buffer, STREAMON
  // kTimeout when poll times out or VIDIOC_DQBUF says EAGAIN. A buffer the driver flags as
  // corrupt (V4L2_BUF_FLAG_ERROR) or an empty MJPEG buffer is requeued and reported as kTimeout.
  // ENODEV/EIO/ENXIO (unplugged) give "device <path> disappeared mid-stream (frame N)", N being
  // the frames delivered so far; the source then only accepts stop(). Holding every buffer of the
  // ring is an error rather than a wait that could never end.
  Expected<AcquireResult> acquire(int32_t timeout_ms, FrameView* frame) override;
  Status release(const FrameView& frame) override;  // requeues frame.buffer_index
  // STREAMOFF, unmap, REQBUFS 0, close; idempotent, and completes even when the device has gone.
  Status stop() override;

  // After configure(): the formats the device offered (VIDIOC_ENUM_FMT order), the row stride and
  // image size in use (after the minimum clamp) and the number of buffers in the ring.
  const std::vector<uint32_t>& offered_formats() const { return offered_; }
  int32_t bytes_per_line() const { return bytes_per_line_; }
  uint32_t image_size() const { return image_size_; }
  int32_t buffer_count() const { return static_cast<int32_t>(buffers_.size()); }

 private:
  struct Buffer {
    void* data = nullptr;
    size_t length = 0;
    bool queued = false;  // owned by the driver (between QBUF and DQBUF)
  };
  Status negotiate(const FrameFormat& requested, FrameFormat* actual);
  Status teardown();
  Status device_error(const char* what, int err) const;
  Status gone_error() const;

  std::string path_, name_;
  V4l2Device& ops_;
  int32_t ring_size_;
  int fd_ = -1;
  bool streaming_ = false, failed_ = false;
  std::vector<uint32_t> offered_;
  std::vector<Buffer> buffers_;
  FrameFormat format_;
  int32_t bytes_per_line_ = 0;
  uint32_t image_size_ = 0;
  uint64_t frames_delivered_ = 0;
};

struct V4l2DeviceInfo {
  std::string path;                 // e.g. "/dev/video0"
  std::string card, driver, bus;    // VIDIOC_QUERYCAP's card, driver and bus_info
  std::vector<uint32_t> formats;    // fourccs offered for capture, VIDIOC_ENUM_FMT order
  std::string error;                // set when the node could not be opened (permission); rest empty
};

// Scans dev_dir for videoN nodes (sorted by N) and describes those that can capture video. Nodes
// that are not V4L2 devices or have no video capture (UVC metadata nodes, encoders, outputs) are
// skipped; a node that cannot be opened for lack of permission is listed with `error` set so the
// user learns why their camera is missing. An empty list is not an error.
Expected<std::vector<V4l2DeviceInfo>> list_v4l2_devices(V4l2Device& ops, const std::string& dev_dir = "/dev");

}  // namespace gs::capture
