// SPDX-License-Identifier: MIT
// Frame selection for ingestion: from every frame of a video or capture, keep about N that are
// sharp and spread along the camera's motion. Two numbers per frame drive it, both computed from a
// grey copy of the frame with no allocation after set-up:
//   sharpness: variance of the 3x3 Laplacian on the grey image downscaled to <= 320 px wide
//              (blur flattens it); judged relative to the neighbouring frames, so a dim or
//              low-texture stretch of video is not rejected wholesale;
//   motion:    mean absolute difference (0..1) between 32x24 grey thumbnails of this frame and the
//              previous one, a cheap stand-in for how far the view moved.
// Selection is deterministic: the same statistics and options give the same frames.
#pragma once

#include <cstdint>
#include <vector>

#include "gs/status.h"

namespace gs::capture {

struct FrameStats {
  int64_t index = 0;         // frame number in the source
  int64_t timestamp_ns = 0;
  double sharpness = 0;      // Laplacian variance, grey levels^2 (0..255 scale)
  double motion = 0;         // thumbnail difference to the previous frame, 0..1 (0 for the first)
};

// Computes FrameStats for consecutive frames; keeps the previous thumbnail between calls.
class FrameAnalyzer {
 public:
  // Plans buffers for frames up to max_width x max_height.
  static Expected<FrameAnalyzer> create(int32_t max_width, int32_t max_height);
  // rgb: [height, rgb_stride bytes], RGB24. Frames larger than planned are an error.
  Expected<FrameStats> add(const uint8_t* rgb, int32_t width, int32_t height, int32_t rgb_stride, int64_t index,
                           int64_t timestamp_ns);

  FrameAnalyzer() = default;

 private:
  int32_t max_width_ = 0, max_height_ = 0;
  std::vector<float> grey_;       // downscaled grey image
  std::vector<float> thumb_, prev_thumb_;
  bool have_prev_ = false;
};

struct SelectOptions {
  int target_count = 100;    // frames to keep (fewer when the video has fewer usable ones)
  double blur_ratio = 0.6;   // a frame is blurred when sharpness < blur_ratio * median of its window
  int blur_window = 7;       // neighbours on each side for that median
  double min_motion = 0.0;   // frames closer than this (summed motion) to the last kept one are skipped
};

struct SelectReport {
  int total = 0;             // frames analysed
  int blurred = 0;           // rejected as blurred
  int kept = 0;
  double total_motion = 0;   // summed motion over the sequence
};

// Indices into `stats` (not frame numbers) of the frames to keep, ascending. The motion path is cut
// into target_count equal stretches of summed motion and the sharpest unblurred frame of each
// stretch is kept, so a camera that pauses does not fill the dataset with one view.
std::vector<size_t> select_frames(const std::vector<FrameStats>& stats, const SelectOptions& options,
                                  SelectReport* report = nullptr);

// Variance of the 3x3 Laplacian (4-neighbour) of a grey image [height, width] (interior pixels).
double laplacian_variance(const float* grey, int32_t width, int32_t height);

}  // namespace gs::capture
