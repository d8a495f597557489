// SPDX-License-Identifier: MIT
// libFuzzer harness: the video-file source (FFmpeg demuxing and decoding behind hbgs's checks, and
// hbgs's own frame handling). VideoSource opens a path, so each input is written to a tmpfs
// scratch file; at most 8 frames are decoded per input.
#include <cstdint>
#include <string>

#include "fuzz_util.h"
#include "gs/capture/video_source.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = gs::fuzz::scratch_path(".video");
  if (!gs::fuzz::write_scratch(path, data, size)) return 0;
  gs::capture::VideoSource src(path);
  gs::capture::FrameFormat want, got;
  want.format = gs::capture::PixelFormat::kRGB24;
  if (!src.configure(want, &got).ok() || !src.start().ok()) return 0;
  for (int i = 0; i < 8; ++i) {
    gs::capture::FrameView frame;
    gs::Expected<gs::capture::AcquireResult> r = src.acquire(0, &frame);
    if (!r.ok() || *r != gs::capture::AcquireResult::kFrame) break;
    if (!src.release(frame).ok()) break;
  }
  (void)src.stop();
  return 0;
}
