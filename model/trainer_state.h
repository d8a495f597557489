// SPDX-License-Identifier: MIT
// Private to gs_model: the trainer's state (Trainer::Impl), shared by the files of the training
// loop: trainer.cpp (views, schedules, Adam, poses, registration passes, step), trainer_anchors.cpp
// (densification statistics, anchor growing and pruning) and checkpoint.cpp (the checkpoint file).
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "byte_codec.h"
#include "float_backend.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/model/image_features.h"
#include "gs/model/register.h"
#include "gs/model/trainer.h"
#include "gs/render.h"

namespace gs::model {

namespace detail {

// One optimised tensor: parameters (owned by the model), gradient and Adam moments. Per-anchor
// groups hold row_floats values per anchor and are stepped over the live rows only.
struct ParamGroup {
  const char* name = "";
  float* param = nullptr;
  size_t row_floats = 0;  // per-anchor groups: floats per anchor; 0 = a fixed-size tensor
  size_t fixed_size = 0;  // fixed-size groups: element count
  std::vector<float> grad, m, v;
  double lr0 = 0, lr1 = 0;
  size_t live(size_t anchors) const { return row_floats ? row_floats * anchors : fixed_size; }
};

struct CellKey {
  int64_t x, y, z;
  bool operator<(const CellKey& o) const { return x != o.x ? x < o.x : (y != o.y ? y < o.y : z < o.z); }
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

}  // namespace detail

struct Trainer::Impl {
  HybridModel model;
  TrainOptions opt;
  std::vector<const io::DatasetView*> views;
  // [views] the photos of masked views composited on the evaluation background, for the image
  // features and the registration passes (empty for a view without a mask: its image is used).
  std::vector<io::Image8> composited;
  std::vector<Camera> view_cameras;     // [views] current training poses (optimised in place)
  std::vector<const Camera*> cameras;   // -> view_cameras (the image-feature bank reads these)
  std::vector<double> pose_m, pose_v;   // [views, 6] Adam moments of the pose twists
  std::vector<int32_t> pose_steps;      // [views] Adam steps taken per pose
  std::unique_ptr<pose::Registrar> registrar;  // registration passes; held-back views' passes while needed
  platform::ThreadPool* pool = nullptr;
  const simd::KernelTable* kernels = nullptr;
  ImageFeatureBank bank;
  Renderer renderer;
  detail::FloatBackend backend;
  StepWorkspace<float> ws;
  std::vector<float> target;  // [H, W, 3] of the current view
  std::vector<uint8_t> valid_target;  // [H, W] its valid pixels (views with io::DatasetView::valid)
  std::vector<detail::ParamGroup> groups;  // offsets, log_scales, features, then the MLPs
  int iteration = 0;
  detail::SplitMix64 rng;
  std::vector<int32_t> view_order;
  size_t view_pos = 0;
  std::vector<uint8_t> held;  // [views] 1: held back (not trained on) until registered
  std::vector<uint8_t> repaired;  // [views] 1: released by registration (register_held polishes it)
  // [views, kDescriptorWidth x kDescriptorHeight] grey descriptors of the photos (image_descriptor.h),
  // for the starts of held-back views' registrations; empty until a view is held.
  std::vector<float> descriptors;
  // Densification statistics (capacity rows).
  std::vector<float> opacity_accum;   // [cap]
  std::vector<int32_t> anchor_seen;   // [cap]
  std::vector<float> grad_accum;      // [cap, k]
  std::vector<int32_t> grad_denom;    // [cap, k]
  // Growth scratch (capacity-sized; std::sort works in place).
  std::vector<detail::CellKey> existing_cells;            // [cap]
  std::vector<std::pair<detail::CellKey, uint32_t>> cand;  // [cap k] (cell, candidate index row * k + j)
  std::vector<uint8_t> pruned;                     // [cap]
  uint64_t planned_bytes = 0;
  int nonfinite_steps = 0, nonfinite_in_a_row = 0, first_nonfinite = 0;
  int plan_w = 1, plan_h = 1;  // largest training view: what the pipeline is planned for
  Status growth_status;        // a failed growth (allocation) reported by step()
  int growths = 0;             // times the rows grew (each one allocation, at a densification step)
  size_t last_visible = 0;    // visible anchors of the last step
  size_t last_gaussians = 0;  // kept neural Gaussians of the last step
  bool step_memory_released = false;  // release_step_memory() ran: step() plans again first
  size_t most_gaussians = 0;  // the most kept neural Gaussians of a step so far (plans the workspace)
  std::vector<std::pair<float, uint32_t>> cell_scores;  // [cap k] (-mean gradient, first candidate) per new cell
  // The run's schedule as it goes (Trainer::retarget): the learning-rate progress fraction reached
  // (never decreasing), the iteration where coarse to fine ends, and whether retarget was called
  // (then the checkpoint records the schedule).
  double lr_progress = 0;
  double coarse_end = 0;
  bool retargeted = false;
  StageTimes* stage_times = nullptr;  // Trainer::set_stage_times

