// SPDX-License-Identifier: MIT
// The real V4L2 device layer: thin wrappers that turn the libc "-1 and errno" convention into the
// "-errno" one of gs/capture/v4l2_device.h, plus the EINTR-retrying xioctl used for every request.
#include "gs/capture/v4l2_device.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace gs::capture {
namespace {

class SystemV4l2Device final : public V4l2Device {
 public:
  int open(const std::string& path, int flags) override {
    const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
    return fd >= 0 ? fd : -errno;
  }
  int close(int fd) override { return ::close(fd) == 0 ? 0 : -errno; }
  int ioctl(int fd, unsigned long request, void* arg) override {
    const int r = ::ioctl(fd, request, arg);
    return r >= 0 ? r : -errno;
  }
  int mmap(size_t length, int fd, int64_t offset, void** out) override {
    void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, static_cast<off_t>(offset));
    if (p == MAP_FAILED) return -errno;
    *out = p;
    return 0;
  }
  int munmap(void* addr, size_t length) override { return ::munmap(addr, length) == 0 ? 0 : -errno; }
  int poll(int fd, int timeout_ms) override {
    pollfd p{};
    p.fd = fd;
    p.events = POLLIN;
    const int r = ::poll(&p, 1, timeout_ms < 0 ? -1 : timeout_ms);
    return r >= 0 ? r : -errno;
  }
};

}  // namespace

V4l2Device& system_v4l2_device() {
  static SystemV4l2Device device;
  return device;
}

int xioctl(V4l2Device& device, int fd, unsigned long request, void* arg) {
  int r = device.ioctl(fd, request, arg);
  for (int retry = 0; r == -EINTR && retry < kXioctlMaxRetries; ++retry) r = device.ioctl(fd, request, arg);
  return r;
}

}  // namespace gs::capture
