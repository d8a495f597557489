// SPDX-License-Identifier: MIT
// The rendering job (`hbgs render`): every selected view of a COLMAP dataset rendered with
// gs::Renderer (Gaussians from a 3DGS PLY, or initialised from the dataset's SfM points), or of a
// trained model's dataset (a run folder or .hbgs file) with the model; one PNG per view (named after
// its image) and <out>/render.json with per-view timing and PSNR against the dataset's images.
// A failure leaves no file of this run behind.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::jobs {

struct RenderRunOptions {
  std::string input;          // COLMAP dataset folder, or a run folder / .hbgs model
  std::string out;            // folder for <image>.png and render.json
  std::string ply;            // dataset input: a 3DGS PLY with the Gaussians ("" : from the SfM points)
  std::string model_dataset;  // model input: its dataset ("" : from the run's run.json)
  int max_width = -1;         // downscale views to at most this width (-1: full size; a model: as trained)
  int threads = 0;            // 0: all CPUs
  std::string isa;            // dataset input: kernel table ("" : the best for this CPU)
  std::string split = "all";  // "all", "train" or "test"
  // Background (gs/model/background.h text: black, white or r,g,b): "" is black for a dataset and
  // the run's training background for a model.
  std::string background;
  bool fixed_point = false;   // model input: the on-device fixed-point blending (RenderOptions::fixed_point)
};

struct RenderedView {
  std::string name, png;  // the image name and its PNG, relative to out
  bool is_test = false;
  int width = 0, height = 0;
  double ms = 0;
  double psnr = 0;    // dB against the dataset image (+inf when identical)
  double ssim = -1;   // model input only
  size_t gaussians = 0;  // visible Gaussians (dataset input) or kept neural Gaussians (model input)
};

struct RenderRunSummary {
  bool from_model = false;
  std::string dataset, source;  // source: the model file, the PLY, or "sfm points"
  std::string isa, json_path;
  std::vector<RenderedView> views;
  size_t gaussians = 0, anchors = 0;  // dataset input / model input
  int max_width = 0, max_height = 0, threads = 0;
  double median_ms = 0, mean_ms = 0, mean_psnr = 0, mean_ssim = -1, load_seconds = 0, total_seconds = 0;
};

// progress: called after each view with its result, its 1-based number and the count.
Status render_run(const RenderRunOptions& options, const std::function<void(const RenderedView&, size_t, size_t)>& progress,
                  RenderRunSummary* summary);

}  // namespace gs::jobs
