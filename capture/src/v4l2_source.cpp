// SPDX-License-Identifier: MIT
// V4L2 memory-mapped streaming capture and device listing. Every system call goes through a
// V4l2Device so tests can run the whole state machine against an in-memory fake. Messages name the
// device and say what the user can do about it (permissions, a format the camera does offer),
// because a capture that fails with a bare errno is the most common support question for V4L2 tools.
#include "gs/capture/v4l2_source.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

namespace gs::capture {
namespace {

constexpr int32_t kMaxBuffers = 32;  // VIDEO_MAX_FRAME: the most a V4L2 queue holds
constexpr uint32_t kMaxFormats = 256;  // bound on VIDIOC_ENUM_FMT in case a driver never says EINVAL

std::string errno_text(int err) { return std::strerror(err < 0 ? -err : err); }

// A USB camera unplugged mid-stream makes the next ioctl fail with one of these.
bool device_gone(int err) { return err == -ENODEV || err == -EIO || err == -ENXIO; }

Status open_error(const std::string& path, int err) {
  if (err == -ENOENT) return io_error("no such device " + path);
  if (err == -EACCES || err == -EPERM)
    return io_error("permission denied opening " + path + " (is your user in the 'video' group?)");
  if (err == -EBUSY) return io_error("device " + path + " is busy (another program is using it)");
  return io_error("cannot open " + path + ": " + errno_text(err));
}

std::string array_text(const uint8_t* s, size_t n) {
  const char* c = reinterpret_cast<const char*>(s);
  return std::string(c, strnlen(c, n));
}

// The capabilities of the opened node: device_caps when the driver fills it (a driver exposing
// several nodes reports the union in `capabilities`, which would make a metadata node look
// capture-capable).
uint32_t node_caps(const v4l2_capability& cap) {
  return (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
}

int enum_formats(V4l2Device& ops, int fd, std::vector<uint32_t>* out) {
  out->clear();
  for (uint32_t i = 0; i < kMaxFormats; ++i) {
    v4l2_fmtdesc d{};
    d.index = i;
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const int r = xioctl(ops, fd, VIDIOC_ENUM_FMT, &d);
    if (r == -EINVAL) break;  // past the last format
    if (r < 0) return r;
    out->push_back(d.pixelformat);
  }
  return 0;
}

std::string format_list(const std::vector<uint32_t>& fourccs) {
  if (fourccs.empty()) return "none";
  std::string s;
  for (uint32_t f : fourccs) s += (s.empty() ? "" : ", ") + fourcc_text(f);
  return s;
}

// Smallest row and image sizes a format needs; drivers have been known to report bytesperline or
// sizeimage of 0 (or too small), which the kernel's capture.c example works around the same way.
uint32_t min_bytes_per_line(PixelFormat f, uint32_t w) {
  const uint32_t cw = (w + 1) / 2;
  switch (f) {
    case PixelFormat::kRGB24: return 3 * w;
    case PixelFormat::kYUYV: return 4 * cw;
    case PixelFormat::kNV12: return 2 * cw;  // Y needs w, the UV row 2 * ceil(w / 2); they share the stride
    case PixelFormat::kMJPEG: return 0;
  }
  return 0;
}
uint32_t min_image_size(PixelFormat f, uint32_t bpl, uint32_t h) {
  switch (f) {
    case PixelFormat::kRGB24:
    case PixelFormat::kYUYV: return bpl * h;
    case PixelFormat::kNV12: return bpl * h + bpl * ((h + 1) / 2);
    case PixelFormat::kMJPEG: return 0;
  }
  return 0;
}

}  // namespace

V4l2Source::V4l2Source(std::string path, V4l2Device& ops, int32_t ring_size)
    : path_(std::move(path)), name_("v4l2:" + path_), ops_(ops),
      ring_size_(std::clamp<int32_t>(ring_size, 2, kMaxBuffers)) {}

V4l2Source::~V4l2Source() { (void)stop(); }

Status V4l2Source::device_error(const char* what, int err) const {
  return io_error(name_ + ": " + what + " failed: " + errno_text(err));
}

Status V4l2Source::gone_error() const {
  return io_error("device " + path_ + " disappeared mid-stream (frame " + std::to_string(frames_delivered_) + ")");
}

Status V4l2Source::configure(const FrameFormat& requested, FrameFormat* actual) {
  GS_RETURN_IF_ERROR(teardown());
  Status s = negotiate(requested, actual);
  if (!s.ok()) (void)teardown();  // leave nothing open or mapped behind a failed configure
  return s;
}

Status V4l2Source::negotiate(const FrameFormat& requested, FrameFormat* actual) {
  if (requested.width < 0 || requested.height < 0 || !(requested.fps >= 0.0))
    return invalid_argument(name_ + ": bad requested format " + std::to_string(requested.width) + "x" +
                            std::to_string(requested.height) + " at " + std::to_string(requested.fps) + " fps");
  // Non-blocking so DQBUF says EAGAIN instead of sleeping: poll() owns the waiting and its timeout.
  const int fd = ops_.open(path_, O_RDWR | O_NONBLOCK);
  if (fd < 0) return open_error(path_, fd);
  fd_ = fd;

  v4l2_capability cap{};
  int r = xioctl(ops_, fd_, VIDIOC_QUERYCAP, &cap);
  if (r == -ENOTTY || r == -EINVAL) return unsupported(path_ + " is not a V4L2 device");
  if (r < 0) return device_error("VIDIOC_QUERYCAP", r);
  const uint32_t caps = node_caps(cap);
  const std::string who = path_ + " (" + array_text(cap.card, sizeof(cap.card)) + ")";
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE)
      return unsupported(who + " is a multi-planar capture device, which hbgs does not handle");
    char hex[16];
    std::snprintf(hex, sizeof(hex), "0x%08x", caps);
    return unsupported(who + " is not a video capture device (capabilities " + hex + ")");
  }
  if (!(caps & V4L2_CAP_STREAMING))
    return unsupported(who + " does not support streaming I/O (V4L2_CAP_STREAMING), which hbgs needs");

