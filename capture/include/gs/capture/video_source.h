// SPDX-License-Identifier: MIT
// VideoSource: a recorded video file (anything FFmpeg's libavformat/libavcodec read: MP4, MKV,
// MPEG-TS, AVI; H.264, HEVC, MJPEG, ...) behind the FrameSource interface, so `hbgs ingest` treats a
// clip like a camera. Frames are decoded in-process (measured twice as fast as piping the ffmpeg CLI)
// and always delivered as RGB24 at the native size, or downscaled when configure asks for a smaller
// size. Only compiled when GS_HAVE_LIBAV is defined.
//
// Truncated files: a container whose header is unreadable (an MP4 cut before its `moov` atom, a text
// file renamed .mp4) fails at configure. A stream that ends early (the demuxer reaches end of file in
// the middle of a packet, as in an MPEG-TS or MKV cut in half) delivers every frame that decodes and
// then reports kEndOfStream; truncated() then says the file ended early so callers can warn. A packet
// the decoder rejects outright is an error "video <path>: decode error at frame N: <reason>".
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "gs/capture/frame_source.h"

namespace gs::capture {

struct VideoInfo {
  int32_t width = 0, height = 0;  // coded picture size
  double fps = 0.0;               // average frame rate (0 when the container does not say)
  int64_t frame_count = 0;        // the container's count, else duration * fps; an estimate
  double duration_s = 0.0;        // 0 when unknown
  std::string codec;              // libavcodec's short name, e.g. "h264"
};

class VideoSource : public FrameSource {
 public:
  explicit VideoSource(std::string path);
  ~VideoSource() override;
  VideoSource(const VideoSource&) = delete;
  VideoSource& operator=(const VideoSource&) = delete;

  const char* name() const override { return name_.c_str(); }  // "video:<path>"
  // Opens the file and its best video stream. requested.format is ignored (always RGB24) and fps is
  // reported, not changed; width/height 0 mean native, a smaller size is a swscale downscale
  // (a size larger than native, or only one of the two given, is an invalid_argument error).
  Status configure(const FrameFormat& requested, FrameFormat* actual) override;
  Status start() override;
  // Decodes the next frame into the source's one RGB buffer. timeout_ms is ignored (decoding does
  // not wait). Holds at most one frame out: acquiring again before release is an error.
  Expected<AcquireResult> acquire(int32_t timeout_ms, FrameView* frame) override;
  Status release(const FrameView& frame) override;
  Status stop() override;

  // Valid after configure.
  VideoInfo probe() const;
  // After kEndOfStream: true when the stream ended early (the demuxer hit a truncated packet or a
  // read error after at least one frame was delivered).
  bool truncated() const;
  uint64_t frames_decoded() const;

 private:
  struct Impl;
  std::string path_, name_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gs::capture
