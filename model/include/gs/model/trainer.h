// SPDX-License-Identifier: MIT
// Training loop of the hybrid anchor model (ALGORITHM.md Part A items 4, 6, 9; Part B 5-7): one
// random training view per iteration (without replacement per epoch), the step graph in float with
// the SIMD kernels, dense Adam per parameter group with the reference schedules, Scaffold-GS anchor
// growing and pruning under the hard budgets, image features refreshed at a fixed interval, and a
// complete, versioned checkpoint of the training state.
//
// Memory: create() plans and allocates everything (model arrays at budget capacity, optimiser
// moments, renderer arena, workspace); step() allocates nothing (tests/model/test_trainer.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gs/gaussians.h"
#include "gs/io/colmap.h"
#include "gs/model/background.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/step_graph.h"
#include "gs/optim/adam.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::model {

struct TrainOptions {
  int iterations = 30000;
  int schedule_iterations = 30000;  // horizon of the exponential learning-rate schedules
  uint64_t seed = 0;
  StepConfig step;
  // The colour renders are blended on, and which the targets of masked views (DatasetView::mask)
  // are composited on: image * mask + background * (1 - mask). Random: a new colour per iteration
  // (drawn from the run's generator, so resuming stays bit-identical).
  Background background;
  // Learning rates (Part B section 6). Offsets are scaled by the scene extent.
  double lr_offset_init = 0.01, lr_offset_final = 0.0001;
  double lr_feature = 0.0075;
  double lr_scaling = 0.007;
  double lr_mlp_opacity_init = 0.002, lr_mlp_opacity_final = 2e-5;
  double lr_mlp_cov_init = 0.004, lr_mlp_cov_final = 0.004;
  double lr_mlp_color_init = 0.008, lr_mlp_color_final = 5e-5;
  double lr_mlp_image_init = 0.004, lr_mlp_image_final = 4e-5;  // hbgs's F (no reference value)
  double adam_eps = optim::kAdamEps;  // parameters and poses (gs/optim/adam.h)
  // Anchor growing and pruning (Part B section 7).
  int stat_start = 500, update_from = 1500, update_interval = 100, update_until = 15000;
  double densify_grad_threshold = 0.0002, success_threshold = 0.8, min_opacity = 0.005;
  int update_depth = 3, update_init_factor = 16, update_hierarchy_factor = 4;
  // Growth budget (0: none): neural Gaussians per training view at most this many per pixel of the
  // view. A growth step predicts the Gaussians per view from the anchors each view sees and the kept
  // Gaussians per visible anchor of the current step; when the candidates would exceed the budget,
  // it takes the cells with the largest mean gradients first. The render cost of an iteration
  // follows the Gaussians per view, so this bounds it whatever the run's length.
  double growth_gaussians_per_pixel = 0;
  // Image features are recomputed from the current poses every this many iterations (0: never;
  // the training job, gs/jobs/train.h, sets 250 when it optimises the poses).
  int image_feature_refresh = 0;
  // Joint pose optimisation (ALGORITHM.md Part A item 7): one pose per training view, updated by
  // Adam on a left se(3) increment after each render of that view, then retracted (R
  // re-orthonormalised). Rates are per Adam step: radians, and translation in units of the scene
  // extent; linear warm-up over pose_warmup iterations, then log-linear decay to the final rate at
  // schedule_iterations.
  bool optimize_poses = false;
  double lr_pose_rotation_init = 5e-5, lr_pose_rotation_final = 1e-6;
  double lr_pose_translation_init = 5e-5, lr_pose_translation_final = 1e-6;
  int pose_warmup = 100;
  // Registration passes (block-coordinate bundle adjustment): every pose_register_every iterations
  // up to pose_register_until, each training pose is registered against the current (frozen)
  // model with Levenberg-Marquardt, coarse to fine down to the current training resolution, and
  // kept when it fits its image better; Adam moments of a moved pose are reset. 0: never.
  int pose_register_every = 0;
  int pose_register_until = 0;
  // Views held back (1 per training view; empty: none): not trained on until a registration against
  // the current model (every held_back_register_every iterations from held_back_register_from up to
  // held_back_register_until: a model too young to register against gives confident wrong poses)
  // gives them a converged pose. For views whose given pose is far off, e.g. those structure from
  // motion could not register: trained on, they would blur the model where they look.
  std::vector<uint8_t> held_back_views;
  int held_back_register_every = 0, held_back_register_from = 0, held_back_register_until = 0;
  // Evidence beyond the model's on a new pose that registration found for a held view: called with
  // the view's index, its camera at the given pose and at the new one. kContradicts: the view is
  // not placed there; kAccepts: it may move if the model's evidence is clear (a much better fit);
  // kPrefers: the evidence clearly favours the new pose, so it moves on any better fit. Null: the
  // model's evidence alone. The training job asks the SfM points (pose::is_suspect, pose::prefers):
  // a registration against a model that has not seen what a view shows can converge to a
  // look-alike pose, and a young model's fit alone cannot tell a wrong given pose from that.
  enum class PoseEvidence { kContradicts, kAccepts, kPrefers };
  std::function<PoseEvidence(size_t view, const Camera& given, const Camera& moved)> judge_new_pose;
  // Coarse to fine: the first coarse_fraction of the iterations render and compare at reduced
  // resolution, coarse_levels halvings spread evenly over it (2: 1/4 then 1/2), then full resolution.
  int coarse_levels = 0;
  double coarse_fraction = 0.3;
  // Numerical guard: a step whose loss or any gradient is NaN or infinite changes nothing (no Adam,
  // pose or statistics update; the iteration still counts) and is reported in IterationStats; this
  // many such steps in a row stop training with a kNumerical error (the model has diverged).
  int max_nonfinite_in_a_row = 10;
  // Test hook (fault injection): these iterations' gradients are replaced by NaN.
  std::vector<int> test_nonfinite_iterations;
};

