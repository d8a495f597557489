// SPDX-License-Identifier: MIT
// Live camera tracking against a trained model (issue 25): the pose of every frame of a stream.
// A keyframe (the model rendered with depth at a pose) serves many frames: each frame is aligned
// directly to it (Levenberg-Marquardt on the 6-DoF twist, warping keyframe pixels by their depth,
// coarse to fine on box pyramids) from a constant-velocity prediction; a new keyframe is rendered
// when the camera has moved far from it or the residual grows. Every frame gets a verdict:
// `tracking`, `relocalized` (placed again after being lost, from candidate poses ranked by a small
// global image descriptor and registered with gs::pose::Registrar) or `lost` (no pose is claimed).
//
// Memory: create() plans every buffer for the model and the frame size (keyframes are rendered by
// the relocalisation's own Registrar: one renderer, one decode workspace), set_candidates() renders
// and describes the candidates; track() allocates nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "gs/camera.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/register.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::pose {

struct TrackOptions {
  int track_downscale = 2;         // frames are aligned at 1/track_downscale of their size (box filter)
  int levels = 3;                  // pyramid levels of the alignment, each half the size of the previous
  int iterations_per_level = 10;   // Levenberg-Marquardt steps per level at most
  // A new keyframe is rendered when the camera has turned or moved this far from the keyframe's
  // pose (translation in units of the model's scene extent), or when the alignment's RMSE has grown
  // to keyframe_rmse_growth times the first RMSE against this keyframe (the model's own residual
  // differs from scene to scene; the growth measures what the warp loses).
  double keyframe_rotation_deg = 10.0, keyframe_translation = 0.1, keyframe_rmse_growth = 1.5;
  // Verdict of an aligned frame: `tracking` when the RMSE over colour values in [0, 1] is at most
  // max_rmse, the keyframe explains at least min_explained of the frame's variance where its
  // points land, and they cover at least min_coverage of the frame; otherwise the tracker
  // relocalises.
  double max_rmse = 0.12, min_explained = 0.5, min_coverage = 0.05;
  // Per-pixel colour residual norm beyond which a pixel's weight falls as 1 / |r| (Huber). Smaller
  // values discount what the model renders wrong. Built-in scene's hand-held trajectory (3,000-
  // iteration model, tracked at 1/2 from its frames): median rotation error 0.109 degrees at 0.1,
  // 0.078 at 0.05, 0.074 at 0.03; the object trajectory 0.093 / 0.096 / 0.095; a faster 90-frame
  // sweep 0.155 / 0.117 at 0.1 / 0.05, and 0.02 let a poorly modelled stretch end 1.3 degrees off.
  double huber_delta = 0.05;
  // The weight of colour against brightness in the alignment's residual: (sqrt(3) Y, w (B - Y),
  // w (R - Y)) instead of RGB (a grey residual keeps its norm); negative: RGB. At 1 brightness
  // counts twice as much as in RGB: median rotation error on the object trajectory's H.264 video
  // (4:2:0 colour) 0.105 -> 0.097 degrees, its frames 0.096 -> 0.081, the built-in trajectory's
  // frames 0.078 -> 0.083; snowmiku_plush's photos in capture order no longer have a frame placed
  // over 1 degree off (92 of 97 within, 5 lost).
  double chroma_weight = 1.0;
  bool motion_model = true;        // predict from the last two poses (constant velocity)
  // An alignment that moves the pose further than this from the prediction (degrees; translation
  // in units of the scene extent) found a look-alike, not the camera: the frame is relocalised.
  double max_correction_deg = 10.0, max_correction_translation = 0.1;
  // A frame whose alignment moved it further than this from the prediction (degrees; 0: never) is
  // checked by a registration from the pose found (its wider start candidates and anti-aliased
  // verdict): a 30 frames per second stream moves less between frames, photos taken one by one more.
  double verify_correction_deg = 3.0;
  // A placed frame's RMSE may be at most this many times the median RMSE of the last 20 placed
  // frames (the model's own residual on this stream; 0: no bound): a look-alike pose on a weakly
  // textured object can explain much of the frame's variance, but not as well as the true pose.
  // A relocalised pose beyond it is still accepted when registrations from two starts over 1 degree
  // or 1 % apart reach it (within 1 degree and 1 %): a held-out or blurred photo that the model
  // renders worse than the stream's usual, not a look-alike (model/tracker.cpp, relocalize).
  double max_rmse_growth = 2.5;
  // A pose found by registration (relocalised, or a frame checked after a large move) must also be
  // where the alignment returns to from 4 starts turned this far about the camera centre (0: no
  // check): a look-alike pose near the true one is a shallow local minimum. On snowmiku_plush's
  // photos in capture order 2 degrees took the frames placed over 1 degree off from 2 to 1 (4 lost
  // either way); 3 and 4 degrees lost 17-20 frames and every sceaux_castle photo.
  double basin_check_deg = 2.0;
  // Registrations from the best-ranked candidates when lost (after one from the last pose); the
  // accepted pose with the lowest RMSE wins, not the first.
  int relocalize_candidates = 3;
  // The registrations' options (their background and fixed_point are the tracker's own); by
  // default they end at half resolution.
  RegisterOptions relocalize = half_resolution_registration();
  bool fixed_point = false;        // keyframe renders with the fixed-point blending
  float background[3] = {0, 0, 0}; // the colour behind the model (the one it was trained on)

