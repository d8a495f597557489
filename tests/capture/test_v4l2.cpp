// SPDX-License-Identifier: MIT
// V4l2Source and list_v4l2_devices against FakeV4l2, an in-memory V4L2 driver: no /dev/video* can
// exist on the build machines (no kernel modules, no CUSE), so the fake plays the kernel's part of
// the streaming protocol (QUERYCAP, ENUM_FMT, S_FMT, REQBUFS, QUERYBUF, mmap, QBUF/DQBUF, STREAMON/
// OFF) and fills each dequeued buffer with a generated frame whose every byte is known. It also
// injects the faults real devices produce (EINTR, EAGAIN, poll timeouts, unplugging mid-stream, a
// driver reporting bytesperline 0) and checks the source's hygiene: every mapping unmapped, every fd
// closed, every buffer requeued, no allocation in the acquire/release loop.
#include <doctest/doctest.h>
#include <errno.h>
#include <linux/videodev2.h>
#include <stb/stb_image.h>        // implemented in gs_io (io/image/stb_impl.cpp)
#include <stb/stb_image_write.h>  // likewise

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gs/capture/v4l2_source.h"
#include "support/alloc_counter.h"
#include "support/temp_dir.h"

namespace gs::capture {
namespace {

constexpr uint32_t kYUYV = V4L2_PIX_FMT_YUYV, kNV12 = V4L2_PIX_FMT_NV12, kMJPG = V4L2_PIX_FMT_MJPEG;

// Frame k's timestamp in microseconds, as a 30 fps driver would stamp it.
int64_t frame_time_us(size_t k) { return 1000000000LL + int64_t(k) * 33333; }

// Generated frame contents. Bytes are a function of (position, frame number) so a frame read from
// the wrong buffer, row or plane shows up as a mismatch.
uint8_t yuyv_byte(uint32_t xb, uint32_t y, size_t k) { return uint8_t(xb * 3 + y * 7 + k * 11); }
uint8_t nv12_y(uint32_t x, uint32_t y, size_t k) { return uint8_t(x + 2 * y + k); }
uint8_t nv12_uv(uint32_t xb, uint32_t r, size_t k) { return uint8_t(128 + xb * 5 + r * 3 + k); }
constexpr uint8_t kPad = 0xEE;  // row padding a driver leaves beyond the visible bytes

struct FakeCamera {
  // What the device is.
  std::string path;
  bool is_v4l2 = true;
  uint32_t caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  std::string card = "Fake Cam", driver = "fakecam", bus = "usb-0000:00:14.0-1";
  std::vector<uint32_t> formats{kYUYV};
  uint32_t default_width = 32, default_height = 8;
  int open_error = 0;          // -errno open() fails with
  uint32_t extra_stride = 0;   // padding bytes per row the driver uses (and reports)
  bool report_zero_bpl = false;  // driver bug: bytesperline and sizeimage reported as 0
  bool timeperframe = true;
  std::vector<uint8_t> jpeg;   // MJPEG payload of every frame

  // Faults to inject.
  std::map<unsigned long, int> eintr;  // request -> how many times it fails with EINTR first
  int poll_eintr = 0, poll_timeouts = 0, dqbuf_eagain = 0;
  long gone_after = -1;                // DQBUF fails with ENODEV once this many frames went out
  size_t frame_limit = SIZE_MAX;       // no more frames after this many (poll times out)

  // Driver state.
  int fd = -1;
  bool streaming = false, gone = false;
  v4l2_pix_format fmt{};
  uint32_t real_stride = 0, real_size = 0;
  v4l2_fract interval{1, 30};
  std::vector<std::vector<uint8_t>> buffers;
  std::vector<int> mapped, queued, qbuf_count;
  int queue[32] = {};
  int queue_head = 0, queue_size = 0;
  size_t delivered = 0;
  int eintr_returned = 0, last_poll_timeout = -2, bad_calls = 0;

