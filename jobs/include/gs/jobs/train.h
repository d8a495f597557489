// SPDX-License-Identifier: MIT
// The training job: everything `hbgs train` does, as one library call. It checks the inputs before
// touching the run folder, optionally perturbs the poses (seeded noise protocol), re-estimates them
// by structure from motion (COLMAP) and aligns them to the SfM points, trains the hybrid anchor
// model (jointly with the poses when asked), evaluates it, and keeps the run folder resumable:
//
//   run.json                     the dataset and every option (eval, render and resume read it)
//   checkpoint.bin progress.json the complete training state and the figures up to it
//   psnr_vs_time.csv/.svg        test PSNR against training seconds
//   model.hbgs model_<it>.hbgs   the final model and the ones at save_at
//   results.json per_view.json   the 3DGS schema, one method per fully evaluated iteration
//   test/ours_<it>/renders/      test renders; refined_poses/ sfm_init/ with pose optimisation
//
// TrainRunOptions holds every default once: the CLI binds its flags to a default-constructed one,
// and bench_train and the examples start from the same struct, so all run one configuration.
//
// Structure from motion (pose_init "sfm") runs COLMAP through the capture library, which the jobs
// library does not link (the on-device set base..jobs has no capture): the program passes an
// SfmPoseInitializer (TrainRunOptions::sfm_pose_init). `hbgs` passes one made of gs_capture's
// choose_sfm_images and init_poses_by_sfm (apps/hbgs/colmap_pose_init.cpp); `hbgs-device` passes
// none and refuses --pose-init sfm.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/model/evaluate.h"
#include "gs/model/trainer.h"
#include "gs/pose/pose.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::jobs {

class SfmPoseInitializer;

struct TrainRunOptions {
  std::string dataset;  // COLMAP dataset folder with SfM points (images/, sparse/0/)
  std::string out;      // run folder (train_run only)
  int iterations = 30000;  // with a time budget: the most it may run (a cap)
  // Seconds of training (the steps, as train_seconds counts them: not loading, evaluation or
  // checkpoints) the whole schedule is fitted into; 0: none, the run is `iterations` long. The run
  // measures its pace as it goes, predicts how many iterations fit (at most `iterations`) and
  // re-targets its schedule to that length (set_run_length, model::Trainer::retarget), stops
  // before an iteration that would end past the budget, and ends with the usual evaluation. A
  // resumed run has what is left of it (budget minus the train_seconds already recorded).
  double time_budget = 0;
  // The clock the training steps are timed with (train_seconds, the time budget); null:
  // platform::now_seconds. Tests inject a fake one. Not an option: run.json does not record it.
  std::function<double()> clock;
  std::string image_features = "paper";  // "paper" or "none" (plain Scaffold-GS)
  // What renders are blended on and masked views composited on (gs/model/background.h): black,
  // white, random (a colour per iteration; evaluated on black) or r,g,b.
  std::string background = "black";
  size_t max_anchors = 50000, max_gaussians = 500000;
  // Growth budget: neural Gaussians per training view at most this many per pixel of the view (0: no
  // budget; model::TrainOptions::growth_gaussians_per_pixel).
  double gaussians_per_pixel = 0;
  // Weight of the opacity term, x mean opacity of the kept Gaussians (model::StepConfig::
  // opacity_weight; 0: none).
  double opacity_reg = 0;
  float voxel_size = 0.0f;  // anchor voxel size in world units (0: automatic)
  // A dataset without a point cloud whose training views all have masks starts from points carved
  // from the masks (gs::io::carve_points_from_masks) instead of its random points; false: random.
  bool carve_points = true;
  // Neural Gaussians (offsets) per anchor, k. -1: automatic (effective_offsets): 7 for a run under a
  // time budget or shorter than 15,000 iterations, where quality per second is what counts; 10
  // (Scaffold-GS's and the paper's k) for longer runs.
  int offsets = -1;
  int feature_dim = 32;     // learned anchor feature width
  uint64_t seed = 0;        // MLP initialisation and view order
  int threads = 0;          // worker threads (0: all CPUs)
  int max_width = 0;        // downscale views to at most this width (0: as stored)
  double fisheye_fov = 0;   // fisheye cameras' pinhole field of view, degrees (0: automatic; io::DatasetOptions)
  int checkpoint_every = 1000, eval_every = 500;  // 0: only at the end / never
  std::string save_at = "1000,7000,30000";       // iterations saving model_<it>.hbgs with a full evaluation
  std::string lpips_weights;                     // "" : default_lpips_dir()
  // Poses: seeded noise on the input poses (gs::pose::parse_pose_noise) on "train", "test" or
  // "all" views; joint optimisation; before it, SfM re-initialisation (pose_init "sfm", COLMAP on
  // sfm_images: "auto", "train" or a folder) and the alignment to the SfM points (point_align).
  std::string pose_noise = "none", pose_noise_on = "train";
  bool optimize_poses = false;
  bool point_align = true;
  // Every training view's agreement with the SfM points at its pose before training (TrainSession,
  // pose::suspect_views): views the points contradict are held back, with optimize_poses until a
  // registration against the model places them, without it for the whole run. Needs SfM points
  // (not random or carved ones).
  bool view_check = true;
  int register_passes = 0;         // registration passes of every training pose over the first half
  std::string pose_init = "none";  // "none" or "sfm"
  std::string colmap = "colmap";   // the COLMAP program for pose_init "sfm"
  std::string sfm_images = "auto";
  // What pose_init "sfm" runs (not owned; null: pose_init "sfm" is refused, except to resume a run
  // whose poses SfM already initialised). Not an option: run.json does not record it.
  const SfmPoseInitializer* sfm_pose_init = nullptr;
  // Coarse to fine: resolution halvings over the first coarse_fraction of the iterations. -1: 2 levels
  // over 0.3 when optimising poses without SfM initialisation, none when refining SfM poses, else 1
  // level over 0.5 (half resolution for the first half: speed at no cost in quality).
  int coarse_levels = -1;
  double coarse_fraction = -1;
  int feature_refresh = -1;  // image features recomputed every N iterations (-1: 250 when optimising poses, else 0)
  double pose_lr = 5e-5;     // initial pose learning rate (rad; translation x scene extent)
  bool resume = false, force = false;
  std::string isa;  // kernel table by name (gs/simd/kernel_table.h); "" : the best for this CPU
  // With resume: the options set explicitly (long flag names such as "iterations"); the others
  // come from the run's run.json, and model options that differ from it are refused.
  std::vector<std::string> given;
};

