// SPDX-License-Identifier: MIT
// `hbgs train`, the library's training job and bench_train run the same configuration: on one
// generated scene with the same seed, threads and iterations, every iteration's training loss is
// identical (bit for bit) across the three, and equal to what the job reports through its callback;
// bench_train --profile trains identically too. The per-stage times reach progress.json, the run
// summary and the bench's JSON.
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/jobs/run_folder.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"
#include "gs/stage_times.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;

using gs::test::run;

nlohmann::json json_in(const std::string& json_file) {
  gs::Expected<std::string> text = gs::platform::read_text_file(json_file);
  REQUIRE_MESSAGE(text.ok(), text.status().to_string());
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  REQUIRE(j.is_object());
  return j;
}

std::vector<float> losses_in(const std::string& json_file) { return json_in(json_file).value("losses", std::vector<float>()); }

}  // namespace

TEST_CASE("train job: hbgs train, gs::jobs::train_run and bench_train give identical losses") {
  const fs::path tmp = fs::path(GS_TEST_TMP) / "same_config";
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  const std::string scene = (tmp / "scene").string();
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + scene + " --width 64 --height 48 --views-arc 6 --views-orbit 6 --points 2000") == 0);

  constexpr int kIterations = 60;
  // The library job with its defaults, as a program linking hbgs would call it.
  gs::jobs::TrainRunOptions o;
  o.dataset = scene;
  o.out = (tmp / "run_library").string();
  o.iterations = kIterations;
  o.threads = 2;
  o.seed = 7;
  std::vector<float> reported;
  gs::jobs::TrainRunSummary summary;
  const gs::Status st = gs::jobs::train_run(
      o, [&](const gs::jobs::TrainEvent& e) {
        if (e.kind == gs::jobs::TrainEvent::kIteration) reported.push_back(float(e.stats->step.loss));
      },
      &summary);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  CHECK(summary.iterations == kIterations);
  const std::vector<float> library = losses_in(o.out + "/" + gs::jobs::kProgressFile);

  const std::string cli_run = (tmp / "run_cli").string();
  REQUIRE(run(std::string(GS_HBGS_EXE) + " train " + scene + " --out " + cli_run + " --iterations " + std::to_string(kIterations) +
              " --threads 2 --seed 7 -q") == 0);
  const std::vector<float> cli = losses_in(cli_run + "/" + gs::jobs::kProgressFile);

  const std::string bench_json = (tmp / "bench.json").string();
  REQUIRE(run(std::string(GS_BENCH_TRAIN_EXE) + " --dataset " + scene + " --warmup 0 --iterations " + std::to_string(kIterations) +
              " --threads 2 --seed 7 --json " + bench_json) == 0);
  const std::vector<float> bench = losses_in(bench_json);
  const std::string profile_json = (tmp / "bench_profile.json").string();
  REQUIRE(run(std::string(GS_BENCH_TRAIN_EXE) + " --dataset " + scene + " --warmup 0 --iterations " + std::to_string(kIterations) +
              " --threads 2 --seed 7 --profile --json " + profile_json) == 0);
  const nlohmann::json profiled = json_in(profile_json);

  REQUIRE(reported.size() == size_t(kIterations));
  CHECK(library == reported);
  CHECK(cli == reported);
  CHECK(bench == reported);
  CHECK(profiled.value("losses", std::vector<float>()) == reported);  // profiling changes nothing

  // The stage figures: every stage named in progress.json and the bench's table, the timed ones
  // positive, and the summary's copy equal to progress.json's.
  const nlohmann::json progress = json_in(o.out + "/" + gs::jobs::kProgressFile);
  CHECK(progress.value("stage_iterations", 0) == kIterations);
  const nlohmann::json stage_ms = progress.value("stage_ms_per_iteration", nlohmann::json::object());
  const nlohmann::json& table = profiled["profile"]["stages"];
  REQUIRE(table.is_array());
  REQUIRE(table.size() == size_t(gs::kStageCount));
  double sum = 0;
  for (int s = 0; s < gs::kStageCount; ++s) {
    CAPTURE(gs::stage_name(s));
    REQUIRE(stage_ms.contains(gs::stage_name(s)));
    CHECK(stage_ms[gs::stage_name(s)].get<double>() == doctest::Approx(summary.stage_ms_per_iteration[s]).epsilon(1e-9));
    sum += summary.stage_ms_per_iteration[s];
    CHECK(table[size_t(s)].value("stage", "") == gs::stage_name(s));
    for (const char* key : {"ms", "flops", "bytes", "gflops", "gbs", "fma_peak_fraction", "copy_peak_fraction"})
      CHECK(table[size_t(s)].contains(key));
  }
  for (int s : {gs::kStageProject, gs::kStageRasterFwd, gs::kStageRasterBwd, gs::kStageAdam}) {
    CAPTURE(gs::stage_name(s));
    CHECK(summary.stage_ms_per_iteration[s] > 0);
    CHECK(table[size_t(s)]["ms"].get<double>() > 0);
    CHECK(table[size_t(s)]["bytes"].get<double>() > 0);
  }
  CHECK(table[size_t(gs::kStageRasterFwd)]["flops"].get<double>() > 0);
  // The stages account for the steps' time: their mean sum is the mean step, not more than the
  // job's mean iteration (which also holds the step's callback and bookkeeping).
  double iteration_ms = 0;
  for (float ms : progress.value("iteration_ms", std::vector<float>())) iteration_ms += double(ms) / kIterations;
  CHECK(sum <= iteration_ms * 1.001 + 1e-3);
  const nlohmann::json& peaks = profiled["profile"]["peaks"];
  for (const char* key : {"fma_gflops_core", "fma_gflops_all", "copy_gbs_core", "copy_gbs_all"}) {
    CAPTURE(key);
    CHECK(peaks.value(key, 0.0) > 0);
  }
  // Not a constant: training lowers the loss.
  CHECK(reported.back() < reported.front());
  fs::remove_all(tmp, ec);
}