  int mapped_count() const { return int(std::count(mapped.begin(), mapped.end(), 1)); }
  int total_qbufs() const {
    int n = 0;
    for (int q : qbuf_count) n += q;
    return n;
  }
  void set_format(uint32_t w, uint32_t h, uint32_t pixfmt) {
    fmt = v4l2_pix_format{};
    fmt.width = w;
    fmt.height = h;
    fmt.pixelformat = pixfmt;
    fmt.field = V4L2_FIELD_NONE;
    if (pixfmt == kYUYV) {
      real_stride = 2 * w + extra_stride;
      real_size = real_stride * h;
    } else if (pixfmt == kNV12) {
      real_stride = w + extra_stride;
      real_size = real_stride * h + real_stride * ((h + 1) / 2);
    } else {
      real_stride = 0;
      real_size = std::max<uint32_t>(w * h * 2, 65536);  // room for any JPEG of this size
    }
    fmt.bytesperline = report_zero_bpl ? 0 : real_stride;
    fmt.sizeimage = report_zero_bpl ? 0 : real_size;
  }
  // Writes frame k into buffer i the way the hardware would; returns bytesused.
  uint32_t fill(int i, size_t k) {
    uint8_t* d = buffers[size_t(i)].data();
    const uint32_t w = fmt.width, h = fmt.height;
    if (fmt.pixelformat == kYUYV) {
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t xb = 0; xb < real_stride; ++xb)
          d[y * real_stride + xb] = xb < 2 * w ? yuyv_byte(xb, y, k) : kPad;
    } else if (fmt.pixelformat == kNV12) {
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < real_stride; ++x) d[y * real_stride + x] = x < w ? nv12_y(x, y, k) : kPad;
      uint8_t* uv = d + real_stride * h;
      for (uint32_t r = 0; r < (h + 1) / 2; ++r)
        for (uint32_t xb = 0; xb < real_stride; ++xb) uv[r * real_stride + xb] = xb < w ? nv12_uv(xb, r, k) : kPad;
    } else {
      const size_t n = std::min<size_t>(jpeg.size(), buffers[size_t(i)].size());
      if (n) std::memcpy(d, jpeg.data(), n);
      return uint32_t(n);
    }
    return real_size;
  }

  int ioctl(unsigned long request, void* arg) {
    auto e = eintr.find(request);
    if (e != eintr.end() && e->second > 0) {
      --e->second;
      ++eintr_returned;
      return -EINTR;
    }
    if (!is_v4l2) return -ENOTTY;
    if (gone) return -ENODEV;
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* c = static_cast<v4l2_capability*>(arg);
        *c = v4l2_capability{};
        std::strncpy(reinterpret_cast<char*>(c->driver), driver.c_str(), sizeof(c->driver) - 1);
        std::strncpy(reinterpret_cast<char*>(c->card), card.c_str(), sizeof(c->card) - 1);
        std::strncpy(reinterpret_cast<char*>(c->bus_info), bus.c_str(), sizeof(c->bus_info) - 1);
        c->capabilities = caps | V4L2_CAP_DEVICE_CAPS | V4L2_CAP_VIDEO_OUTPUT;  // the union over nodes
        c->device_caps = caps;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* d = static_cast<v4l2_fmtdesc*>(arg);
        if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= formats.size()) return -EINVAL;
        d->pixelformat = formats[d->index];
        return 0;
      }
      case VIDIOC_G_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        if (fmt.width == 0) set_format(default_width, default_height, formats[0]);
        f->fmt.pix = fmt;
        return 0;
      }
      case VIDIOC_S_FMT: {
        if (!buffers.empty()) return -EBUSY;
        auto* f = static_cast<v4l2_format*>(arg);
        const v4l2_pix_format& want = f->fmt.pix;
        const bool offered = std::find(formats.begin(), formats.end(), want.pixelformat) != formats.end();
        set_format(std::min(want.width ? want.width : default_width, 1920u) & ~1u,
                   std::min(want.height ? want.height : default_height, 1080u), offered ? want.pixelformat : formats[0]);
        f->fmt.pix = fmt;
        return 0;
      }
      case VIDIOC_G_PARM:
      case VIDIOC_S_PARM: {
        auto* p = static_cast<v4l2_streamparm*>(arg);
        if (!timeperframe) return -ENOTTY;
        if (request == VIDIOC_S_PARM) {
          const v4l2_fract t = p->parm.capture.timeperframe;  // the fake runs at 15 or 30 fps
          interval = (t.numerator > 0 && t.denominator * 1.0 / t.numerator < 22.5) ? v4l2_fract{1, 15} : v4l2_fract{1, 30};
        }
        p->parm.capture = v4l2_captureparm{};
        p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        p->parm.capture.timeperframe = interval;
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        if (r->memory != V4L2_MEMORY_MMAP || r->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return -EINVAL;
        if (streaming) return -EBUSY;
        if (r->count == 0) {
          if (mapped_count() > 0) return -EBUSY;  // the kernel refuses to free mapped buffers
          buffers.clear();
          mapped.clear();
          queued.clear();
          return 0;
        }
        if (!buffers.empty() || fmt.width == 0) return -EBUSY;
        r->count = std::min(r->count, 32u);
        buffers.assign(r->count, std::vector<uint8_t>(real_size, 0));
        mapped.assign(r->count, 0);
        queued.assign(r->count, 0);
        qbuf_count.assign(r->count, 0);
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= buffers.size()) return -EINVAL;
        b->length = real_size;
        b->m.offset = b->index * 0x100000u;
        return 0;
      }
      case VIDIOC_QBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= buffers.size() || queued[b->index] || b->memory != V4L2_MEMORY_MMAP) return -EINVAL;
        queued[b->index] = 1;
        ++qbuf_count[b->index];
        queue[(queue_head + queue_size++) % 32] = int(b->index);
        return 0;
      }
      case VIDIOC_DQBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (!streaming) return -EINVAL;
        if (dqbuf_eagain > 0) {
          --dqbuf_eagain;
          return -EAGAIN;
        }
        if (gone_after >= 0 && delivered == size_t(gone_after)) {
          gone = true;
          return -ENODEV;
        }
        if (queue_size == 0 || delivered >= frame_limit) return -EAGAIN;
        const int i = queue[queue_head];
        queue_head = (queue_head + 1) % 32;
        --queue_size;
        queued[size_t(i)] = 0;
        const size_t k = delivered++;
        b->index = uint32_t(i);
        b->bytesused = fill(i, k);
        b->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_DONE;
        b->field = V4L2_FIELD_NONE;
        b->sequence = uint32_t(k);
        b->timestamp.tv_sec = decltype(b->timestamp.tv_sec)(frame_time_us(k) / 1000000);
        b->timestamp.tv_usec = decltype(b->timestamp.tv_usec)(frame_time_us(k) % 1000000);
        return 0;
      }
      case VIDIOC_STREAMON:
        if (buffers.empty()) return -EINVAL;
        streaming = true;
        delivered = 0;  // drivers restart the sequence count at STREAMON
        return 0;
      case VIDIOC_STREAMOFF:
        streaming = false;
        std::fill(queued.begin(), queued.end(), 0);
        queue_head = queue_size = 0;
        return 0;
      default: return -ENOTTY;
    }
  }
  int poll(int timeout_ms) {
    last_poll_timeout = timeout_ms;
    if (poll_eintr > 0) {
      --poll_eintr;
      return -EINTR;
    }
    if (poll_timeouts > 0) {
      --poll_timeouts;
      return 0;
    }
    if (gone || (gone_after >= 0 && delivered == size_t(gone_after))) return 1;  // POLLERR
    return streaming && queue_size > 0 && delivered < frame_limit ? 1 : 0;
  }
};

