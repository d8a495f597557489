// SPDX-License-Identifier: MIT
// The evaluation job (`hbgs eval`): a trained model (run folder or .hbgs file) on a split of its
// dataset: PSNR, SSIM and LPIPS-Alex merged as one method into <out>/results.json and
// per_view.json (3DGS schema), optionally with the renders.
#pragma once

#include <cstddef>
#include <string>

#include "gs/jobs/run_folder.h"
#include "gs/model/evaluate.h"
#include "gs/status.h"

namespace gs::jobs {

struct EvaluateRunOptions {
  std::string input;          // run folder (from train_run) or .hbgs model file
  std::string dataset;        // "" : the one recorded in the run's run.json
  std::string out;            // "" : <run>/eval
  std::string lpips_weights;  // "" : default_lpips_dir()
  std::string method = "ours";  // method key in the JSON files
  std::string split = "test";   // "test", "train" or "all"
  int max_width = -1;           // -1: as trained
  double fisheye_fov = -1;      // fisheye cameras' pinhole field of view, degrees (-1: as trained, 0: automatic)
  int threads = 0;              // 0: all CPUs
  bool renders = false;         // also write <out>/<split>/<method>/renders/*.png
  bool fixed_point = false;     // the on-device path: fixed-point blending (RenderOptions::fixed_point)
  std::string background;       // black, white or r,g,b ("" : the run's training background)
  bool composite_renders = false;  // renders composited through the views' masks (model::EvalOptions)
};

struct EvaluateRunSummary {
  ModelSource source;
  std::string out_dir, render_dir;  // render_dir "" unless renders
  model::EvalResult result;
  size_t anchors = 0;
  double mean_gaussians = 0, seconds = 0;
  std::string note;  // why LPIPS was not computed, or a replaced unreadable file ("" : nothing to say)
};

Status evaluate_run(const EvaluateRunOptions& options, EvaluateRunSummary* summary);

}  // namespace gs::jobs
