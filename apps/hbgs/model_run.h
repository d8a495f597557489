// SPDX-License-Identifier: MIT
// What train, eval, render and demo share about a training run: the run folder's files (run.json
// names the dataset and options), finding the model and dataset behind a run or .hbgs path, the
// LPIPS weights, and evaluating a model into results.json / per_view.json.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/metrics/lpips.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/pose.h"
#include "gs/status.h"

namespace hbgs::cli {

// File names inside a run folder.
inline constexpr const char* kRunJson = "run.json";
inline constexpr const char* kModelFile = "model.hbgs";
inline constexpr const char* kCheckpointFile = "checkpoint.bin";
inline constexpr const char* kProgressFile = "progress.json";  // train-time figures at the checkpoint
inline constexpr const char* kResultsJson = "results.json";
inline constexpr const char* kPerViewJson = "per_view.json";

// True for a .hbgs file or a folder holding run.json or model.hbgs (a training run).
bool is_model_input(const std::string& path);

// The model file, dataset and image width limit behind a run folder or .hbgs file. dataset and
// max_width come from the run's run.json unless overridden (dataset_override non-empty,
// max_width_override >= 0). run_dir is the folder holding the model.
struct ModelSource {
  std::string model_path, run_dir, dataset;
  int max_width = 0;
};
gs::Expected<ModelSource> resolve_model_source(const std::string& path, const std::string& dataset_override,
                                               int max_width_override);

// Loads the dataset views of split "test", "train" or "all"; errors name the dataset and split.
struct LoadedDataset {
  gs::io::Dataset dataset;
  std::vector<const gs::io::DatasetView*> views;  // the chosen split, into dataset.views
};
gs::Expected<std::unique_ptr<LoadedDataset>> load_dataset_split(const std::string& root, int max_width,
                                                                 const std::string& split);

// The LPIPS weights folder: explicit (must load), or ../shared/data/lpips_alex next to the source
// tree when present. Returns null (after saying so on stderr unless quiet) when there are none.
gs::Expected<std::unique_ptr<gs::metrics::LpipsAlex>> load_lpips(const std::string& explicit_dir, int threads,
                                                                bool quiet);
std::string default_lpips_dir();  // "" when the folder is absent

// Evaluates views and merges the result as `method` into <dir>/results.json and per_view.json
// (other methods already in them are kept). extra_members: JSON object members for results.json.
gs::Status write_eval_files(const std::string& dir, const std::string& method, const gs::model::EvalResult& r,
                            const std::string& extra_members);

// Members of a JSON object without its braces, for results_json's extra_json_members.
std::string json_members(const std::string& object_dump);

std::string absolute_path(const std::string& path);
uint64_t file_size_or_zero(const std::string& path);

// `hbgs train`, callable from `hbgs demo`. Options given on the command line are listed in `given`
// (long names without dashes): with --resume, the others come from the run's run.json.
struct TrainArgs {
  std::string dataset, out;
  int iterations = 30000;
  std::string image_features = "paper";
  size_t max_anchors = 50000, max_gaussians = 500000;
  float voxel_size = 0.0f;
  uint64_t seed = 0;
  int threads = 0;
  int max_width = 0;
  int checkpoint_every = 1000, eval_every = 500;
  std::string save_at = "1000,7000,30000";
  std::string lpips_weights;
  // Poses: seeded noise on the input poses, joint optimisation, coarse to fine (-1: 2 levels when
  // optimising poses, else 0), the initial pose learning rate (rotation rad, translation x extent).
  std::string pose_noise = "none", pose_noise_on = "train";
  bool optimize_poses = false;
  bool point_align = true;  // with optimize_poses: align the poses to the SfM points first
  int register_passes = 0;  // with optimize_poses: registration passes over the first half
  std::string pose_init = "none";  // with optimize_poses: "sfm" = global initialisation by COLMAP first
  std::string colmap = "colmap";   // the COLMAP program for pose_init sfm
  std::string sfm_images = "auto"; // pose_init sfm: "auto", "train" or a folder (gs/capture/sfm_images.h)
  int coarse_levels = -1;
  int feature_refresh = -1;        // image features recomputed every N iterations (-1: 250 with optimize_poses, else 0)
  double pose_lr = 5e-5;
  bool resume = false, force = false, quiet = false;
  std::vector<std::string> given;
};

struct TrainSummary {
  std::string run_dir, image_features;
  int iterations = 0;
  gs::model::EvalResult final_eval;
  bool have_test_views = false;
  double train_seconds = 0, median_iteration_ms = 0, mean_gaussians = 0;
  size_t anchors = 0, train_views = 0, test_views = 0;
  uint64_t model_bytes = 0, model_file_bytes = 0;
  std::string isa;
  int threads = 0;
  bool have_pose_errors = false;
  gs::pose::PoseErrors train_pose_input, train_pose_final;  // Sim(3)-aligned, against the true poses
};
int run_train(const TrainArgs& args, TrainSummary* summary);

}  // namespace hbgs::cli