class FakeV4l2 final : public V4l2Device {
 public:
  FakeCamera& add(const std::string& path) {
    cams_.push_back(std::make_unique<FakeCamera>());
    cams_.back()->path = path;
    return *cams_.back();
  }
  int open_fds() const {
    int n = 0;
    for (const auto& c : cams_) n += c->fd >= 0;
    return n;
  }
  int open(const std::string& path, int flags) override {
    for (size_t i = 0; i < cams_.size(); ++i) {
      FakeCamera& c = *cams_[i];
      if (c.path != path) continue;
      if (c.open_error) return c.open_error;
      if (c.fd >= 0) return -EBUSY;  // the fake allows one open at a time
      c.fd = 100 + int(i);
      c.fmt = v4l2_pix_format{};
      c.gone = false;
      return c.fd;
    }
    return -ENOENT;
  }
  int close(int fd) override {
    FakeCamera* c = by_fd(fd);
    if (!c) return -EBADF;
    if (c->mapped_count() > 0) ++c->bad_calls;  // closing with live mappings: the source leaked them
    c->fd = -1;
    c->streaming = false;
    c->buffers.clear();
    c->mapped.clear();
    c->queued.clear();
    c->queue_head = c->queue_size = 0;
    return 0;
  }
  int ioctl(int fd, unsigned long request, void* arg) override {
    FakeCamera* c = by_fd(fd);
    return c ? c->ioctl(request, arg) : -EBADF;
  }
  int mmap(size_t length, int fd, int64_t offset, void** out) override {
    FakeCamera* c = by_fd(fd);
    if (!c) return -EBADF;
    const size_t i = size_t(offset / 0x100000);
    if (offset % 0x100000 != 0 || i >= c->buffers.size() || length != c->buffers[i].size() || c->mapped[i]) {
      ++c->bad_calls;
      return -EINVAL;
    }
    c->mapped[i] = 1;
    *out = c->buffers[i].data();
    return 0;
  }
  int munmap(void* addr, size_t length) override {
    for (auto& c : cams_)
      for (size_t i = 0; i < c->buffers.size(); ++i)
        if (c->buffers[i].data() == addr && c->mapped[i] && c->buffers[i].size() == length) {
          c->mapped[i] = 0;
          return 0;
        }
    return -EINVAL;
  }
  int poll(int fd, int timeout_ms) override {
    FakeCamera* c = by_fd(fd);
    return c ? c->poll(timeout_ms) : -EBADF;
  }