  size_t cap() const { return model.capacity(); }
  size_t budget() const { return model.config.anchor_capacity(); }
  int k() const { return model.config.k; }
  bool paper() const { return uses_image_features(model.config.image_features); }
  ModelParamsT<float> params() const { return detail::model_params(model); }
  int held_count() const { return int(std::count(held.begin(), held.end(), uint8_t(1))); }
  int repaired_count() const { return int(std::count(repaired.begin(), repaired.end(), uint8_t(1))); }
  // The photo of view v as the model should render it (composited when the view has a mask).
  const io::Image8& photo(size_t v) const { return composited[v].empty() ? views[v]->image : composited[v]; }

  // The training loop (trainer.cpp).
  // True when every live gradient (and the pose twist) is finite. The exponent bits are tested
  // as integers so that the scan vectorises (a float reduction would not, without fast-math).
  bool gradients_finite(size_t M, const double v_pose[6]) const;
  // Plans every capacity-sized array for cap() rows: the renderer, decoder workspace and
  // registrar, the densification statistics and growth scratch (resize: live rows keep their
  // values), and the byte count. Called at creation and after the rows grow.
  Status plan(const TrainOptions& options);
  // Creates the registrar when the run has registration passes (see plan_registrar in trainer.cpp);
  // held-back views' passes create it themselves (create_registrar) and free it when done.
  Status plan_registrar(const TrainOptions& options);
  Status create_registrar();
  // Dry run of the decoder's visibility test: the most live anchors one training view sees.
  size_t most_visible_anchors() const;
  // Memory follows the scene: the rows (model, Adam moments, gradients, statistics, pipeline) grow
  // to hold `rows` anchors, by at least half again, never past the anchor budget. Values of the
  // live rows are kept; results do not depend on the capacity.
  Status ensure_capacity(size_t rows);
  // Every anchor's raw image feature from the current poses (visible mode: after the depth buffers
  // of the current anchors, discs of one voxel).
  void refresh_image_features();
  void build_groups();
  ModelGradsT<float> grads();
  // The next training view, skipping held-back ones (create() refuses a run with every view held).
  int next_view();
  // View v takes a pose found by registration: its Adam state starts again.
  void adopt_pose(size_t v, const Pose& pose);
  // Registers every held-back view against the current model; a converged one gets that pose
  // (Adam state reset) and joins training. Returns how many joined. Several starts per view: its
  // own pose, the poses of the trained views next to it in capture order (by name) and of those
  // whose photos look most like it (descriptors), searched at kHeldSearchDownscale, then the own
  // pose and the best converged search at kHeldDecideDownscale; the converged result with the
  // lowest residual wins, and a view moved there is registered again at full resolution.
  // A view moves only when a converged pose away from the given one fits clearly better
  // (kRepairRmseRatio) or better with the points preferring it (TrainOptions::judge_new_pose);
  // else it rejoins at its given pose if the registration from it converged there, or to a pose
  // the points contradict.
  // Views repaired (moved) by an earlier pass are registered again from their pose (the model is better
  // now) and keep the result when it converges to a lower residual.
  Status register_held(int it, int* released);
  // Up to kHeldStarts start poses for held view v (see register_held); returns how many.
  static constexpr int kHeldStarts = 5;
  // A held view whose registration from its own pose converges within these of it is confirmed
  // at that pose (degrees; fraction of the scene extent): it rejoins unchanged.
  static constexpr double kConfirmDeg = 1.0, kConfirmExtent = 0.01;
  // A held view moves to a registered pose only when that pose's RMSE is below this fraction of
  // the RMSE at its given pose (see register_held).
  static constexpr double kRepairRmseRatio = 0.7;
  // The resolution divisors of the search from a held view's starts and of the registrations that
  // decide whether it is confirmed or moved (register_held).
  static constexpr int kHeldSearchDownscale = 4, kHeldDecideDownscale = 2;
  int held_starts(size_t v, Pose* starts) const;
  void describe_photos();  // fills descriptors
  // Target at resolution divisor s (s x s block means, matching scaled_camera), composited on bg;
  // a view with missing pixels (DatasetView::valid) sets ws.valid_pixels for the step (else null).
  void load_target(const io::DatasetView& v, int s, const float bg[3]);
  // Coarse-to-fine level (0 = coarsest) of iteration it when the coarse phase ends at `end`.
  int coarse_level(int it, double end) const;
  int downscale_at(int it) const;
  // Registers every training pose against the current model (see TrainOptions); returns how many
  // poses moved.
  Status register_all(int it, int* moved);
  // One Adam step on the pose of view vi from its twist gradient g (rho, phi), retracted on SE(3).
  void pose_adam(size_t vi, const double g[6], int it);
  void adam_all(int it);

  // Densification statistics, anchor growing and pruning (trainer_anchors.cpp).
  void accumulate_stats(const Camera& cam);
  // Moves anchor row src to dst in every per-anchor array (model, optimiser, statistics).
  void move_row(size_t src, size_t dst);
  // Clears a newly added anchor row's optimiser state and statistics.
  void clear_row(size_t row);
  // One growth level (Part B section 7 step 2); returns the number of anchors added.
  size_t growth_allowance() const;
  size_t grow_level(int level, double min_denom, size_t allowance);
  void adjust_anchors();
};

}  // namespace gs::model