struct IterationStats {
  int iteration = 0;       // 1-based number of the iteration just run
  int view = 0;            // index into the training views
  StepResult step;
  double psnr = 0;         // of this iteration's render against its target (float, unclamped; metrics::psnr_f32)
  size_t anchors = 0;      // live anchors after the iteration
  size_t isects = 0;       // Gaussian-tile pairs rendered
  double seconds = 0;      // wall time of this iteration
  bool adjusted = false;   // anchors were grown / pruned this iteration
  int downscale = 1;       // resolution divisor of this iteration (coarse to fine)
  int poses_registered = -1;  // poses moved by a registration pass this iteration (-1: no pass)
  int views_released = -1;    // held-back views registered and released this iteration (-1: no attempt)
  int views_held_back = 0;    // views still held back after this iteration
  bool skipped_nonfinite = false;  // the loss or a gradient was not finite: nothing was updated
  int nonfinite_steps = 0;         // steps skipped so far by this trainer (since create or load)
};

class Trainer {
 public:
  // train_views: cameras and 8-bit images (not owned; must outlive the trainer). kernels null =
  // best for this CPU; pool may be null. Errors: no views, images of the wrong size, a model whose
  // capacity cannot hold its anchors, a renderer plan that cannot be allocated.
  static Expected<std::unique_ptr<Trainer>> create(HybridModel model, const std::vector<const io::DatasetView*>& train_views,
                                                   const TrainOptions& options, platform::ThreadPool* pool,
                                                   const simd::KernelTable* kernels = nullptr);
  ~Trainer();

  // Runs one iteration. Fails on a broken invariant (reported, not asserted) and with kNumerical
  // after max_nonfinite_in_a_row non-finite steps in a row.
  Status step(IterationStats* stats);
  int iteration() const;  // completed iterations
  const HybridModel& model() const;
  const TrainOptions& options() const;
  // Current camera of every training view (the input poses, refined when optimize_poses is on).
  const std::vector<Camera>& cameras() const;
  // 1 for each training view still held back (TrainOptions::held_back_views).
  const std::vector<uint8_t>& held_back() const;
  // 1 for each training view a registration released at a new pose (a repaired view); a released
  // view without it was confirmed at its given pose.
  const std::vector<uint8_t>& repaired() const;
  // Resolution divisor used at a 1-based iteration (coarse to fine).
  int downscale_at(int iteration) const;

  // A new length for the run, while it trains (a time budget, gs/jobs/train.h, re-predicts how many
  // iterations fit as it measures its pace). Takes from `schedule` only what follows from the run's
  // length: iterations and schedule_iterations, the densification window (stat_start, update_from,
  // update_interval, update_until), pose_warmup, the registration passes (pose_register_every,
  // pose_register_until) and the held-back registrations (held_back_register_every, _from, _until),
  // and the end of coarse to fine (coarse_fraction x iterations). What has happened stays: the
  // learning rates never rise again (schedule_progress never decreases), a window that has closed
  // never re-opens and one that has started keeps its start, the pose warm-up only shortens, and the
  // resolution never gets coarser. The checkpoint keeps the re-targeted schedule.
  Status retarget(const TrainOptions& schedule);
  // The fraction of the learning-rate schedules reached at the last step: iteration /
  // schedule_iterations in a run of fixed length; after a retarget, never below what it was.
  double schedule_progress() const;

  // Checkpoint: magic "HBGSCKPT", version, the model, every Adam moment and step count, densification
  // statistics, iteration, RNG and view-order state, the training poses and their Adam state, the
  // held-back views and, once retarget was called, the re-targeted schedule (restored on load).
  // Written atomically (temp file + rename). Other versions are refused with a message.
  Status save_checkpoint(const std::string& path) const;
  // Restores a checkpoint written by save_checkpoint for the same training views (count checked).
  Status load_checkpoint(const std::string& path);

  // Bytes allocated at create() (model capacity, optimiser, workspace, renderer arena).
  uint64_t planned_bytes() const;
  // Frees what only further steps use: the decoder's gradient buffers and the growth scratch
  // (about 20 MiB for snowmiku_plush at 1,000 iterations), so that the evaluation after the last
  // step does not add to the peak. render() and the checkpoint are unaffected; a later step() plans
  // them again first (one allocation).
  void release_step_memory();
  // Times a step or render found more visible anchors or kept Gaussians than the decoder workspace
  // was planned for and grew it (each one allocation; the plan follows a visibility dry run and the
  // counts seen, see docs/MODEL.md).
  int workspace_replans() const;

  // Profiling: every later step() adds its stages' wall time and counts to *times (gs/stage_times.h;
  // StageTimes::finish_iteration per step); render() never does. Null (the default) turns it off:
  // a branch per stage, no clock read, no allocation.
  void set_stage_times(StageTimes* times);

  // Renders the current model for a camera with the trainer's own pipeline (forward only; the next
  // step() is unaffected): evaluation during training without a second renderer. rgb [H, W, 3];
  // gaussians and alpha [H, W] optional. Fails when the image is larger than the training views.
  Status render(const Camera& camera, const float background[3], float* rgb, size_t* gaussians = nullptr,
                float* alpha = nullptr);
  bool can_render(int width, int height) const;

 private:
  Trainer();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// 1.1 x the largest distance of a camera centre from the mean centre (the offset LR scale).
float cameras_extent(const std::vector<const Camera*>& cameras);

}  // namespace gs::model