  static RegisterOptions half_resolution_registration() {
    RegisterOptions r;
    r.finest_downscale = 2;
    return r;
  }
};

enum class TrackVerdict { kTracking, kRelocalized, kLost };
const char* track_verdict_name(TrackVerdict v);  // "tracking", "relocalized", "lost"

// Wall milliseconds of one track() call by stage.
struct TrackStageMs {
  double prepare = 0;     // the frame's box filter and pyramid
  double align = 0;       // direct alignment to the keyframe
  double keyframe = 0;    // decoding and rendering keyframes
  double verdict = 0;     // a separate verdict check (0: the verdict comes from the alignment's own sums)
  double relocalize = 0;  // descriptor ranking and registrations when lost
  double total = 0;
};

struct TrackResult {
  Pose pose;              // world-to-camera in the model's frame; meaningless when verdict is kLost
  TrackVerdict verdict = TrackVerdict::kLost;
  double rmse = 0, explained = 0, coverage = 0;  // at the returned pose, tracking resolution
  int iterations = 0;     // LM steps of this frame
  bool new_keyframe = false;
  uint64_t keyframes = 0; // keyframes rendered since create()
  TrackStageMs ms;
};

class Tracker {
 public:
  // frame: the stream's intrinsics at full resolution (frames are that size). The model must stay
  // alive while the tracker is used.
  static Expected<std::unique_ptr<Tracker>> create(const model::HybridModel& model, const PinholeIntrinsics& frame,
                                                   const TrackOptions& options, platform::ThreadPool* pool,
                                                   const simd::KernelTable* kernels = nullptr);
  ~Tracker();
  // Candidate poses for relocalisation (e.g. the training views): each is rendered once and
  // described; replaces the earlier set. Allocates (and the first call of this or reset(start)
  // plans the relocalisation's registrar with one registration).
  Status set_candidates(const std::vector<Pose>& poses);
  // The next frame is aligned from this pose (a known start); without it, or after reset(), the
  // next frame is relocalised from the candidates (and the keyframes placed so far).
  Status reset(const Pose& start);
  void reset();
  // One RGB frame [H, W, 3] (8-bit) of the size given at create(), at time_seconds (used by the
  // motion model). Errors (not verdicts): a null frame, times that go backwards. Allocates nothing.
  Status track(const uint8_t* rgb, double time_seconds, TrackResult* result);

  const TrackOptions& options() const;
  uint64_t planned_bytes() const;

 private:
  Tracker();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gs::pose
