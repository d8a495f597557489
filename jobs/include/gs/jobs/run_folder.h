// SPDX-License-Identifier: MIT
// What the jobs share about a training run folder: its file names (run.json names the dataset
// and options), finding the model and dataset behind a run or .hbgs path, loading a dataset split,
// and the LPIPS weights.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gs/gaussians.h"
#include "gs/io/colmap.h"
#include "gs/metrics/lpips.h"
#include "gs/model/background.h"
#include "gs/model/compact_model.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::jobs {

// File names inside a run folder.
inline constexpr const char* kRunJson = "run.json";
inline constexpr const char* kModelFile = "model.hbgs";
inline constexpr const char* kCheckpointFile = "checkpoint.bin";
inline constexpr const char* kProgressFile = "progress.json";  // train-time figures at the checkpoint
inline constexpr const char* kResultsJson = "results.json";
inline constexpr const char* kPerViewJson = "per_view.json";
inline constexpr const char* kPsnrCsv = "psnr_vs_time.csv";
inline constexpr const char* kPsnrSvg = "psnr_vs_time.svg";

// True for a model file (.hbgs, .hbgc, or any file starting with a model magic: float or compact),
// a file of plain Gaussians (is_splat_file) or a folder holding run.json or model.hbgs (a run).
bool is_model_input(const std::string& path);
// True for a regular file in one of the splat formats hbgs reads as a model (3DGS PLY,
// compressed.ply, .splat, .spz: gs/io/splat_formats.h), by its extension.
bool is_splat_file(const std::string& path);

// The model file, dataset and image width limit behind a run folder or .hbgs file. dataset and
// max_width come from the run's run.json unless overridden (dataset_override non-empty,
// max_width_override >= 0). run_dir is the folder holding the model.
struct ModelSource {
  std::string model_path, run_dir, dataset;
  int max_width = 0;
  double fisheye_fov = 0;  // run.json's "fisheye_fov" (io::DatasetOptions::fisheye_fov_deg; 0: automatic)
  std::string background = "black";  // the run's training background (run.json; black without one)
};
// The background to render a model on: override (parse_background's text) when not empty, else the
// run's; "random" means the colour a random-background run is evaluated on (black).
Expected<model::Background> model_background(const ModelSource& source, const std::string& override_text);
Expected<ModelSource> resolve_model_source(const std::string& path, const std::string& dataset_override,
                                           int max_width_override);

// Loads the dataset views of split "test", "train" or "all"; errors name the dataset and split.
struct LoadedDataset {
  io::Dataset dataset;
  std::vector<const io::DatasetView*> views;  // the chosen split, into dataset.views
};
// frame: the scene frame to load it into (a model's); null: the dataset's own (choose_scene_frame).
// fisheye_fov: io::DatasetOptions::fisheye_fov_deg.
Expected<std::unique_ptr<LoadedDataset>> load_dataset_split(const std::string& root, int max_width,
                                                             const std::string& split, const SceneFrame* frame = nullptr,
                                                             double fisheye_fov = 0);

// A trained model (run folder or .hbgs file, as resolve_model_source) with the views of split
// `split` of its dataset: what evaluation, rendering and batch registration start from.
struct ModelViews {
  ModelSource source;
  model::HybridModel model;                      // the anchor model (empty when cloud is set)
  std::unique_ptr<model::CompactModel> compact;  // set when the model file is a compact one
  std::unique_ptr<GaussianCloud> cloud;          // set when the input is a splat file (plain Gaussians)
  std::unique_ptr<LoadedDataset> data;
  // World size for registration steps and limits: the model's, or for a cloud the training
  // cameras' (model::cameras_extent).
  float scene_extent() const;
  // The scene frame everything above is in (gs/scene_frame.h): the model's, which its dataset was
  // loaded into; for plain Gaussians their dataset's, which they were moved into.
  const SceneFrame& frame() const { return data->dataset.frame; }
};
// fisheye_fov_override >= 0: that field of view for fisheye cameras instead of the run's.
Expected<ModelViews> load_model_views(const std::string& input, const std::string& dataset_override, int max_width_override,
                                      const std::string& split, double fisheye_fov_override = -1);

// Evaluates the loaded model or cloud on views (gs/model/evaluate.h).
Expected<model::EvalResult> evaluate_loaded(const ModelViews& loaded, const std::vector<const io::DatasetView*>& views,
                                            const model::EvalOptions& options, platform::ThreadPool* pool);

// The default LPIPS-Alex weights folder: $HBGS_LPIPS_WEIGHTS when set, else the first
// shared/data/lpips_alex (holding weights.bin) beside the current folder or beside one of the
// program's ancestor folders (a checkout next to ../shared); "" when there is none. Nothing about
// the build machine is compiled in.
std::string default_lpips_dir();
// The LPIPS weights: explicit_dir (must load) or default_lpips_dir(); null when there are none
// (*note then says why LPIPS is not computed).
Expected<std::unique_ptr<metrics::LpipsAlex>> load_lpips(const std::string& explicit_dir, int threads,
                                                         std::string* note);

// A dataset as the jobs take it: a folder (COLMAP, or NeRF-style with transforms.json or
// transforms_train.json), or a NeRF-style transforms .json file (what io::load_dataset reads).
// Refuses anything else with a message giving both forms; io::load_dataset checks the contents.
Status check_dataset_path(const std::string& dataset);
// The folder a dataset lives in: the path itself for a folder, the json's folder for a .json file.
std::string dataset_folder(const std::string& dataset);

// Refuses an output folder that exists as a file, that is the dataset folder (for a .json dataset,
// its folder), or that lies inside the dataset's images*/ or sparse/ folders (symbolic links
// resolved): renders or a run there would change the dataset. A sub-folder of its own
// ("DATASET/renders") is allowed. Render and train call it before writing anything.
Status check_output_outside_dataset(const std::string& out, const std::string& dataset);

std::string absolute_path(const std::string& path);
uint64_t file_size_or_zero(const std::string& path);

}  // namespace gs::jobs
