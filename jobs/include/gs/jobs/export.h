// SPDX-License-Identifier: MIT
// The export job (`hbgs export`): a trained anchor model (run folder or model file, float or compact)
// baked into plain Gaussians with SH colour over its dataset's training cameras (gs/model/bake.h)
// and written in the splat format the output's extension names (3DGS PLY, compressed.ply, .splat,
// .spz: gs/io/splat_formats.h), atomically; or a splat file converted to another format as it is.
// Optionally measured: test PSNR of the input and of the Gaussians as written (read back from the
// file, so the format's quantisation counts).
#pragma once

#include <cstdint>
#include <string>

#include "gs/io/splat_formats.h"
#include "gs/jobs/run_folder.h"
#include "gs/model/bake.h"
#include "gs/model/evaluate.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::jobs {

struct ExportRunOptions {
  std::string input;        // run folder, model file (.hbgs or .hbgc) or splat file (converted, with --dataset to measure)
  std::string out;          // the file to write; its extension picks the format
  std::string dataset;      // "" : the one in the run's run.json
  int max_width = -1;       // -1: as trained
  int threads = 0;          // 0: all CPUs
  int sh_degree = 3;        // 0..3 (.splat keeps degree 0 only)
  int distill_iterations = 2000;  // steps of distillation against the model's renders (0: the fit only)
  bool evaluate = true;     // test PSNR of the model and of the written Gaussians
  uint64_t seed = 0;
  io::SplatWriteOptions write;  // the format's options: write.spz.version (4, or 3 for older readers)
};

struct ExportRunSummary {
  ModelSource source;
  io::SplatFormat format = io::SplatFormat::kPly;
  model::BakeStats bake;
  size_t gaussians = 0;
  uint64_t bytes = 0;  // of the written file
  bool evaluated = false;
  model::EvalResult model_eval, baked_eval;  // test views, 8-bit renders
  double seconds = 0;
};

Status export_run(const ExportRunOptions& options, ExportRunSummary* summary);

// What the export job and the report page (gs/jobs/report.h) share:
// Refuses an input that is not an anchor model to bake (missing, plain Gaussians already, neither
// a run folder nor a model file), with a message naming it.
Status check_bake_input(const std::string& input);
// Bakes the loaded anchor model over its dataset's training cameras (model::bake_model) on
// `background` (the run's training background); options.background is overwritten with it.
// Errors: no training views, the bake's own.
Expected<GaussianCloud> bake_over_training_views(const ModelViews& loaded, const model::Background& background,
                                                 model::BakeOptions options, platform::ThreadPool* pool,
                                                 model::BakeStats* stats);

}  // namespace gs::jobs
