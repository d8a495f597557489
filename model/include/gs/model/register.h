// SPDX-License-Identifier: MIT
// Test-view registration against a frozen model (ALGORITHM.md Part A item 8, Part B section 9):
// find the world-to-camera pose of a new image by minimising the photometric error of the render,
// coarse to fine on a box pyramid of the image, with early stopping, the best pose kept, and a
// verdict per view.
//
// Three solvers, same pyramid and stopping rules:
//   kKeyframe:    (default) render the model once at the current pose with depth (a keyframe), then
//                 align the image to it directly: Levenberg-Marquardt on the twist, warping keyframe
//                 pixels by their depth, coarse to fine on box pyramids of both (cost per step is
//                 per pixel, not per Gaussian, and both pyramids are properly filtered); re-render
//                 and repeat, then polish with kGaussNewton steps at the finest level;
//   kGaussNewton: Levenberg-Marquardt on the 6-DoF left twist with the renderer's analytic
//                 forward-mode pose Jacobian (J^T W J, J^T W r; Huber-weighted residuals) at
//                 every level;
//   kAdam:        Adam on the L1 photometric loss with the rasteriser's pose gradient (the
//                 reference code's method, with a learning-rate decay per level).
// Per level, the neural Gaussians are decoded once at the level's starting pose (colours depend
// on the view direction) from a widened field of view, so anchors that come into view as the pose
// moves are already there; within a level the objective is a fixed function of the pose.
//
// Memory: create() plans everything for the model and the largest image; register_view()
// allocates nothing (tests/model/test_register.cpp counts operator new). Time is bounded by the
// iteration caps and an optional wall-clock budget.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::pose {

struct RegisterOptions {
  enum Solver { kKeyframe, kGaussNewton, kAdam } solver = kKeyframe;
  int keyframes = 2;             // kKeyframe: renders (outer rounds) before the polish
  int keyframe_iterations = 15;  // kKeyframe: LM steps per pyramid level per keyframe
  int polish_iterations = 3;     // kKeyframe: renderer LM steps at the finest level at the end (full resolution)
  // kKeyframe below full resolution: LM steps at the end against the anti-aliased render itself
  // (rendered at keyframe_downscale, box-filtered to the finest level; Jacobian from its gradient
  // and depth), one render per trial.
  int render_polish_iterations = 3;
  // The image level of the render polish (0: the finest level; e.g. 2 with finest_downscale 4 to end
  // on the half-resolution image: the render costs the same, the image has 4x the pixels).
  int polish_level_downscale = 0;
  // kKeyframe: at the coarsest level of the first keyframe, start the alignment from this many
  // rotations about the camera centre (the start, then pan/tilt offsets of candidate_angle_deg on a
  // 3x3 grid) and keep the one that ends with the lowest cost: a wider basin for the price of a few
  // coarse (tiny) alignments. 1: only the start.
  int coarse_candidates = 9;
  double candidate_angle_deg = 8.0;
  int finest_downscale = 1;      // resolution divisor of the last level (1: full, 4: quarter)
  // kKeyframe: resolution divisor at which keyframes are rendered before being box-filtered down to
  // the levels (0: max(1, finest_downscale / 2)), and the one of the render polish and the
  // verdict's render (0: max(1, finest_downscale / 4)). Each must divide finest_downscale (else 1).
  int keyframe_downscale = 0, polish_downscale = 0;
  int min_coarse_width = 12;     // the coarsest level is the largest halving at least this wide, px
  int max_levels = 6;            // at most this many levels
  int max_iterations_per_level = 20;  // LM; Adam uses adam_iterations_per_level
  int adam_iterations_per_level = 100;
  double time_budget_ms = 0;     // > 0: stop (keeping the best pose) when exceeded
  // On-device mode: the forward-only renders (keyframes, the render polish, the verdict's render:
  // colour, depth, alpha) use the fixed-point blending (RenderOptions::fixed_point); the lm and
  // adam solvers and the full-resolution renderer-Jacobian polish stay float (they need a backward).
  bool fixed_point = false;
  // The colour behind the model's Gaussians in every render: the background it was trained on
  // (gs/model/background.h); the image should be composited on the same colour where it has a mask.
  float background[3] = {0, 0, 0};
  float huber_delta = 0.1f;      // per-pixel residual norm beyond which the weight falls as 1/|r|
  // Stopping: a level ends when an accepted step moves less than these (rad; x scene extent) or the
  // cost falls by a relative amount below min_relative_decrease.
  double min_step_rotation = 1e-4, min_step_translation = 1e-4, min_relative_decrease = 1e-4;
  double adam_lr_rotation = 2e-3, adam_lr_translation = 2e-3;  // rad; x scene extent
  // Verdict: converged when the final photometric RMSE (over colour values in [0, 1]) is at most
  // max_rmse, the render explains at least min_explained of the image's variance (1 - MSE / Var:
  // an image of something else, or with no contrast at all, explains nothing), the model covers
  // at least min_coverage of the image (mean opacity of the render), and the pose moved at most
  // max_rotation_deg / max_translation (x scene extent) from the start.
  double max_rmse = 0.15, min_explained = 0.55, min_coverage = 0.05, max_rotation_deg = 45, max_translation = 1.0;
  // Relocalisation (Registrar::set_candidates): a view that does not converge from its start (any
  // verdict but converged and time_budget) is registered again from this many candidate poses, the
  // ones whose renders look most like the image (a small grey image descriptor, normalised
  // cross-correlation); of those that converge, the one with the lowest final RMSE is returned
  // (a look-alike pose may converge too, with a worse fit). 0: never.
  int relocalize_candidates = 3;
};