 private:
  FakeCamera* by_fd(int fd) {
    for (auto& c : cams_)
      if (c->fd >= 0 && c->fd == fd) return c.get();
    return nullptr;
  }
  std::vector<std::unique_ptr<FakeCamera>> cams_;
};

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Acquires one frame, failing the test on anything else.
FrameView must_acquire(V4l2Source& src, int32_t timeout_ms = 100) {
  FrameView f;
  Expected<AcquireResult> r = src.acquire(timeout_ms, &f);
  REQUIRE_MESSAGE(r.ok(), r.status().to_string());
  REQUIRE(*r == AcquireResult::kFrame);
  return f;
}

// The first mismatching byte of a YUYV frame against the pattern, or -1.
long yuyv_mismatch(const FrameView& f, size_t k) {
  for (int32_t y = 0; y < f.height; ++y)
    for (int32_t xb = 0; xb < 2 * f.width; ++xb)
      if (f.planes[0].data[size_t(y) * size_t(f.planes[0].stride) + size_t(xb)] != yuyv_byte(uint32_t(xb), uint32_t(y), k))
        return long(y) * 100000 + xb;
  return -1;
}
long nv12_mismatch(const FrameView& f, size_t k) {
  for (int32_t y = 0; y < f.height; ++y)
    for (int32_t x = 0; x < f.width; ++x)
      if (f.planes[0].data[size_t(y) * size_t(f.planes[0].stride) + size_t(x)] != nv12_y(uint32_t(x), uint32_t(y), k))
        return long(y) * 100000 + x;
  for (int32_t r = 0; r < (f.height + 1) / 2; ++r)
    for (int32_t xb = 0; xb < f.width; ++xb)
      if (f.planes[1].data[size_t(r) * size_t(f.planes[1].stride) + size_t(xb)] != nv12_uv(uint32_t(xb), uint32_t(r), k))
        return 1000000000L + long(r) * 100000 + xb;
  return -1;
}

void check_clean(const FakeV4l2& fake, const FakeCamera& cam) {
  CHECK(cam.mapped_count() == 0);
  CHECK(fake.open_fds() == 0);
  CHECK(cam.bad_calls == 0);
}

std::vector<uint8_t> make_jpeg(int w, int h) {
  std::vector<uint8_t> rgb(size_t(w * h * 3));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = &rgb[size_t((y * w + x) * 3)];
      p[0] = uint8_t(x * 255 / w);
      p[1] = uint8_t(y * 255 / h);
      p[2] = 128;
    }
  std::vector<uint8_t> jpeg;
  auto append = [](void* ctx, void* data, int size) {
    auto* out = static_cast<std::vector<uint8_t>*>(ctx);
    out->insert(out->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
  };
  REQUIRE(stbi_write_jpg_to_func(append, &jpeg, w, h, 3, rgb.data(), 90) != 0);
  return jpeg;
}

TEST_CASE("V4L2 YUYV frames keep the driver's padded stride and their contents") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.formats = {kMJPG, kYUYV};
  cam.extra_stride = 16;  // a driver aligning rows: bytesperline 2 * 40 + 16
  {
    V4l2Source src("/dev/video0", fake);
    CHECK(std::string(src.name()) == "v4l2:/dev/video0");
    FrameFormat req;
    req.width = 40;
    req.height = 6;
    req.format = PixelFormat::kYUYV;
    FrameFormat got;
    Status s = src.configure(req, &got);
    REQUIRE_MESSAGE(s.ok(), s.to_string());
    CHECK(got.width == 40);
    CHECK(got.height == 6);
    CHECK(got.format == PixelFormat::kYUYV);
    CHECK(got.fps == doctest::Approx(30.0));  // the driver's current rate, read with G_PARM
    CHECK(src.bytes_per_line() == 96);
    CHECK(src.offered_formats() == std::vector<uint32_t>{kMJPG, kYUYV});
    CHECK(src.buffer_count() == 4);
    CHECK(cam.mapped_count() == 4);  // everything is mapped at configure
    REQUIRE(src.start().ok());
    for (size_t k = 0; k < 6; ++k) {
      FrameView f = must_acquire(src);
      CHECK(validate_frame(f).ok());
      CHECK(f.width == 40);
      CHECK(f.height == 6);
      CHECK(f.format == PixelFormat::kYUYV);
      CHECK(f.num_planes == 1);
      CHECK(f.planes[0].stride == 96);
      CHECK(f.planes[0].size == 96u * 6);
      CHECK(f.planes[1].data == nullptr);
      CHECK(f.sequence == k);
      CHECK(f.timestamp_ns == frame_time_us(k) * 1000);
      CHECK(f.buffer_index == int32_t(k % 4));
      CHECK(yuyv_mismatch(f, k) == -1);
      CHECK(f.planes[0].data[80] == kPad);  // the padding is there, the view just skips it
      REQUIRE(src.release(f).ok());
    }
    REQUIRE(src.stop().ok());
    check_clean(fake, cam);
  }
  check_clean(fake, cam);
}

