// SPDX-License-Identifier: MIT
// The compact job (`hbgs compact`): a trained model (run folder or model file) quantised into a
// compact model file (gs/model/compact_model.h), pruned and calibrated on its dataset's training
// views, and measured: file sizes and test-view PSNR of the float and the compact model.
#pragma once

#include <cstdint>
#include <string>

#include "gs/jobs/run_folder.h"
#include "gs/model/compact_model.h"
#include "gs/model/evaluate.h"
#include "gs/status.h"

namespace gs::jobs {

struct CompactRunOptions {
  std::string input;     // run folder or model file (float or compact)
  std::string out;       // compact file to write (required)
  std::string dataset;   // "" : the one in the run's run.json
  int max_width = -1;    // -1: as trained
  int threads = 0;       // 0: all CPUs
  bool evaluate = true;  // measure test PSNR of both models
  model::CompactOptions compact;
};

struct CompactRunSummary {
  ModelSource source;
  uint64_t float_bytes = 0, compact_bytes = 0;
  model::CompactStats stats;
  bool evaluated = false;
  model::EvalResult float_eval, compact_eval;  // test views, 8-bit renders
  double seconds = 0;
};

Status compact_run(const CompactRunOptions& options, CompactRunSummary* summary);

}  // namespace gs::jobs
