// SPDX-License-Identifier: MIT
// FrameSource: the one interface every frame producer implements (V4L2 device, libcamera camera,
// video file, image folder). Lifecycle: configure (negotiate the format, allocate and map every
// buffer) -> start -> acquire/release repeatedly -> stop. acquire() and release() allocate nothing;
// a frame stays valid until it is released, and a source hands out at most its ring size at once.
#pragma once

#include <cstdint>

#include "gs/capture/frame.h"
#include "gs/status.h"

namespace gs::capture {

enum class AcquireResult {
  kFrame,        // *frame holds a frame; release it when done
  kTimeout,      // nothing arrived within the timeout (V4L2 EAGAIN / poll timeout); try again
  kEndOfStream,  // a file source has no more frames
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Printable name for messages, e.g. "v4l2:/dev/video0", "video:clip.mp4".
  virtual const char* name() const = 0;
  // Negotiates the format; *actual receives what the source will deliver. A format the source does
  // not offer is an error that lists the formats it does offer.
  virtual Status configure(const FrameFormat& requested, FrameFormat* actual) = 0;
  virtual Status start() = 0;
  // Waits at most timeout_ms (< 0: forever). Errors (device gone, corrupt data) come back as a
  // Status naming the source; the source is then unusable except for stop().
  virtual Expected<AcquireResult> acquire(int32_t timeout_ms, FrameView* frame) = 0;
  virtual Status release(const FrameView& frame) = 0;
  virtual Status stop() = 0;
};

}  // namespace gs::capture
