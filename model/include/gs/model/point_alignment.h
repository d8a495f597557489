// SPDX-License-Identifier: MIT
// Photometric alignment of noisy camera poses to the SfM points, before (and independently of) any
// trained model: the first stage of hbgs's pose optimisation (ALGORITHM.md Part A item 7, "aim
// higher"). The SfM points are the anchors' positions, so they already sit in the true frame; a
// pose is right when the colours its image shows at the projections of the points agree with what
// the other views show there. Per view, Gauss-Newton (Levenberg-Marquardt) on the left twist of the
// pose minimises the Huber-weighted difference between its bilinear colour samples and the
// leave-one-out mean colour of each point over the other views, the means being recomputed between
// rounds (block-coordinate photometric bundle adjustment with fixed structure). Coarse to fine on
// box pyramids of the images widens the basin; occluded points are excluded by a per-view point
// z-buffer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::pose {

struct PointAlignOptions {
  int max_levels = 4;            // pyramid levels (each halves), coarsest at least min_width wide
  int min_width = 32;            // px
  int rounds_per_level = 6;      // mean-colour / pose alternations per level
  int gn_iterations = 4;         // Levenberg-Marquardt steps per view per round
  double huber = 0.1;            // colour residual norm beyond which weights fall as 1/|r|
  size_t max_points = 20000;     // points used (an even subsample of larger clouds)
  double occlusion_tolerance = 0.03;  // a point is visible if z <= (1 + tol) x the z-buffer depth
  // For starts that are already close (after SfM): the colour objective has a precision of its
  // own (about 0.15-0.2 degrees on real scenes, from COLMAP's point colours and the sparse
  // z-buffer), and an occluder without SfM points can pull a view degrees away.
  double discard_below_median_move_deg = 0;  // > 0: when the median view moved less than this
                                             // (degrees), every view keeps its start pose
  double max_move_over_median = 0;           // > 0: a view moved more than this x the median move
                                             // (rotation or centre) keeps its start pose
};

struct PointAlignReport {
  int levels = 0, rounds = 0;
  size_t points_used = 0;
  double initial_cost = 0, final_cost = 0;  // mean Huber cost per residual at the finest level
  std::vector<int> reverted_views;          // views that kept their start pose (see the options above)
  double median_move_deg = 0, median_move_frac = 0;  // how far the views moved (rotation; centre / radius)
  bool discarded = false;                   // every view kept its start (discard_below_median_move_deg)
  double seconds = 0;
};

// Aligns cameras[i] (in place; intrinsics unchanged) to the points [n, 3] using images[i] (RGB,
// the cameras' size). With point colours rgb [n, 3] (the SfM reconstruction's, as 3DGS uses to
// initialise its Gaussians), each view is aligned to those fixed colours (no consensus needed, so
// views cannot drag each other along); without, to the leave-one-out mean over the other views.
// Errors: size mismatches, fewer than 2 views or 10 points.
Status align_poses_to_points(const float* xyz, const uint8_t* rgb, size_t n, const std::vector<const io::Image8*>& images,
                             std::vector<Camera>* cameras, const PointAlignOptions& options, platform::ThreadPool* pool,
                             PointAlignReport* report);

// How well each view's image agrees with the SfM points at its pose, before any model exists: the
// evidence "every view earns its place" (docs/POSES.md) starts from. Per view, the points in front,
// inside the image and not behind nearer points (the same per-view z-buffer as the alignment) are
// sampled at their projections; a point agrees when the colour there is within `huber` (colour
// norm, values in [0, 1]) of the point's colour (the SfM colour when given, else the mean over the
// other views that see it). The chance level is the same count with every point compared to the
// sample of another visible point of the view (a fixed cyclic shift of the visible list): what a
// pose that lines up nothing would score on this image, so the measure needs no scene constant.
struct ViewPointAgreement {
  size_t visible = 0;        // points seen (at full resolution)
  double agree = 0;          // fraction of them that agree
  double chance = 0;         // fraction that agree with a shifted point's sample
};
Status score_views_against_points(const float* xyz, const uint8_t* rgb, size_t n, const std::vector<const io::Image8*>& images,
                                  const std::vector<Camera>& cameras, double huber, size_t max_points,
                                  platform::ThreadPool* pool, std::vector<ViewPointAgreement>* scores);

// Which views the point agreement says may be wrong: a view is suspect when its agreement above
// its own chance level is less than a quarter of the typical view's (agree - chance < 0.25
// (median agree - median chance)), or it sees fewer than a quarter of the median view's points.
// A pose off by 10 degrees or more agrees at about chance level. Correct views can be suspect too:
// an occluder without SfM points (snowmiku_plush's wardrobe door) or a strong change of exposure
// hides the points behind it, which is why a suspect view is only held back until the model can
// decide (docs/POSES.md). Returns one flag per view; none when fewer than 3 views or when the
// typical margin is under 0.1 (the points say too little about this scene).
std::vector<uint8_t> suspect_views(const std::vector<ViewPointAgreement>& scores);
// The rule above for one view against the typical view (median agree - median chance, median
// points), e.g. a view at a new pose against the scores the whole set had.
struct TypicalAgreement {
  double margin = 0, points = 0;
};
TypicalAgreement typical_agreement(const std::vector<ViewPointAgreement>& scores);
bool is_suspect(const ViewPointAgreement& score, const TypicalAgreement& typical);
// Whether the points clearly prefer a view at a new pose to the same view at its given pose: the
// new pose is not suspect and its margin over chance is higher by at least a quarter of the typical
// margin (the unit of the suspect rule). A pose off by 8 degrees the points only half trusted (a
// margin of 0.29 against a typical 0.62, not suspect) scored 0.61 at the true pose; the correct
// views snowmiku_plush's door hides stay suspect at every pose registration gave them.
bool prefers(const ViewPointAgreement& moved, const ViewPointAgreement& given, const TypicalAgreement& typical);

}  // namespace gs::pose