TEST_CASE("V4L2 NV12 frames carry the UV plane after the Y plane") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.formats = {kYUYV, kNV12};
  cam.extra_stride = 8;
  V4l2Source src("/dev/video0", fake);
  FrameFormat req;
  req.width = 24;
  req.height = 10;
  req.format = PixelFormat::kNV12;
  FrameFormat got;
  REQUIRE(src.configure(req, &got).ok());
  CHECK(got.format == PixelFormat::kNV12);
  REQUIRE(src.start().ok());
  for (size_t k = 0; k < 5; ++k) {
    FrameView f = must_acquire(src);
    CHECK(validate_frame(f).ok());
    CHECK(f.num_planes == 2);
    CHECK(f.planes[0].stride == 32);
    CHECK(f.planes[1].stride == 32);
    CHECK(f.planes[0].size == 32u * 10);
    CHECK(f.planes[1].size == 32u * 5);
    CHECK(f.planes[1].data == f.planes[0].data + 32 * 10);
    CHECK(f.sequence == k);
    CHECK(f.timestamp_ns == frame_time_us(k) * 1000);
    CHECK(nv12_mismatch(f, k) == -1);
    REQUIRE(src.release(f).ok());
  }
  REQUIRE(src.stop().ok());
  check_clean(fake, cam);
}

TEST_CASE("V4L2 MJPEG frames carry the whole JPEG") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.formats = {kYUYV, kMJPG};
  cam.jpeg = make_jpeg(16, 8);
  V4l2Source src("/dev/video0", fake, 3);
  FrameFormat req;
  req.width = 16;
  req.height = 8;
  req.format = PixelFormat::kMJPEG;
  FrameFormat got;
  REQUIRE(src.configure(req, &got).ok());
  CHECK(src.buffer_count() == 3);
  REQUIRE(src.start().ok());
  for (size_t k = 0; k < 4; ++k) {
    FrameView f = must_acquire(src);
    CHECK(validate_frame(f).ok());
    CHECK(f.format == PixelFormat::kMJPEG);
    CHECK(f.num_planes == 1);
    CHECK(f.planes[0].stride == 0);
    REQUIRE(f.planes[0].size == cam.jpeg.size());  // bytesused, not the buffer length
    CHECK(std::memcmp(f.planes[0].data, cam.jpeg.data(), cam.jpeg.size()) == 0);
    CHECK(f.sequence == k);
    int w = 0, h = 0, n = 0;
    stbi_uc* rgb = stbi_load_from_memory(f.planes[0].data, int(f.planes[0].size), &w, &h, &n, 3);
    REQUIRE(rgb != nullptr);
    CHECK(w == 16);
    CHECK(h == 8);
    stbi_image_free(rgb);
    REQUIRE(src.release(f).ok());
  }
  // An empty MJPEG buffer is dropped, not handed out.
  cam.jpeg.clear();
  FrameView f;
  Expected<AcquireResult> r = src.acquire(10, &f);
  REQUIRE(r.ok());
  CHECK(*r == AcquireResult::kTimeout);
  REQUIRE(src.stop().ok());
  check_clean(fake, cam);
}

TEST_CASE("V4L2 a format the device does not offer lists the offered ones") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video2");
  cam.card = "Brand Webcam";
  cam.formats = {kYUYV, kMJPG};
  V4l2Source src("/dev/video2", fake);
  FrameFormat req;
  req.format = PixelFormat::kNV12;
  FrameFormat got;
  Status s = src.configure(req, &got);
  REQUIRE_FALSE(s.ok());
  CHECK(s.code() == StatusCode::kUnsupported);
  INFO(s.message());
  CHECK(contains(s.message(), "/dev/video2"));
  CHECK(contains(s.message(), "Brand Webcam"));
  CHECK(contains(s.message(), "NV12"));
  CHECK(contains(s.message(), "YUYV, MJPG"));
  check_clean(fake, cam);
  // The source is still usable with a format that is offered.
  req.format = PixelFormat::kYUYV;
  REQUIRE(src.configure(req, &got).ok());
  CHECK(got.width == 32);  // 0 asked: the device's current size
  CHECK(got.height == 8);
}