  r = enum_formats(ops_, fd_, &offered_);
  if (r < 0) return device_error("VIDIOC_ENUM_FMT", r);
  const uint32_t want = pixel_format_fourcc(requested.format);
  if (std::find(offered_.begin(), offered_.end(), want) == offered_.end())
    return unsupported(who + " does not offer " + fourcc_text(want) + " (" + pixel_format_name(requested.format) +
                       "); it offers: " + format_list(offered_));

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (requested.width == 0 || requested.height == 0) {  // keep the device's current size
    r = xioctl(ops_, fd_, VIDIOC_G_FMT, &fmt);
    if (r < 0) return device_error("VIDIOC_G_FMT", r);
  }
  if (requested.width > 0) fmt.fmt.pix.width = static_cast<uint32_t>(requested.width);
  if (requested.height > 0) fmt.fmt.pix.height = static_cast<uint32_t>(requested.height);
  fmt.fmt.pix.pixelformat = want;
  fmt.fmt.pix.field = V4L2_FIELD_ANY;
  fmt.fmt.pix.bytesperline = 0;  // let the driver choose its stride
  fmt.fmt.pix.sizeimage = 0;
  r = xioctl(ops_, fd_, VIDIOC_S_FMT, &fmt);
  if (r == -EBUSY) return io_error("device " + path_ + " is busy (another program is streaming from it)");
  if (r < 0) return device_error("VIDIOC_S_FMT", r);
  // S_FMT writes back what the driver will actually deliver.
  const v4l2_pix_format& pix = fmt.fmt.pix;
  if (pix.pixelformat != want)
    return unsupported(who + " was asked for " + fourcc_text(want) + " but switched to " + fourcc_text(pix.pixelformat));
  if (pix.width == 0 || pix.height == 0 || pix.width > 65536 || pix.height > 65536)
    return unsupported(who + " reported an unusable frame size " + std::to_string(pix.width) + "x" +
                       std::to_string(pix.height));
  const uint32_t min_bpl = min_bytes_per_line(requested.format, pix.width);
  const uint32_t bpl = requested.format == PixelFormat::kMJPEG ? 0 : std::max(pix.bytesperline, min_bpl);
  const uint32_t size = std::max(pix.sizeimage, min_image_size(requested.format, bpl, pix.height));

