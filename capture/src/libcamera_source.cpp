// SPDX-License-Identifier: MIT
// LibcameraSource over libcamera's C++ API: a process-wide CameraManager, one camera, one stream,
// one Request per allocated buffer. The completion callback runs on libcamera's internal thread, so
// it does the least possible: push the request's index into a lock-free SPSC ring and bump an
// eventfd (one write syscall, no lock, no allocation). Everything else (checking the frame status,
// building the FrameView, re-queueing) happens on the caller's thread in acquire/release. Only the
// "no camera" paths can run on a machine without cameras; the capture paths follow the sequence
// verified with libcamera's own tools (TOOLCHAIN.md section 3).
#include "gs/capture/libcamera_source.h"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/control_ids.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/property_ids.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>
#include <libcamera/version.h>

namespace gs::capture {
namespace {

namespace lc = libcamera;

// Fixed-capacity single-producer (libcamera's thread) / single-consumer (acquire) ring of request
// indices. Each request is in the ring at most once, so a capacity >= the request count never fills.
class IndexRing {
 public:
  static constexpr uint32_t kCapacity = LibcameraSource::kMaxBuffers;
  static_assert((kCapacity & (kCapacity - 1)) == 0, "capacity must be a power of two");

  bool push(uint32_t v) {
    const uint32_t t = tail_.load(std::memory_order_relaxed);
    if (t - head_.load(std::memory_order_acquire) == kCapacity) return false;
    slots_[t & (kCapacity - 1)] = v;
    tail_.store(t + 1, std::memory_order_release);
    return true;
  }
  bool pop(uint32_t* v) {
    const uint32_t h = head_.load(std::memory_order_relaxed);
    if (h == tail_.load(std::memory_order_acquire)) return false;
    *v = slots_[h & (kCapacity - 1)];
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  void clear() {  // only when the producer is quiet (camera stopped)
    head_.store(tail_.load(std::memory_order_acquire), std::memory_order_release);
  }

 private:
  alignas(64) std::atomic<uint32_t> head_{0};  // separate lines: producer and consumer do not share
  alignas(64) std::atomic<uint32_t> tail_{0};
  uint32_t slots_[kCapacity] = {};
};

// libcamera forbids two CameraManagers in one process; share one among every user and stop it when
// the last goes away.
std::shared_ptr<lc::CameraManager> shared_manager(Status* error) {
  static std::mutex mu;
  static std::weak_ptr<lc::CameraManager> weak;
  std::lock_guard<std::mutex> lock(mu);
  if (auto m = weak.lock()) return m;
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", /*overwrite=*/0);
  auto m = std::shared_ptr<lc::CameraManager>(new lc::CameraManager(), [](lc::CameraManager* p) {
    p->stop();
    delete p;
  });
  const int r = m->start();
  if (r < 0) {
    *error = io_error(std::string("libcamera: cannot start the camera manager: ") + std::strerror(-r));
    return nullptr;
  }
  weak = m;
  return m;
}

CameraInfo info_of(const lc::Camera& cam) {
  CameraInfo i;
  i.id = cam.id();
  if (auto model = cam.properties().get(lc::properties::Model)) i.model = *model;
  return i;
}

std::string describe(const std::vector<std::shared_ptr<lc::Camera>>& cams) {
  if (cams.empty()) return "no cameras found";
  std::string s = "available: ";
  for (size_t i = 0; i < cams.size(); ++i) {
    const CameraInfo info = info_of(*cams[i]);
    if (i) s += ", ";
    s += std::to_string(i) + " = " + info.id + (info.model.empty() ? "" : " (" + info.model + ")");
  }
  return s;
}

bool to_libcamera(PixelFormat f, lc::PixelFormat* out) {
  switch (f) {
    case PixelFormat::kYUYV: *out = lc::formats::YUYV; return true;
    case PixelFormat::kNV12: *out = lc::formats::NV12; return true;
    case PixelFormat::kMJPEG: *out = lc::formats::MJPEG; return true;
    default: return false;  // libcamera's RGB888 is BGR in memory; hbgs converts from YUV instead
  }
}

bool from_libcamera(const lc::PixelFormat& f, PixelFormat* out) {
  if (f == lc::formats::YUYV) return *out = PixelFormat::kYUYV, true;
  if (f == lc::formats::NV12) return *out = PixelFormat::kNV12, true;
  if (f == lc::formats::MJPEG) return *out = PixelFormat::kMJPEG, true;
  return false;
}

std::string offered_formats(const lc::StreamConfiguration& cfg) {
  std::string s;
  for (const lc::PixelFormat& f : cfg.formats().pixelformats()) {
    PixelFormat mine;
    if (!from_libcamera(f, &mine)) continue;
    if (!s.empty()) s += ", ";
    s += pixel_format_name(mine);
  }
  return s.empty() ? "none that hbgs handles (yuyv, nv12, mjpeg)" : s;
}

struct Mapping {
  int fd = -1;
  void* addr = MAP_FAILED;
  size_t length = 0;
};

}  // namespace

struct LibcameraSource::Impl {
  std::shared_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  bool acquired = false, configured = false, running = false;
  std::unique_ptr<lc::CameraConfiguration> config;
  lc::Stream* stream = nullptr;
  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<lc::Request>> requests;
  std::vector<std::vector<Mapping>> maps;  // per buffer, one mapping per distinct dmabuf fd
  std::vector<uint8_t> out;                // per request: handed out and not yet released
  FrameFormat format;
  uint32_t stride = 0;
  int event_fd = -1;
  IndexRing ring;