TEST_CASE("V4L2 EINTR on ioctls and poll is retried") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  for (unsigned long req : {VIDIOC_QUERYCAP, VIDIOC_ENUM_FMT, VIDIOC_S_FMT, VIDIOC_G_PARM, VIDIOC_REQBUFS,
                            VIDIOC_QUERYBUF, VIDIOC_QBUF, VIDIOC_STREAMON, VIDIOC_DQBUF, VIDIOC_STREAMOFF})
    cam.eintr[req] = 3;
  cam.poll_eintr = 2;
  V4l2Source src("/dev/video0", fake);
  FrameFormat req;
  req.format = PixelFormat::kYUYV;
  FrameFormat got;
  Status s = src.configure(req, &got);
  REQUIRE_MESSAGE(s.ok(), s.to_string());
  REQUIRE(src.start().ok());
  FrameView f = must_acquire(src);
  CHECK(yuyv_mismatch(f, 0) == -1);
  REQUIRE(src.release(f).ok());
  REQUIRE(src.stop().ok());
  CHECK(cam.eintr_returned == 30);
  CHECK(cam.poll_eintr == 0);
  check_clean(fake, cam);
}

TEST_CASE("V4L2 an ioctl interrupted without end gives up") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.eintr[VIDIOC_QUERYCAP] = 1000000;
  V4l2Source src("/dev/video0", fake);
  FrameFormat got;
  Status s = src.configure(FrameFormat{}, &got);
  REQUIRE_FALSE(s.ok());
  CHECK(contains(s.message(), "VIDIOC_QUERYCAP"));
  CHECK(cam.eintr_returned == kXioctlMaxRetries + 1);
  check_clean(fake, cam);
}

TEST_CASE("V4L2 EAGAIN from DQBUF is a timeout and the frame follows") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  V4l2Source src("/dev/video0", fake);
  FrameFormat got;
  REQUIRE(src.configure(FrameFormat{}, &got).ok());
  REQUIRE(src.start().ok());
  cam.dqbuf_eagain = 1;
  FrameView f;
  Expected<AcquireResult> r = src.acquire(50, &f);
  REQUIRE(r.ok());
  CHECK(*r == AcquireResult::kTimeout);
  f = must_acquire(src);
  CHECK(f.sequence == 0);
  CHECK(yuyv_mismatch(f, 0) == -1);
  REQUIRE(src.release(f).ok());
}

TEST_CASE("V4L2 poll timeouts are reported as timeouts") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.frame_limit = 2;
  V4l2Source src("/dev/video0", fake);
  FrameFormat got;
  REQUIRE(src.configure(FrameFormat{}, &got).ok());
  REQUIRE(src.start().ok());
  cam.poll_timeouts = 1;
  FrameView f;
  Expected<AcquireResult> r = src.acquire(25, &f);
  REQUIRE(r.ok());
  CHECK(*r == AcquireResult::kTimeout);
  CHECK(cam.last_poll_timeout == 25);
  for (size_t k = 0; k < 2; ++k) {
    f = must_acquire(src, -1);
    CHECK(cam.last_poll_timeout == -1);
    CHECK(f.sequence == k);
    REQUIRE(src.release(f).ok());
  }
  r = src.acquire(0, &f);  // the camera has stopped sending
  REQUIRE(r.ok());
  CHECK(*r == AcquireResult::kTimeout);
}

TEST_CASE("V4L2 a device disappearing mid-stream is a clear error and stop still cleans up") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video1");
  cam.gone_after = 3;
  V4l2Source src("/dev/video1", fake);
  FrameFormat got;
  REQUIRE(src.configure(FrameFormat{}, &got).ok());
  REQUIRE(src.start().ok());
  FrameView held = must_acquire(src);  // the caller still holds a frame when the cable is pulled
  for (int k = 1; k < 3; ++k) REQUIRE(src.release(must_acquire(src)).ok());
  FrameView f;
  Expected<AcquireResult> r = src.acquire(100, &f);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().code() == StatusCode::kIoError);
  CHECK(r.status().message() == "device /dev/video1 disappeared mid-stream (frame 3)");
  r = src.acquire(100, &f);  // stays failed
  REQUIRE_FALSE(r.ok());
  CHECK(contains(r.status().message(), "disappeared"));
  CHECK_FALSE(src.release(held).ok());
  Status s = src.stop();
  CHECK_MESSAGE(s.ok(), s.to_string());
  check_clean(fake, cam);
  CHECK(src.stop().ok());  // idempotent
  CHECK(src.release(held).ok());  // after stop there is nothing left to give back
}

