// SPDX-License-Identifier: MIT
// The handful of system calls a V4L2 capture source makes (open, close, ioctl, mmap, munmap, poll),
// behind an interface so the source can be driven by an in-memory fake in tests: this machine and CI
// have no /dev/video* and cannot create one (no kernel modules, no CUSE), so the fake is the only way
// the streaming state machine, the error paths and the driver-bug workarounds get exercised.
// Every call reports failure as a negative errno value instead of -1 + errno, because a fake then
// needs no thread-local state and a caller cannot lose errno to an intervening libc call.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace gs::capture {

class V4l2Device {
 public:
  virtual ~V4l2Device() = default;
  // Returns a file descriptor (>= 0) or -errno. flags are open(2) flags (O_RDWR | O_NONBLOCK).
  virtual int open(const std::string& path, int flags) = 0;
  // Returns 0 or -errno.
  virtual int close(int fd) = 0;
  // Returns the ioctl's non-negative result or -errno (-EINTR included: see xioctl).
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  // Maps length bytes of the device at offset (from VIDIOC_QUERYBUF) shared and read/write;
  // returns 0 with *out set, or -errno.
  virtual int mmap(size_t length, int fd, int64_t offset, void** out) = 0;
  // Returns 0 or -errno.
  virtual int munmap(void* addr, size_t length) = 0;
  // Waits for the fd to become readable; timeout_ms < 0 waits forever. Returns > 0 when readable or
  // in error (a vanished device is reported by the VIDIOC_DQBUF that follows), 0 on timeout, -errno.
  virtual int poll(int fd, int timeout_ms) = 0;
};

// The real system calls.
V4l2Device& system_v4l2_device();

// ioctl retried while it fails with EINTR, at most kXioctlMaxRetries extra times (a signal storm
// must not hang capture forever; after that -EINTR is returned like any other error).
constexpr int kXioctlMaxRetries = 64;
int xioctl(V4l2Device& device, int fd, unsigned long request, void* arg);

}  // namespace gs::capture