  // Frame rate: only through the timeperframe interface, and only when the driver has it; a
  // camera without it runs at its own rate, which is not worth failing over.
  double fps = 0.0;
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(ops_, fd_, VIDIOC_G_PARM, &parm) >= 0 && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    if (requested.fps > 0.0) {
      v4l2_streamparm set{};
      set.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      set.parm.capture.timeperframe.numerator = 1000;
      set.parm.capture.timeperframe.denominator = static_cast<uint32_t>(std::lround(requested.fps * 1000.0));
      r = xioctl(ops_, fd_, VIDIOC_S_PARM, &set);
      if (r < 0 && device_gone(r)) return device_error("VIDIOC_S_PARM", r);
      if (r >= 0) parm = set;  // S_PARM writes back the interval the driver chose
    }
    const v4l2_fract& t = parm.parm.capture.timeperframe;
    if (t.numerator > 0 && t.denominator > 0) fps = double(t.denominator) / double(t.numerator);
  }

  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(ring_size_);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  r = xioctl(ops_, fd_, VIDIOC_REQBUFS, &req);
  if (r == -EINVAL) return unsupported(who + " does not support memory-mapped streaming");
  if (r < 0) return device_error("VIDIOC_REQBUFS", r);
  if (req.count < 2)
    return io_error(name_ + ": insufficient buffer memory (the driver granted " + std::to_string(req.count) +
                    " buffers, at least 2 are needed)");
  buffers_.assign(std::min<uint32_t>(req.count, kMaxBuffers), Buffer{});
  for (size_t i = 0; i < buffers_.size(); ++i) {
    v4l2_buffer b{};
    b.index = static_cast<uint32_t>(i);
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    r = xioctl(ops_, fd_, VIDIOC_QUERYBUF, &b);
    if (r < 0) return device_error("VIDIOC_QUERYBUF", r);
    // A buffer smaller than a frame at the clamped stride would make views read past the mapping.
    if (b.length == 0 || b.length < min_image_size(requested.format, bpl, pix.height))
      return io_error(name_ + ": buffer " + std::to_string(i) + " is " + std::to_string(b.length) +
                      " bytes, too small for a " + std::to_string(pix.width) + "x" + std::to_string(pix.height) + " " +
                      fourcc_text(want) + " frame with " + std::to_string(bpl) + " bytes per line");
    void* p = nullptr;
    r = ops_.mmap(b.length, fd_, static_cast<int64_t>(b.m.offset), &p);
    if (r < 0) return device_error("mmap", r);
    buffers_[i].data = p;
    buffers_[i].length = b.length;
  }

  format_.width = static_cast<int32_t>(pix.width);
  format_.height = static_cast<int32_t>(pix.height);
  format_.format = requested.format;
  format_.fps = fps;
  bytes_per_line_ = static_cast<int32_t>(bpl);
  image_size_ = size;
  if (actual) *actual = format_;
  return Status::Ok();
}

