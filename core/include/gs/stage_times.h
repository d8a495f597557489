// SPDX-License-Identifier: MIT
// Per-stage wall time of training iterations (bench_train --profile, progress.json): a plain
// struct the renderer, the step graph and the trainer add to when they are handed a pointer to
// one; with a null pointer every timer is a single branch (no clock read, no allocation).
#pragma once

#include <cstddef>
#include <cstdint>

#include "gs/platform/clock.h"

namespace gs {

// The stages of one training iteration, in the order they run. kOther is the remainder of the
// iteration's wall time (target loading, gradient zeroing, the finite check, pose steps and
// registration, the training PSNR), filled by StageTimes::finish_iteration.
enum Stage : int {
  kStageAnchorSelect = 0,  // select_visible_anchors
  kStageImageMlpFwd,       // gather raw image features + image-feature MLP forward
  kStageDecoderInput,      // build_decoder_input
  kStageDecoderMlpFwd,     // the three decoder MLPs forward
  kStageDecodeFwd,         // decode_fwd (kept neural Gaussians)
  kStageProject,           // projection + splat-record packing (renderer)
  kStageBin,               // binning: count, scan, emit keys (renderer)
  kStageSortCopy,          // per-tile depth sort + record copy (renderer; share of the tile pass)
  kStageRasterFwd,         // tile blending forward (renderer; share of the tile pass)
  kStageLoss,              // L1 + SSIM forward and backward, volume term
  kStageRasterBwd,         // tile blending backward (renderer)
  kStageReduce,            // intersection gradients reduced to Gaussians (renderer)
  kStageProjectBwd,        // projection backward (renderer)
  kStageDecodeBwd,         // decode_bwd
  kStageMlpBwd,            // decoder MLPs + image-feature MLP backward (and the input-gradient sums)
  kStageAdam,              // Adam over every parameter group (and the pose step)
  kStageStats,             // densification statistics (accumulate_stats)
  kStageAdjust,            // anchor growing / pruning (adjust_anchors)
  kStageImageFeatures,     // image-feature refresh
  kStageOther,             // the rest of the iteration's wall time
  kStageCount
};

// Short stable names (JSON keys, table rows).
inline const char* stage_name(int s) {
  static const char* const names[kStageCount] = {
      "anchor_select", "image_mlp_fwd", "decoder_input", "decoder_mlp_fwd", "decode_fwd", "project",
      "bin",           "sort_copy",     "raster_fwd",    "loss",            "raster_bwd", "reduce",
      "project_bwd",   "decode_bwd",    "mlp_bwd",       "adam",            "stats",      "adjust",
      "image_features", "other"};
  return s >= 0 && s < kStageCount ? names[s] : "?";
}

// Sums over the iterations profiled so far. Counters are what the roofline's counting model needs
// (bench_train --profile); each is a sum over iterations, divide by `iterations`.
struct StageTimes {
  uint64_t ns[kStageCount] = {};  // wall nanoseconds per stage
  uint64_t wall_ns = 0;           // whole iterations (Trainer::step, start to end), overhead_ns included
  uint64_t iterations = 0;
  uint64_t anchors = 0;           // live anchors M at the step
  uint64_t visible_anchors = 0;   // V
  uint64_t gaussians = 0;         // kept neural Gaussians N (rendered)
  uint64_t projected = 0;         // Gaussians with a non-zero radius
  uint64_t isects = 0;            // Gaussian-tile pairs
  uint64_t pixels = 0;            // W x H
  uint64_t adam_floats = 0;       // parameters Adam updated
  uint64_t stats_steps = 0;       // iterations that accumulated densification statistics
  uint64_t adjust_steps = 0;      // iterations that grew / pruned anchors
  uint64_t refresh_steps = 0;     // iterations that refreshed the image features
  // Pixel-splat pairs inside the splats' alpha >= 1/255 support boxes (clipped to their tiles): the
  // pairs the tile kernels evaluate, up to SIMD rounding and early termination. Counted by the
  // renderer only when count_splat_pixels is set (one pass over the tile lists, ~1 % of a frame).
  bool count_splat_pixels = false;
  uint64_t splat_pixels = 0;
  // Wall time spent on the profile's own counting (count_splat_pixels), inside wall_ns but in no
  // stage: finish_iteration leaves it out of kStageOther.
  uint64_t overhead_ns = 0;

  void add(int stage, uint64_t dt) { ns[stage] += dt; }
  // Closes an iteration of wall time `iteration_ns`: kStageOther gets what the stages left.
  void finish_iteration(uint64_t iteration_ns) {
    uint64_t named = 0;
    for (int s = 0; s < kStageOther; ++s) named += ns[s];
    wall_ns += iteration_ns;
    ++iterations;
    // The stages are disjoint intervals inside the iterations, so the named ones and the overhead
    // never sum to more than the wall time; other is what remains (all sums over iterations).
    const uint64_t net = wall_ns > overhead_ns ? wall_ns - overhead_ns : 0;
    ns[kStageOther] = net > named ? net - named : 0;
  }
  // Mean wall ms per iteration without the profile's overhead (the stages sum to it).
  double profiled_ms_per_iteration() const {
    return iterations ? 1e-6 * double(wall_ns > overhead_ns ? wall_ns - overhead_ns : 0) / double(iterations) : 0.0;
  }
  double ms_per_iteration(int stage) const { return iterations ? 1e-6 * double(ns[stage]) / double(iterations) : 0.0; }
  void reset() { *this = StageTimes{count_splat_pixels}; }
  StageTimes() = default;
  explicit StageTimes(bool count_pixels) : count_splat_pixels(count_pixels) {}
};

// A lap timer: lap(stage) adds the time since the previous lap (or construction / restart) to the
// stage. With a null StageTimes it reads no clock.
class StageClock {
 public:
  explicit StageClock(StageTimes* t) : t_(t), last_(t ? platform::now_ns() : 0) {}
  void restart() {
    if (t_) last_ = platform::now_ns();
  }
  void lap(int stage) {
    if (!t_) return;
    const uint64_t now = platform::now_ns();
    t_->ns[stage] += now - last_;
    last_ = now;
  }
  StageTimes* times() const { return t_; }

 private:
  StageTimes* t_;
  uint64_t last_;
};

}  // namespace gs