TEST_CASE("V4L2 released buffers are requeued round the ring") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  {
    V4l2Source src("/dev/video0", fake, 4);
    FrameFormat got;
    REQUIRE(src.configure(FrameFormat{}, &got).ok());
    REQUIRE(src.start().ok());
    CHECK(cam.total_qbufs() == 4);
    for (size_t k = 0; k < 13; ++k) {
      FrameView f = must_acquire(src);
      CHECK(f.buffer_index == int32_t(k % 4));
      CHECK(f.sequence == k);
      CHECK(yuyv_mismatch(f, k) == -1);
      REQUIRE(src.release(f).ok());
    }
    CHECK(cam.total_qbufs() == 4 + 13);
    CHECK(cam.qbuf_count == std::vector<int>{5, 4, 4, 4});  // index 0 held frames 0, 4, 8 and 12

    // Releasing twice and releasing a foreign index are caller bugs.
    FrameView f = must_acquire(src);
    REQUIRE(src.release(f).ok());
    CHECK_FALSE(src.release(f).ok());
    FrameView bogus;
    bogus.buffer_index = 9;
    CHECK_FALSE(src.release(bogus).ok());

    // Holding the whole ring: acquire says so instead of waiting for a frame that cannot come.
    FrameView held[4];
    for (FrameView& h : held) h = must_acquire(src);
    Expected<AcquireResult> r = src.acquire(10, &f);
    REQUIRE_FALSE(r.ok());
    CHECK(contains(r.status().message(), "release a frame"));
    REQUIRE(src.release(held[2]).ok());
    f = must_acquire(src);
    CHECK(f.buffer_index == held[2].buffer_index);
    // The source goes out of scope streaming with four frames held: the destructor cleans up.
  }
  check_clean(fake, cam);
}

TEST_CASE("V4L2 open errors name the device and the fix") {
  FakeV4l2 fake;
  fake.add("/dev/video3").open_error = -EACCES;
  fake.add("/dev/video4").open_error = -EPERM;
  FrameFormat got;
  {
    V4l2Source src("/dev/video7", fake);
    Status s = src.configure(FrameFormat{}, &got);
    CHECK(s.code() == StatusCode::kIoError);
    CHECK(s.message() == "no such device /dev/video7");
  }
  for (const char* path : {"/dev/video3", "/dev/video4"}) {
    V4l2Source src(path, fake);
    Status s = src.configure(FrameFormat{}, &got);
    CHECK(s.message() == std::string("permission denied opening ") + path + " (is your user in the 'video' group?)");
  }
  V4l2Source src("/dev/video7", fake);
  CHECK_FALSE(src.start().ok());  // not configured
  FrameView f;
  CHECK_FALSE(src.acquire(0, &f).ok());
  CHECK(src.stop().ok());
}

TEST_CASE("V4L2 devices that cannot capture or stream are refused") {
  FakeV4l2 fake;
  FakeCamera& rw = fake.add("/dev/video0");
  rw.caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
  FakeCamera& out = fake.add("/dev/video1");
  out.caps = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING;
  FakeCamera& mplane = fake.add("/dev/video2");
  mplane.caps = V4L2_CAP_VIDEO_CAPTURE_MPLANE | V4L2_CAP_STREAMING;
  FakeCamera& tty = fake.add("/dev/video3");
  tty.is_v4l2 = false;
  FrameFormat got;
  const char* expect[] = {"does not support streaming I/O", "is not a video capture device", "multi-planar",
                          "/dev/video3 is not a V4L2 device"};
  for (int i = 0; i < 4; ++i) {
    const std::string path = "/dev/video" + std::to_string(i);
    V4l2Source src(path, fake);
    Status s = src.configure(FrameFormat{}, &got);
    REQUIRE_FALSE(s.ok());
    INFO(s.message());
    CHECK(s.code() == StatusCode::kUnsupported);
    CHECK(contains(s.message(), path));
    CHECK(contains(s.message(), expect[i]));
    CHECK(fake.open_fds() == 0);
  }
}

TEST_CASE("V4L2 a driver reporting bytesperline 0 is clamped to the minimum") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.formats = {kYUYV, kNV12};
  cam.report_zero_bpl = true;
  for (PixelFormat pf : {PixelFormat::kYUYV, PixelFormat::kNV12}) {
    V4l2Source src("/dev/video0", fake);
    FrameFormat req;
    req.width = 32;
    req.height = 8;
    req.format = pf;
    FrameFormat got;
    REQUIRE(src.configure(req, &got).ok());
    const int32_t stride = pf == PixelFormat::kYUYV ? 64 : 32;
    CHECK(src.bytes_per_line() == stride);
    CHECK(src.image_size() == (pf == PixelFormat::kYUYV ? 64u * 8 : 32u * 12));
    REQUIRE(src.start().ok());
    FrameView f = must_acquire(src);
    CHECK(validate_frame(f).ok());
    CHECK(f.planes[0].stride == stride);
    CHECK((pf == PixelFormat::kYUYV ? yuyv_mismatch(f, 0) : nv12_mismatch(f, 0)) == -1);
    REQUIRE(src.release(f).ok());
    REQUIRE(src.stop().ok());
    check_clean(fake, cam);
  }
}

