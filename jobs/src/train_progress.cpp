// SPDX-License-Identifier: MIT
// progress.json and psnr_vs_time.csv/.svg of a training run (train_progress.h).
#include "train_progress.h"

#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "gs/jobs/run_folder.h"
#include "gs/platform/file.h"
#include "gs/stats.h"
#include "text_util.h"

namespace gs::jobs {

namespace fs = std::filesystem;

Status write_psnr_files(const std::string& run, const std::vector<PsnrRow>& rows, const std::string& title) {
  std::string csv = "iteration,train_seconds,test_psnr\n";
  for (const PsnrRow& r : rows) csv += std::to_string(r.iteration) + "," + fixed(r.seconds, 3) + "," + fixed(r.psnr, 4) + "\n";
  GS_RETURN_IF_ERROR(platform::write_file_atomic((fs::path(run) / kPsnrCsv).string(), csv));
  return platform::write_file_atomic((fs::path(run) / kPsnrSvg).string(), psnr_svg(rows, title));
}

nlohmann::json stage_ms_json(const Progress& p) {
  nlohmann::json j = nlohmann::json::object();
  for (int s = 0; s < kStageCount; ++s) j[stage_name(s)] = p.stage_ms_per_iteration(s);
  return j;
}

Status save_progress_to(const std::string& path, const Progress& p) {
  nlohmann::json j;
  j["iteration"] = p.iteration;
  j["train_seconds"] = p.train_seconds;
  j["train_cpu_seconds"] = p.train_cpu_seconds;
  nlohmann::json rows = nlohmann::json::array();
  // A non-finite PSNR (+inf: a render identical to its images) is null, as in every hbgs JSON; read
  // back as NaN, which the plot leaves out (it was written as 0 dB before).
  for (const PsnrRow& r : p.rows)
    rows.push_back({r.iteration, r.seconds, std::isfinite(r.psnr) ? nlohmann::json(r.psnr) : nlohmann::json(nullptr)});
  j["psnr_rows"] = std::move(rows);
  j["iteration_ms"] = p.iteration_ms;
  j["losses"] = p.losses;
  j["skipped_steps"] = p.skipped_steps;
  // Where the training time went: mean ms per iteration of each stage, and the sums a resumed run
  // continues.
  j["stage_ms_per_iteration"] = stage_ms_json(p);
  nlohmann::json totals = nlohmann::json::object();
  for (int s = 0; s < kStageCount; ++s) totals[stage_name(s)] = p.stage_ms[s];
  j["stage_ms_total"] = std::move(totals);
  j["stage_iterations"] = p.stage_iterations;
  return platform::write_file_atomic(path, j.dump() + "\n");
}

Progress load_progress(const std::string& run, int at, const std::function<void(const std::string&)>& say) {
  Progress p;
  Expected<std::string> text = platform::read_text_file((fs::path(run) / kProgressFile).string());
  nlohmann::json j = text.ok() ? nlohmann::json::parse(*text, nullptr, false) : nlohmann::json();
  if (!j.is_object()) {
    say(run + "/" + kProgressFile + " is missing or unreadable; PSNR-vs-time restarts at iteration " + std::to_string(at));
    p.iteration = at;
    return p;
  }
  const int saved = j.value("iteration", 0);
  p.train_seconds = j.value("train_seconds", 0.0);
  p.train_cpu_seconds = j.value("train_cpu_seconds", 0.0);
  for (const auto& r : j.value("psnr_rows", nlohmann::json::array()))
    if (r.is_array() && r.size() == 3 && r[0].get<int>() <= at)
      p.rows.push_back({r[0].get<int>(), r[1].get<double>(), r[2].is_number() ? r[2].get<double>() : std::nan("")});
  p.iteration_ms = j.value("iteration_ms", std::vector<float>());
  if (p.iteration_ms.size() > size_t(at)) p.iteration_ms.resize(size_t(at));
  p.losses = j.value("losses", std::vector<float>());
  p.skipped_steps = j.value("skipped_steps", 0);
  const nlohmann::json totals = j.value("stage_ms_total", nlohmann::json::object());
  p.stage_iterations = totals.is_object() ? j.value("stage_iterations", 0) : 0;
  for (int s = 0; s < kStageCount && p.stage_iterations > 0; ++s)
    p.stage_ms[s] = totals.contains(stage_name(s)) && totals[stage_name(s)].is_number() ? totals[stage_name(s)].get<double>() : 0.0;
  if (p.losses.size() > size_t(at)) p.losses.resize(size_t(at));
  if (saved != at) {
    const double ms = median(std::vector<double>(p.iteration_ms.begin(), p.iteration_ms.end()));
    if (saved < at) p.train_seconds += 1e-3 * ms * (at - saved);
    else if (!p.rows.empty()) p.train_seconds = p.rows.back().seconds;
    say(std::string(kProgressFile) + " was saved at iteration " + std::to_string(saved) + ", the checkpoint at " +
        std::to_string(at) + "; training time estimated");
  }
  p.iteration = at;
  return p;
}

}  // namespace gs::jobs