// The trainer's options and the model's configuration these options resolve to (every "auto"
// value decided here, in one place).
struct ResolvedTraining {
  model::ModelConfig model;
  model::TrainOptions train;
};
Expected<ResolvedTraining> resolve_training(const TrainRunOptions& options);
// The neural Gaussians per anchor a run trains with: options.offsets, or when that is -1 the
// automatic choice (TrainRunOptions::offsets). A run records this value in run.json, so a resumed
// run keeps it.
int effective_offsets(const TrainRunOptions& options);
// Everything in the trainer's options that follows from the run's length, for a run of
// `iterations` iterations: the learning-rate horizon, the densification window, the pose warm-up,
// the registration passes, the held-back views' registrations (and coarse to fine, from
// TrainOptions::iterations). resolve_training sets it for options.iterations; a time-budgeted run
// again for each new prediction of its length (model::Trainer::retarget).
void set_run_length(const TrainRunOptions& options, int iterations, model::TrainOptions* train);

// --time-budget: a positive duration, seconds without a unit or with s, m or h ("60s", "90", "3m",
// "1.5m", "1h"); at most 10,000,000 s. Errors name the text and what is accepted.
Expected<double> parse_time_budget(const std::string& text);

// What the job reports while it runs. kNote, kStage and kDetail (a line of a sub-step such as
// COLMAP) carry a line of text; kIteration carries the
// iteration's statistics; kPoseErrors the training-pose errors every eval_every iterations.
struct TrainEvent {
  enum Kind { kNote, kStage, kDetail, kIteration, kPoseErrors } kind = kNote;
  std::string message;
  // kIteration: the iteration and the run's length (with a time budget: its current prediction).
  int iteration = 0, iterations = 0;
  const model::IterationStats* stats = nullptr;  // kIteration
  bool last = false;                             // kIteration: the run's last iteration
  double budget_seconds = 0, remaining_seconds = 0;  // kIteration with a time budget: the budget and what is left
  pose::PoseErrors pose_errors;                  // kPoseErrors (Sim(3)-aligned, against the true poses)
};
using TrainProgressFn = std::function<void(const TrainEvent&)>;