TEST_CASE("V4L2 frame rate is set when the driver supports it") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  FrameFormat req;
  req.fps = 15;
  FrameFormat got;
  {
    V4l2Source src("/dev/video0", fake);
    REQUIRE(src.configure(req, &got).ok());
    CHECK(got.fps == doctest::Approx(15.0));
    CHECK(cam.interval.denominator == 15u);
  }
  cam.timeperframe = false;
  V4l2Source src("/dev/video0", fake);
  REQUIRE(src.configure(req, &got).ok());
  CHECK(got.fps == 0.0);  // unknown: the camera runs at its own rate
}

TEST_CASE("V4L2 acquire and release allocate nothing") {
  FakeV4l2 fake;
  FakeCamera& cam = fake.add("/dev/video0");
  cam.formats = {kNV12};
  V4l2Source src("/dev/video0", fake);
  FrameFormat req;
  req.format = PixelFormat::kNV12;
  FrameFormat got;
  REQUIRE(src.configure(req, &got).ok());
  REQUIRE(src.start().ok());
  REQUIRE(src.release(must_acquire(src)).ok());  // warm-up
  cam.dqbuf_eagain = 3;  // the timeout path must not allocate either
  cam.eintr[VIDIOC_DQBUF] = 5;
  int frames = 0, timeouts = 0, errors = 0;
  test::AllocationScope scope;
  for (int i = 0; i < 20; ++i) {
    FrameView f;
    Expected<AcquireResult> r = src.acquire(10, &f);
    if (!r.ok()) {
      ++errors;
      continue;
    }
    if (*r == AcquireResult::kTimeout) {
      ++timeouts;
      continue;
    }
    ++frames;
    if (!src.release(f).ok()) ++errors;
  }
  const uint64_t allocations = scope.count();
  CHECK(allocations == 0);
  CHECK(errors == 0);
  CHECK(timeouts == 3);
  CHECK(frames == 17);
}

TEST_CASE("V4L2 device listing over a fake dev dir") {
  test::TempDir dir("gs_v4l2");
  for (const char* name : {"video0", "video1", "video10", "video2", "videoX", "vbi0", "video"})
    std::ofstream(dir / name) << "";
  FakeV4l2 fake;
  FakeCamera& cam = fake.add(dir / "video0");
  cam.formats = {kYUYV, kMJPG};
  FakeCamera& meta = fake.add(dir / "video1");  // the UVC metadata node of the same camera
  meta.caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
  FakeCamera& locked = fake.add(dir / "video10");
  locked.open_error = -EACCES;
  FakeCamera& second = fake.add(dir / "video2");
  second.card = "Second";
  second.driver = "uvcvideo";
  second.formats = {kNV12};

  Expected<std::vector<V4l2DeviceInfo>> list = list_v4l2_devices(fake, dir.path());
  REQUIRE_MESSAGE(list.ok(), list.status().to_string());
  REQUIRE(list->size() == 3);
  const V4l2DeviceInfo& a = (*list)[0];
  CHECK(a.path == dir / "video0");
  CHECK(a.card == "Fake Cam");
  CHECK(a.driver == "fakecam");
  CHECK(a.bus == "usb-0000:00:14.0-1");
  CHECK(a.formats == std::vector<uint32_t>{kYUYV, kMJPG});
  CHECK(a.error.empty());
  const V4l2DeviceInfo& b = (*list)[1];
  CHECK(b.path == dir / "video2");
  CHECK(b.card == "Second");
  CHECK(b.driver == "uvcvideo");
  CHECK(b.formats == std::vector<uint32_t>{kNV12});
  const V4l2DeviceInfo& c = (*list)[2];
  CHECK(c.path == dir / "video10");
  CHECK(contains(c.error, "permission denied"));
  CHECK(fake.open_fds() == 0);

  test::TempDir empty("gs_v4l2_empty");
  list = list_v4l2_devices(fake, empty.path() + "/");
  REQUIRE(list.ok());
  CHECK(list->empty());
  list = list_v4l2_devices(fake, empty / "missing");
  CHECK_FALSE(list.ok());
}

TEST_CASE("V4L2 the real device layer reports a missing device clearly") {
  std::error_code ec;
  if (std::filesystem::exists("/dev/video0", ec)) {
    MESSAGE("/dev/video0 exists here; skipping the missing-device check");
    return;
  }
  V4l2Source src("/dev/video0", system_v4l2_device());
  FrameFormat got;
  Status s = src.configure(FrameFormat{}, &got);
  CHECK(s.message() == "no such device /dev/video0");
  CHECK(src.stop().ok());
  Expected<std::vector<V4l2DeviceInfo>> list = list_v4l2_devices(system_v4l2_device());
  CHECK(list.ok());  // whatever is there, listing /dev works
}

}  // namespace
}  // namespace gs::capture
