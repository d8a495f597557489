// SPDX-License-Identifier: MIT
// `hbgs train`, the library's training job and bench_train run the same configuration: on one
// generated scene with the same seed, threads and iterations, every iteration's training loss is
// identical (bit for bit) across the three, and equal to what the job reports through its callback.
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/jobs/run_folder.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"

namespace {

namespace fs = std::filesystem;

int run(const std::string& command) {
  MESSAGE(command);
  return std::system((command + " > /dev/null 2>&1").c_str());
}

std::vector<float> losses_in(const std::string& json_file) {
  gs::Expected<std::string> text = gs::platform::read_text_file(json_file);
  REQUIRE_MESSAGE(text.ok(), text.status().to_string());
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  REQUIRE(j.is_object());
  return j.value("losses", std::vector<float>());
}

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

  REQUIRE(reported.size() == size_t(kIterations));
  CHECK(library == reported);
  CHECK(cli == reported);
  CHECK(bench == reported);
  // Not a constant: training lowers the loss.
  CHECK(reported.back() < reported.front());
  fs::remove_all(tmp, ec);
}