// Global pose initialisation by structure from motion for pose_init "sfm", injected through
// TrainRunOptions::sfm_pose_init. The job then aligns the result to the SfM points and reports it.
struct SfmPoseInitRequest {
  std::string dataset_folder;                 // the dataset's folder (sfm_images are looked up there)
  std::string sfm_images;                     // TrainRunOptions::sfm_images: "auto", "train" or a folder
  std::string colmap;                         // the COLMAP program
  int threads = 0;                            // 0: COLMAP's default
  std::vector<const io::DatasetView*> views;  // the training views (images, cameras)
  std::vector<std::string> names;             // [views] their unique names
  const float* points_xyz = nullptr;          // the dataset's SfM points [points, 3]
  size_t points = 0;
  std::string work_dir;                       // created and kept (images, database, COLMAP's log)
};
struct SfmPoseInitResult {
  std::vector<Pose> poses;          // [views] the registered views' poses replaced, the others as given
  std::vector<uint8_t> registered;  // [views] 1 where SfM registered the view
  // [views] 1 where SfM's consistency check found the view suspect (other mappings of the same
  // matches place it elsewhere), and the largest rotation difference there (degrees); empty: no check.
  std::vector<uint8_t> suspect;
  std::vector<double> disagreement_deg;
  // The mapper seed of the reconstruction used (0: the first mapping; another when the consistency
  // check found a check run the others agree with more) and the views the first mapping had doubted.
  int chosen_seed = 0, first_run_suspect = 0;
  // The report (results.json "sfm_init"): which images COLMAP saw ("training images" or a folder)
  // and their size, the reconstruction, and the Sim(3) fit into the dataset's frame.
  std::string images;
  int image_width = 0, image_height = 0;
  int views = 0, registered_views = 0, colmap_points = 0, icp_pairs = 0, icp_iterations = 0;
  double seconds = 0, centre_fit_rms = 0, icp_median_before = 0, icp_median_after = 0;
};
class SfmPoseInitializer {
 public:
  virtual ~SfmPoseInitializer() = default;
  // What can be checked before the run folder is touched: the COLMAP program, an explicit
  // sfm_images folder. Errors name the option.
  virtual Status check(const std::string& dataset_folder, const std::string& sfm_images, const std::string& colmap) const = 0;
  // Estimates the training poses; progress gets kNote, kStage and kDetail events. Errors name the option.
  virtual Status run(const SfmPoseInitRequest& request, const TrainProgressFn& progress, SfmPoseInitResult* result) const = 0;
};

// A prepared training: the dataset loaded (with pose noise), the poses initialised, the model and
// trainer created; nothing written except SfM's work folder (<work_dir>/sfm_init with pose_init sfm).
// bench_train steps one of these; train_run adds the run folder, evaluation and checkpoints.
class TrainSession {
 public:
  static Expected<std::unique_ptr<TrainSession>> create(const TrainRunOptions& options, const TrainProgressFn& progress,
                                                        const std::string& work_dir = "");
  ~TrainSession();

  model::Trainer& trainer();
  platform::ThreadPool& pool();
  const simd::KernelTable& kernels() const;  // the table the trainer runs (options.isa or the best)
  const std::vector<const io::DatasetView*>& train_views() const;
  const std::vector<const io::DatasetView*>& test_views() const;
  // Sim(3)-aligned errors of the current training poses against the true (pre-noise) ones.
  pose::PoseErrors train_pose_errors(bool align = true) const;

 private:
  TrainSession();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  friend class TrainRun;  // train_run's steps (train_run.cpp)
};

struct TrainRunSummary {
  std::string run_dir, model_path, image_features, isa;
  int iterations = 0, resumed_from = -1, threads = 0;
  bool have_test_views = false;
  model::EvalResult final_eval;  // the test views at the last iteration
  double train_seconds = 0, median_iteration_ms = 0, mean_gaussians = 0;
  int skipped_steps = 0;  // steps skipped by the numerical guard (non-finite loss or gradient)
  double time_budget = 0;        // the run's time budget in seconds (0: none)
  double schedule_progress = 0;  // fraction of the learning-rate schedules reached (model::Trainer::schedule_progress)
  // Mean wall ms per iteration of each training stage (gs/stage_times.h: index by Stage), over the
  // run's steps; progress.json holds the same as "stage_ms_per_iteration".
  double stage_ms_per_iteration[kStageCount] = {};
  size_t anchors = 0, train_views = 0, test_views = 0;
  uint64_t model_bytes = 0, model_file_bytes = 0;
  pose::PoseErrors train_pose_input, train_pose_final;  // Sim(3)-aligned, against the true poses
};

// Trains into options.out. Errors leave no run folder behind when they are found before training
// starts; afterwards the last checkpoint stays resumable (options.resume).
Status train_run(const TrainRunOptions& options, const TrainProgressFn& progress, TrainRunSummary* summary);

}  // namespace gs::jobs