  // Runs on libcamera's thread: record and wake, nothing else.
  void on_complete(lc::Request* request) {
    ring.push(uint32_t(request->cookie()));
    const uint64_t one = 1;
    ssize_t ignored = ::write(event_fd, &one, sizeof(one));
    (void)ignored;  // the counter cannot overflow with <= kMaxBuffers pending wakes
  }

  // The address of byte `offset` of a buffer plane.
  const uint8_t* plane_address(size_t buffer, const lc::FrameBuffer::Plane& p) const {
    for (const Mapping& m : maps[buffer])
      if (m.fd == p.fd.get()) return static_cast<const uint8_t*>(m.addr) + p.offset;
    return nullptr;
  }

  void teardown() {
    if (running && camera) camera->stop();
    running = false;
    if (camera) camera->requestCompleted.disconnect(this);
    requests.clear();
    for (auto& per_buffer : maps)
      for (Mapping& m : per_buffer)
        if (m.addr != MAP_FAILED) ::munmap(m.addr, m.length);
    maps.clear();
    allocator.reset();
    config.reset();
    if (acquired && camera) camera->release();
    acquired = false;
    camera.reset();
    if (event_fd >= 0) ::close(event_fd);
    event_fd = -1;
  }
  ~Impl() { teardown(); }
};

Expected<std::vector<CameraInfo>> list_libcamera_cameras() {
  Status error;
  auto manager = shared_manager(&error);
  if (!manager) return error;
  std::vector<CameraInfo> out;
  for (const auto& cam : manager->cameras()) out.push_back(info_of(*cam));
  return out;
}

LibcameraSource::LibcameraSource(std::string camera) : camera_(std::move(camera)), name_("libcamera:" + camera_) {}
LibcameraSource::~LibcameraSource() = default;

Status LibcameraSource::configure(const FrameFormat& requested, FrameFormat* actual) {
  impl_.reset();
  auto m = std::make_unique<Impl>();
  Status error;
  m->manager = shared_manager(&error);
  if (!m->manager) return error;

  // Find the camera: an exact id first, then a decimal index into the list.
  const auto cams = m->manager->cameras();
  m->camera = m->manager->get(camera_);
  if (!m->camera && !camera_.empty() && camera_.size() < 6 &&
      std::all_of(camera_.begin(), camera_.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
    const size_t index = size_t(std::stoul(camera_));
    if (index < cams.size()) m->camera = cams[index];
  }
  if (!m->camera) return invalid_argument("libcamera: no camera '" + camera_ + "' (" + describe(cams) + ")");
  if (m->camera->acquire() < 0)
    return io_error(name_ + ": camera is in use by another process or source");
  m->acquired = true;

  m->config = m->camera->generateConfiguration(std::vector<lc::StreamRole>{lc::StreamRole::VideoRecording});
  if (!m->config || m->config->size() != 1)
    return unsupported(name_ + ": the camera offers no single-stream video configuration");
  lc::StreamConfiguration& cfg = m->config->at(0);
  lc::PixelFormat want;
  if (!to_libcamera(requested.format, &want))
    return unsupported(name_ + ": format " + pixel_format_name(requested.format) + " is not offered (offered: " +
                       offered_formats(cfg) + ")");
  cfg.pixelFormat = want;
  if (requested.width > 0 && requested.height > 0) cfg.size = lc::Size(unsigned(requested.width), unsigned(requested.height));
  if (cfg.bufferCount == 0) cfg.bufferCount = 4;
  if (cfg.bufferCount > kMaxBuffers) cfg.bufferCount = kMaxBuffers;

  if (m->config->validate() == lc::CameraConfiguration::Invalid)
    return unsupported(name_ + ": configuration " + cfg.toString() + " rejected (offered formats: " +
                       offered_formats(cfg) + ")");
  // validate() may have adjusted the format, size or buffer count; accept what we can deliver.
  PixelFormat got;
  if (!from_libcamera(cfg.pixelFormat, &got))
    return unsupported(name_ + ": camera substituted " + cfg.pixelFormat.toString() + " for " +
                       pixel_format_name(requested.format) + " (offered: " + offered_formats(cfg) + ")");
  if (cfg.bufferCount > kMaxBuffers)
    return unsupported(name_ + ": camera needs " + std::to_string(cfg.bufferCount) + " buffers, more than " +
                       std::to_string(kMaxBuffers));
  int r = m->camera->configure(m->config.get());
  if (r < 0) return io_error(name_ + ": configure failed: " + std::strerror(-r));
  m->stream = cfg.stream();
  m->stride = cfg.stride;
  m->format.width = int32_t(cfg.size.width);
  m->format.height = int32_t(cfg.size.height);
  m->format.format = got;
  m->format.fps = requested.fps;

  m->event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (m->event_fd < 0) return io_error(name_ + ": eventfd: " + std::strerror(errno));

  // Buffers: allocate, map every plane's dmabuf once, and pair each buffer with its request.
  m->allocator = std::make_unique<lc::FrameBufferAllocator>(m->camera);
  r = m->allocator->allocate(m->stream);
  if (r < 0) return io_error(name_ + ": buffer allocation failed: " + std::strerror(-r));
  const auto& buffers = m->allocator->buffers(m->stream);
  if (buffers.empty() || buffers.size() > kMaxBuffers)
    return io_error(name_ + ": allocator returned " + std::to_string(buffers.size()) + " buffers");
  m->maps.resize(buffers.size());
  m->out.assign(buffers.size(), 0);
  for (size_t b = 0; b < buffers.size(); ++b) {
    lc::FrameBuffer* buffer = buffers[b].get();
    for (const lc::FrameBuffer::Plane& p : buffer->planes()) {
      const int fd = p.fd.get();
      const size_t end = size_t(p.offset) + p.length;
      Mapping* found = nullptr;
      for (Mapping& mm : m->maps[b])
        if (mm.fd == fd) found = &mm;
      if (!found) {
        m->maps[b].push_back(Mapping{fd, MAP_FAILED, 0});
        found = &m->maps[b].back();
      }
      found->length = std::max(found->length, end);
    }
    for (Mapping& mm : m->maps[b]) {
      mm.addr = ::mmap(nullptr, mm.length, PROT_READ, MAP_SHARED, mm.fd, 0);
      if (mm.addr == MAP_FAILED) return io_error(name_ + ": mmap of buffer " + std::to_string(b) + ": " + std::strerror(errno));
    }
    std::unique_ptr<lc::Request> req = m->camera->createRequest(b);  // cookie = index into requests
    if (!req) return io_error(name_ + ": cannot create request " + std::to_string(b));
    r = req->addBuffer(m->stream, buffer);
    if (r < 0) return io_error(name_ + ": cannot attach buffer " + std::to_string(b) + ": " + std::strerror(-r));
    m->requests.push_back(std::move(req));
  }
  m->camera->requestCompleted.connect(m.get(), &Impl::on_complete);
  m->configured = true;
  impl_ = std::move(m);
  if (actual) *actual = impl_->format;
  return Status::Ok();
}

Status LibcameraSource::start() {
  if (!impl_ || !impl_->configured) return invalid_argument(name_ + ": start before a successful configure");
  Impl& m = *impl_;
  if (m.running) return Status::Ok();
  lc::ControlList controls(lc::controls::controls);
  if (m.format.fps > 0) {
    const int64_t frame_us = int64_t(1e6 / m.format.fps);
    const int64_t limits[2] = {frame_us, frame_us};
    controls.set(lc::controls::FrameDurationLimits, lc::Span<const int64_t, 2>(limits));
  }
  int r = m.camera->start(&controls);
  if (r < 0) return io_error(name_ + ": start failed: " + std::strerror(-r));
  m.running = true;
  m.ring.clear();
  std::fill(m.out.begin(), m.out.end(), uint8_t(0));
  for (auto& req : m.requests) {
    r = m.camera->queueRequest(req.get());
    if (r < 0) {
      m.camera->stop();
      m.running = false;
      return io_error(name_ + ": queueing a request failed: " + std::strerror(-r));
    }
  }
  return Status::Ok();
}

Expected<AcquireResult> LibcameraSource::acquire(int32_t timeout_ms, FrameView* frame) {
  if (!impl_ || !impl_->running) return invalid_argument(name_ + ": acquire before start");
  Impl& m = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms < 0 ? 0 : timeout_ms);
  for (;;) {
    uint32_t index;
    while (m.ring.pop(&index)) {
      if (index >= m.requests.size()) continue;
      lc::Request* req = m.requests[index].get();
      const lc::FrameBuffer* buffer = req->findBuffer(m.stream);
      const bool good = req->status() == lc::Request::RequestComplete && buffer &&
                        buffer->metadata().status == lc::FrameMetadata::FrameSuccess;
      if (!good) {
        // A failed or cancelled frame: give the buffer straight back; the sequence gap shows it.
        req->reuse(lc::Request::ReuseBuffers);
        if (m.running) m.camera->queueRequest(req);
        continue;
      }
      const lc::FrameMetadata& md = buffer->metadata();
      const auto& planes = buffer->planes();
      FrameView v;
      v.width = m.format.width;
      v.height = m.format.height;
      v.format = m.format.format;
      v.timestamp_ns = int64_t(md.timestamp);
      v.sequence = md.sequence;
      v.buffer_index = int32_t(index);
      const uint8_t* base = m.plane_address(index, planes[0]);
      if (!base) return io_error(name_ + ": completed buffer " + std::to_string(index) + " is not mapped");
      const size_t used0 = md.planes().size() > 0 ? md.planes()[0].bytesused : planes[0].length;
      if (m.format.format == PixelFormat::kNV12) {
        const size_t y_size = size_t(m.stride) * size_t(v.height);
        v.num_planes = 2;
        v.planes[0] = FramePlane{base, y_size, int32_t(m.stride)};
        if (planes.size() >= 2) {  // a separate chroma plane
          v.planes[1] = FramePlane{m.plane_address(index, planes[1]), planes[1].length, int32_t(m.stride)};
        } else {  // contiguous: chroma follows the luma rows
          v.planes[1] = FramePlane{base + y_size, planes[0].length > y_size ? planes[0].length - y_size : 0,
                                   int32_t(m.stride)};
        }
      } else if (m.format.format == PixelFormat::kMJPEG) {
        v.num_planes = 1;
        v.planes[0] = FramePlane{base, used0, 0};
      } else {
        v.num_planes = 1;
        v.planes[0] = FramePlane{base, planes[0].length, int32_t(m.stride)};
      }
      m.out[index] = 1;
      *frame = v;
      return AcquireResult::kFrame;
    }
    // Nothing completed: sleep on the eventfd until the callback writes or the timeout passes.
    int wait_ms = -1;
    if (timeout_ms >= 0) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return AcquireResult::kTimeout;
      wait_ms = int(left.count());
    }
    pollfd p{m.event_fd, POLLIN, 0};
    const int r = ::poll(&p, 1, wait_ms);
    if (r < 0 && errno != EINTR) return io_error(name_ + ": poll: " + std::strerror(errno));
    if (r > 0) {
      uint64_t count;
      ssize_t ignored = ::read(m.event_fd, &count, sizeof(count));  // reset the counter
      (void)ignored;
    }
    if (r == 0 && timeout_ms >= 0) return AcquireResult::kTimeout;
  }
}

Status LibcameraSource::release(const FrameView& frame) {
  if (!impl_) return invalid_argument(name_ + ": release before configure");
  Impl& m = *impl_;
  if (!m.running) return Status::Ok();  // stop() already took every buffer back
  const int32_t i = frame.buffer_index;
  if (i < 0 || size_t(i) >= m.requests.size() || !m.out[size_t(i)])
    return invalid_argument(name_ + ": release of buffer " + std::to_string(i) + " that is not out");
  m.out[size_t(i)] = 0;
  lc::Request* req = m.requests[size_t(i)].get();
  req->reuse(lc::Request::ReuseBuffers);
  const int r = m.camera->queueRequest(req);
  if (r < 0) return io_error(name_ + ": re-queueing buffer " + std::to_string(i) + " failed: " + std::strerror(-r));
  return Status::Ok();
}

Status LibcameraSource::stop() {
  if (!impl_ || !impl_->running) return Status::Ok();
  Impl& m = *impl_;
  m.running = false;
  // Stopping completes every queued request as cancelled (through the callback); drop them all.
  const int r = m.camera->stop();
  m.ring.clear();
  std::fill(m.out.begin(), m.out.end(), uint8_t(0));
  if (r < 0) return io_error(name_ + ": stop failed: " + std::strerror(-r));
  return Status::Ok();
}

}  // namespace gs::capture