Status V4l2Source::start() {
  if (fd_ < 0 || buffers_.empty()) return invalid_argument(name_ + ": start() before configure()");
  if (streaming_) return invalid_argument(name_ + ": start() while already streaming");
  for (size_t i = 0; i < buffers_.size(); ++i) {
    v4l2_buffer b{};
    b.index = static_cast<uint32_t>(i);
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    const int r = xioctl(ops_, fd_, VIDIOC_QBUF, &b);
    if (r < 0) return device_error("VIDIOC_QBUF", r);
    buffers_[i].queued = true;
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  const int r = xioctl(ops_, fd_, VIDIOC_STREAMON, &type);
  if (r < 0) return device_error("VIDIOC_STREAMON", r);
  streaming_ = true;
  frames_delivered_ = 0;
  return Status::Ok();
}

Expected<AcquireResult> V4l2Source::acquire(int32_t timeout_ms, FrameView* frame) {
  if (!streaming_) return invalid_argument(name_ + ": acquire() before start()");
  if (failed_) return gone_error();
  bool any_queued = false;
  for (const Buffer& b : buffers_) any_queued |= b.queued;
  if (!any_queued)  // the driver has nothing to fill: waiting could only time out
    return invalid_argument(name_ + ": all " + std::to_string(buffers_.size()) +
                            " buffers are held; release a frame before acquiring another");

  // A signal restarts the wait with the full timeout: simpler than tracking the remainder, and
  // signals during capture are rare enough that the longer worst case does not matter.
  int r = ops_.poll(fd_, timeout_ms);
  for (int retry = 0; r == -EINTR && retry < kXioctlMaxRetries; ++retry) r = ops_.poll(fd_, timeout_ms);
  if (r == 0) return AcquireResult::kTimeout;
  if (r < 0) return device_error("poll", r);

  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  r = xioctl(ops_, fd_, VIDIOC_DQBUF, &b);
  if (r == -EAGAIN) return AcquireResult::kTimeout;
  if (device_gone(r)) {
    failed_ = true;
    return gone_error();
  }
  if (r < 0) return device_error("VIDIOC_DQBUF", r);
  if (b.index >= buffers_.size()) {
    failed_ = true;
    return io_error(name_ + ": driver returned buffer index " + std::to_string(b.index) + " of " +
                    std::to_string(buffers_.size()));
  }
  Buffer& buf = buffers_[b.index];
  buf.queued = false;
  const bool mjpeg = format_.format == PixelFormat::kMJPEG;
  if ((b.flags & V4L2_BUF_FLAG_ERROR) || (mjpeg && b.bytesused == 0)) {
    // A corrupt or empty frame: hand the buffer straight back and report "nothing yet".
    r = xioctl(ops_, fd_, VIDIOC_QBUF, &b);
    if (device_gone(r)) {
      failed_ = true;
      return gone_error();
    }
    if (r < 0) return device_error("VIDIOC_QBUF", r);
    buf.queued = true;
    return AcquireResult::kTimeout;
  }

  const uint8_t* p = static_cast<const uint8_t*>(buf.data);
  const size_t stride = static_cast<size_t>(bytes_per_line_);
  const size_t h = static_cast<size_t>(format_.height);
  frame->width = format_.width;
  frame->height = format_.height;
  frame->format = format_.format;
  frame->planes[1] = FramePlane{};
  frame->planes[2] = FramePlane{};
  switch (format_.format) {
    case PixelFormat::kMJPEG:
      frame->num_planes = 1;
      frame->planes[0] = FramePlane{p, std::min<size_t>(b.bytesused, buf.length), 0};
      break;
    case PixelFormat::kNV12:  // one buffer: Y rows, then interleaved UV rows at the same stride
      frame->num_planes = 2;
      frame->planes[0] = FramePlane{p, stride * h, bytes_per_line_};
      frame->planes[1] = FramePlane{p + stride * h, stride * ((h + 1) / 2), bytes_per_line_};
      break;
    case PixelFormat::kRGB24:
    case PixelFormat::kYUYV:
      frame->num_planes = 1;
      frame->planes[0] = FramePlane{p, stride * h, bytes_per_line_};
      break;
  }
  frame->timestamp_ns = int64_t(b.timestamp.tv_sec) * 1000000000 + int64_t(b.timestamp.tv_usec) * 1000;
  frame->sequence = b.sequence;
  frame->buffer_index = static_cast<int32_t>(b.index);
  ++frames_delivered_;
  return AcquireResult::kFrame;
}

Status V4l2Source::release(const FrameView& frame) {
  if (!streaming_) return Status::Ok();  // stop() has already taken every buffer back
  const int32_t i = frame.buffer_index;
  if (i < 0 || i >= buffer_count())
    return invalid_argument(name_ + ": release() of buffer " + std::to_string(i) + ", the ring has " +
                            std::to_string(buffers_.size()));
  if (buffers_[size_t(i)].queued)
    return invalid_argument(name_ + ": buffer " + std::to_string(i) + " released twice");
  v4l2_buffer b{};
  b.index = static_cast<uint32_t>(i);
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  const int r = xioctl(ops_, fd_, VIDIOC_QBUF, &b);
  if (device_gone(r)) {
    failed_ = true;
    return gone_error();
  }
  if (r < 0) return device_error("VIDIOC_QBUF", r);
  buffers_[size_t(i)].queued = true;
  return Status::Ok();
}

Status V4l2Source::stop() { return teardown(); }

Status V4l2Source::teardown() {
  // Every step runs even when an earlier one failed (or the device is gone), so nothing stays
  // mapped or open; the first unexpected failure is reported.
  Status first;
  if (fd_ >= 0 && streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const int r = xioctl(ops_, fd_, VIDIOC_STREAMOFF, &type);
    if (r < 0 && !device_gone(r) && first.ok()) first = device_error("VIDIOC_STREAMOFF", r);
  }
  streaming_ = false;
  bool requested = !buffers_.empty();
  for (Buffer& b : buffers_) {
    if (b.data) {
      const int r = ops_.munmap(b.data, b.length);
      if (r < 0 && first.ok()) first = device_error("munmap", r);
    }
    b = Buffer{};
  }
  buffers_.clear();
  if (fd_ >= 0 && requested) {
    // Frees the driver's buffers now rather than at close; old drivers reject count 0 (EINVAL).
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    const int r = xioctl(ops_, fd_, VIDIOC_REQBUFS, &req);
    if (r < 0 && r != -EINVAL && !device_gone(r) && first.ok()) first = device_error("VIDIOC_REQBUFS 0", r);
  }
  if (fd_ >= 0) {
    const int r = ops_.close(fd_);
    if (r < 0 && first.ok()) first = device_error("close", r);
    fd_ = -1;
  }
  failed_ = false;
  frames_delivered_ = 0;
  return first;
}

Expected<std::vector<V4l2DeviceInfo>> list_v4l2_devices(V4l2Device& ops, const std::string& dev_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::directory_iterator it(dev_dir, ec);
  if (ec) return io_error("cannot list " + dev_dir + ": " + ec.message());
  std::vector<std::pair<unsigned long, std::string>> nodes;
  for (const fs::directory_entry& e : it) {
    const std::string name = e.path().filename().string();
    if (name.size() <= 5 || name.compare(0, 5, "video") != 0) continue;
    if (!std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    if (name.size() > 5 + 9) continue;  // not a plausible minor number
    nodes.emplace_back(std::stoul(name.substr(5)), name);
  }
  std::sort(nodes.begin(), nodes.end());

  const std::string dir = !dev_dir.empty() && dev_dir.back() == '/' ? dev_dir : dev_dir + "/";
  std::vector<V4l2DeviceInfo> out;
  for (const auto& node : nodes) {
    V4l2DeviceInfo info;
    info.path = dir + node.second;
    const int fd = ops.open(info.path, O_RDWR | O_NONBLOCK);
    if (fd < 0) {
      if (fd == -EACCES || fd == -EPERM || fd == -EBUSY) {
        info.error = open_error(info.path, fd).message();
        out.push_back(std::move(info));
      }
      continue;  // vanished between listing and opening, or not openable at all
    }
    v4l2_capability cap{};
    if (xioctl(ops, fd, VIDIOC_QUERYCAP, &cap) >= 0 && (node_caps(cap) & V4L2_CAP_VIDEO_CAPTURE)) {
      info.card = array_text(cap.card, sizeof(cap.card));
      info.driver = array_text(cap.driver, sizeof(cap.driver));
      info.bus = array_text(cap.bus_info, sizeof(cap.bus_info));
      if (enum_formats(ops, fd, &info.formats) < 0) info.formats.clear();
      out.push_back(std::move(info));
    }
    (void)ops.close(fd);
  }
  return out;
}

}  // namespace gs::capture
