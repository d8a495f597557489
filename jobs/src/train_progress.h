// SPDX-License-Identifier: MIT
// Private to the training job: the training-time figures saved beside each checkpoint
// (progress.json), so a resumed run continues them, and the PSNR-vs-time files derived from them.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/stage_times.h"
#include "gs/status.h"
#include "psnr_plot.h"

namespace gs::jobs {

// Training-time figures saved next to each checkpoint, so a resumed run continues them.
struct Progress {
  int iteration = 0;
  double train_seconds = 0;
  double train_cpu_seconds = 0;  // process CPU time of the training steps, all threads
  std::vector<PsnrRow> rows;
  std::vector<float> iteration_ms;  // one per iteration, in order
  std::vector<float> losses;        // the training loss of every iteration, in order
  int skipped_steps = 0;            // steps the numerical guard skipped (non-finite loss or gradient)
  // Wall ms of each training stage (gs/stage_times.h) summed over stage_iterations timed steps
  // (every step of the run; a resumed run continues the sums).
  double stage_ms[kStageCount] = {};
  int stage_iterations = 0;
  // Mean ms per iteration of a stage (0 before any step).
  double stage_ms_per_iteration(int s) const { return stage_iterations > 0 ? stage_ms[s] / stage_iterations : 0.0; }
};

// {stage name: mean ms per iteration} of a run's steps (progress.json, results.json).
nlohmann::json stage_ms_json(const Progress& p);

Status save_progress_to(const std::string& path, const Progress& p);
// Progress at checkpoint iteration `at`. progress.json is written right after checkpoint.bin, so a
// kill between the two leaves it one checkpoint behind: its time is then extended by the median
// iteration time, and anything past `at` is dropped.
Progress load_progress(const std::string& run, int at, const std::function<void(const std::string&)>& say);
// <run>/psnr_vs_time.csv and .svg from the rows.
Status write_psnr_files(const std::string& run, const std::vector<PsnrRow>& rows, const std::string& title);

}  // namespace gs::jobs