enum class RegisterVerdict {
  kConverged,
  kNothingVisible,   // no Gaussian of the model is visible from the start pose (e.g. behind the scene)
  kPoorFit,          // finished, but the residual is too high, explains too little of the image, or the
                     // model barely covers it (an image of something else, a black image)
  kDiverged,         // the pose ran away from the start beyond the plausible range
  kTimeBudget,       // stopped by the time budget before the finest level finished
};
const char* verdict_name(RegisterVerdict v);

struct RegisterResult {
  Pose pose;                  // best pose found (the start pose when nothing better was found)
  RegisterVerdict verdict = RegisterVerdict::kNothingVisible;
  double initial_rmse = 0;    // photometric RMSE at the start pose, finest level
  double final_rmse = 0;      // at the returned pose, finest level
  double coverage = 0;        // mean opacity (1 - final transmittance) of the final render
  double explained = 0;       // 1 - MSE / variance of the image (finest level; 0 for a flat image)
  int iterations = 0;         // solver steps over all levels
  int levels = 0;
  double milliseconds = 0;    // the whole call, relocalisation included
  // The candidate (index into set_candidates' poses) the pose was registered from, when the start
  // did not converge and a candidate did; -1: registered from the start pose. Then iterations count
  // every attempt, and initial_rmse is still the start pose's.
  int relocalized_from = -1;
  int relocalize_attempts = 0;  // candidates tried
  bool converged() const { return verdict == RegisterVerdict::kConverged; }
};

class Registrar {
 public:
  // Plans for the model's anchors (or plan_anchor_rows, for a model that will grow, e.g. during
  // training) and images up to max_width x max_height (the full resolution; levels are smaller).
  // The model must stay alive while the registrar is used; it is read (not copied) at every call.
  static Expected<std::unique_ptr<Registrar>> create(const model::HybridModel& model, int max_width, int max_height,
                                                     const RegisterOptions& options, platform::ThreadPool* pool,
                                                     const simd::KernelTable* kernels = nullptr,
                                                     size_t plan_anchor_rows = 0);
  // The same against plain Gaussians (a baked model, or a 3DGS scene read from a PLY, .splat or .spz
  // file): their SH colours are evaluated where the anchor model would be decoded. scene_extent
  // (world units) scales the translation steps and limits, as HybridModel::scene_extent does (e.g.
  // model::cameras_extent of the training cameras).
  static Expected<std::unique_ptr<Registrar>> create(const GaussianCloud& cloud, float scene_extent, int max_width,
                                                     int max_height, const RegisterOptions& options,
                                                     platform::ThreadPool* pool,
                                                     const simd::KernelTable* kernels = nullptr);
  ~Registrar();

  // Registers one RGB image [H, W, 3] (8-bit) seen by a camera with intrinsics intr (full
  // resolution, the image's size) from the start pose init. Errors (not verdicts): wrong sizes,
  // an image larger than planned, an invalid camera or start pose. Allocates nothing.
  Status register_view(const uint8_t* rgb, const PinholeIntrinsics& intr, const Pose& init, RegisterResult* result);

  // Candidate poses for relocalisation (e.g. a dataset's other views; RegisterOptions::
  // relocalize_candidates), seen with intrinsics intr: the images that will be registered must have
  // intr's size (a view of another size is not relocalised). Each candidate is rendered once at intr
  // and described (model/image_descriptor.h); this call allocates, register_view does not. An
  // empty list removes them.
  Status set_candidates(const std::vector<Pose>& poses, const PinholeIntrinsics& intr);

  // Renders the model at cam (at most the planned size) with the registrar's own decode and
  // renderer, as its keyframes are: colour rgb [H, W, 3] and, when not null, the alpha-weighted
  // depth and the opacity [H, W]. For renders beside registration without a second renderer (the
  // tracker's keyframes). Allocates nothing once a registration has run.
  Status render(const Camera& cam, float* rgb, float* depth = nullptr, float* alpha = nullptr);

  const RegisterOptions& options() const;
  RegisterOptions& mutable_options();  // e.g. switch the solver between calls (no re-planning)
  uint64_t planned_bytes() const;

 private:
  friend struct RegistrarSharing;  // model/register_sharing.h: a trainer lends its renderer
  Registrar();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gs::pose

