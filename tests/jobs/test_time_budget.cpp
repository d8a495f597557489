// SPDX-License-Identifier: MIT
// The training job's time budget (TrainRunOptions::time_budget, hbgs train --time-budget) with an
// injected clock, so that no test sleeps or depends on the machine's speed: a fake pace of X seconds
// per step stops the run at the iteration that fits, a pace that grows (as anchors do) still ends
// within a step of the budget with the schedule run to its end, a resumed run has what is left of
// the budget, the length-derived schedule (set_run_length) follows the predicted length, and bad
// durations are refused by the library and the CLI.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/jobs/run_folder.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;

int run(const std::string& command, const std::string& log = "/dev/null") {
  MESSAGE(command);
  return std::system((command + " > " + log + " 2>&1").c_str());
}

nlohmann::json read_json(const std::string& file) {
  gs::Expected<std::string> text = gs::platform::read_text_file(file);
  REQUIRE_MESSAGE(text.ok(), text.status().to_string());
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  REQUIRE(j.is_object());
  return j;
}

// This process's folder (ctest runs the cases as separate processes, side by side).
const gs::test::TempDir& tmp() {
  static const gs::test::TempDir dir("gs_time_budget");
  return dir;
}

// A generated 64 x 48 scene, made once per process.
const std::string& scene() {
  static const std::string path = [] {
    const fs::path dir = tmp() / "scene";
    REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + dir.string() +
                " --width 64 --height 48 --views-arc 6 --views-orbit 6 --points 2000") == 0);
    return dir.string();
  }();
  return path;
}

// A clock the job times each step with (it reads it before and after the step): every step takes
// pace(iteration) seconds, the time between steps none.
struct FakeClock {
  std::function<double(int)> pace;
  std::shared_ptr<long> calls = std::make_shared<long>(0);
  std::shared_ptr<double> now = std::make_shared<double>(1000.0);
  std::function<double()> fn() const {
    return [p = pace, calls = calls, now = now] {
      const long c = (*calls)++;
      if (c % 2 == 1) *now += p(int(c / 2) + 1);  // the reading after step c / 2 + 1
      return *now;
    };
  }
};

gs::jobs::TrainRunOptions budget_options(const std::string& out, double budget, const FakeClock& clock) {
  gs::jobs::TrainRunOptions o;
  o.dataset = scene();
  o.out = (fs::path(tmp().path()) / out).string();
  o.iterations = 100000;  // a cap far away: the budget decides
  o.time_budget = budget;
  o.clock = clock.fn();
  o.threads = 2;
  o.seed = 3;
  o.eval_every = 0;
  o.checkpoint_every = 0;
  o.save_at = "";
  o.force = true;
  return o;
}

struct Outcome {
  gs::jobs::TrainRunSummary summary;
  std::vector<int> predicted;  // the run's length as each iteration event gave it
};

Outcome train(const gs::jobs::TrainRunOptions& o) {
  Outcome out;
  const gs::Status st = gs::jobs::train_run(
      o,
      [&](const gs::jobs::TrainEvent& e) {
        if (e.kind == gs::jobs::TrainEvent::kIteration) out.predicted.push_back(e.iterations);
      },
      &out.summary);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  return out;
}

}  // namespace

TEST_CASE("time budget: a fake pace of 0.25 s per step stops the run at the 40th step of a 10 s budget") {
  FakeClock clock{[](int) { return 0.25; }};
  const Outcome r = train(budget_options("budget_const", 10.0, clock));
  CHECK(r.summary.iterations == 40);
  CHECK(r.summary.train_seconds == doctest::Approx(10.0));
  CHECK(r.summary.time_budget == 10.0);
  // At a steady pace the prediction is exact, so the schedule runs to its end.
  CHECK(r.summary.schedule_progress == doctest::Approx(1.0));
  REQUIRE(r.predicted.size() == 40);
  CHECK(r.predicted.front() == 0);  // not predicted yet
  CHECK(r.predicted.back() == 40);
  const nlohmann::json results = read_json(r.summary.run_dir + "/" + gs::jobs::kResultsJson);
  REQUIRE(results.contains("ours_40"));
  const nlohmann::json& b = results["ours_40"]["time_budget"];
  CHECK(b["seconds"].get<double>() == 10.0);
  CHECK(b["iterations_fit"].get<int>() == 40);
  CHECK(b["seconds_used"].get<double>() == doctest::Approx(10.0));
  CHECK(b["iteration_cap"].get<int>() == 100000);
  const nlohmann::json run_json = read_json(r.summary.run_dir + "/" + gs::jobs::kRunJson);
  CHECK(run_json["options"]["time-budget"].get<double>() == 10.0);
  CHECK(fs::exists(r.summary.run_dir + "/" + gs::jobs::kModelFile));
  CHECK(fs::exists(r.summary.run_dir + "/" + gs::jobs::kProgressFile));
}

TEST_CASE("time budget: a pace that grows with the iteration still ends within a step of the budget") {
  // 20 ms plus 1 ms per iteration: the early pace predicts far too many steps.
  const auto pace = [](int it) { return 0.02 + 0.001 * it; };
  FakeClock clock{pace};
  const double budget = 8.0;
  const Outcome r = train(budget_options("budget_growing", budget, clock));
  double used = 0;
  int fit = 0;
  while (used + pace(fit + 1) <= budget) used += pace(++fit);  // the steps that fit, known in hindsight
  MESSAGE("iterations " << r.summary.iterations << " (" << fit << " fit), seconds " << r.summary.train_seconds
                        << ", first prediction " << (r.predicted.size() > 25 ? r.predicted[25] : -1) << ", schedule progress "
                        << r.summary.schedule_progress);
  CHECK(r.summary.train_seconds <= budget + pace(r.summary.iterations));
  CHECK(r.summary.train_seconds > budget - 2 * pace(r.summary.iterations));
  CHECK(std::abs(r.summary.iterations - fit) <= 1);
  // The first prediction (the early pace) was too long, and the schedule followed the later ones.
  REQUIRE(r.predicted.size() > 25);
  CHECK(r.predicted[25] > fit + 10);
  CHECK(r.summary.schedule_progress > 0.95);
}

TEST_CASE("time budget: a resumed run has what is left of the budget") {
  FakeClock first{[](int) { return 0.25; }};
  gs::jobs::TrainRunOptions o = budget_options("budget_resume", 10.0, first);
  o.iterations = 24;  // the cap ends the first part at 6 s
  const Outcome a = train(o);
  CHECK(a.summary.iterations == 24);
  CHECK(a.summary.train_seconds == doctest::Approx(6.0));
  // The automatic offsets per anchor are recorded as the number trained with (7 under a budget), so
  // the resumed run below, which gives no budget, keeps them.
  CHECK(read_json(o.out + "/run.json")["options"]["offsets"] == 7);

  // Resumed with a higher cap and no budget given: run.json's 10 s, 6 s of it spent, 16 more steps.
  FakeClock second{[](int) { return 0.25; }};
  gs::jobs::TrainRunOptions r;
  r.dataset = o.dataset;
  r.out = o.out;
  r.resume = true;
  r.iterations = 1000;
  r.given = {"iterations"};
  r.clock = second.fn();
  const Outcome b = train(r);
  CHECK(b.summary.resumed_from == 24);
  CHECK(b.summary.time_budget == 10.0);
  CHECK(b.summary.iterations == 40);
  CHECK(b.summary.train_seconds == doctest::Approx(10.0));
  // The first part's schedule ended at its cap: the rates stay at their end (they never rise again).
  CHECK(b.summary.schedule_progress == 1.0);

  // The budget is spent: resuming again trains nothing and evaluates the model as it is.
  FakeClock third{[](int) { return 0.25; }};
  r.clock = third.fn();
  const Outcome c = train(r);
  CHECK(c.summary.iterations == 40);
  CHECK(c.predicted.empty());
  CHECK(c.summary.have_test_views);
}

TEST_CASE("time budget: the length-derived schedule follows the predicted length") {
  gs::jobs::TrainRunOptions a;
  a.optimize_poses = true;
  a.register_passes = 2;
  gs::model::TrainOptions t400, t4000, t60000, back;
  gs::jobs::set_run_length(a, 400, &t400);
  gs::jobs::set_run_length(a, 4000, &t4000);
  gs::jobs::set_run_length(a, 60000, &t60000);
  CHECK(t400.schedule_iterations == 400);
  CHECK(t4000.schedule_iterations == 4000);
  // The densification window scales with the length below 15,000 iterations...
  CHECK(t400.update_until == 400);
  CHECK(t4000.update_until == 4000);
  CHECK(t4000.update_from > t400.update_from);
  CHECK(t4000.stat_start > t400.stat_start);
  CHECK(t4000.update_interval >= t400.update_interval);
  CHECK(t4000.pose_warmup == 400);
  CHECK(t4000.pose_register_until == 2000);
  // ...and is the reference's above it; a prediction that shrinks back gets the short-run window again.
  CHECK(t60000.update_until == 15000);
  CHECK(t60000.update_from == 1500);
  back = t60000;
  gs::jobs::set_run_length(a, 4000, &back);
  CHECK(back.update_until == t4000.update_until);
  CHECK(back.update_from == t4000.update_from);
  CHECK(back.stat_start == t4000.stat_start);
  CHECK(back.update_interval == t4000.update_interval);
}

TEST_CASE("time budget: a budgeted or short run trains 7 offsets per anchor, a long one 10, unless --offsets says otherwise") {
  gs::jobs::TrainRunOptions a;
  auto k_of = [](const gs::jobs::TrainRunOptions& o) {
    gs::Expected<gs::jobs::ResolvedTraining> r = gs::jobs::resolve_training(o);
    REQUIRE_MESSAGE(r.ok(), r.status().to_string());
    CHECK(gs::jobs::effective_offsets(o) == r->model.k);
    return r->model.k;
  };
  CHECK(a.offsets == -1);
  CHECK(a.iterations == 30000);
  CHECK(k_of(a) == gs::model::ModelConfig{}.k);  // a long run without a budget: the paper's k
  CHECK(k_of(a) == 10);
  a.iterations = 15000;
  CHECK(k_of(a) == 10);
  a.iterations = 14999;  // shorter runs fit their growth window into their length, and train 7
  CHECK(k_of(a) == 7);
  a.iterations = 3000;
  CHECK(k_of(a) == 7);
  a.iterations = 30000;
  a.time_budget = 60;  // a budget caps the iterations at 30,000 but is a short run all the same
  CHECK(k_of(a) == 7);
  a.offsets = 12;
  CHECK(k_of(a) == 12);
  a.time_budget = 0;
  a.offsets = 5;
  CHECK(k_of(a) == 5);
  for (int bad : {0, -2, 65}) {
    a.offsets = bad;
    gs::Expected<gs::jobs::ResolvedTraining> r = gs::jobs::resolve_training(a);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("--offsets must be between 1 and 64") != std::string::npos);
  }
}

TEST_CASE("time budget: durations are parsed, bad ones refused with a message") {
  struct Good { const char* text; double seconds; };
  for (const Good& g : {Good{"60s", 60}, Good{"90", 90}, Good{"3m", 180}, Good{"1.5m", 90}, Good{"1h", 3600}, Good{"0.5", 0.5}}) {
    gs::Expected<double> v = gs::jobs::parse_time_budget(g.text);
    REQUIRE_MESSAGE(v.ok(), g.text);
    CHECK(*v == g.seconds);
  }
  for (const char* bad : {"", "0", "0s", "-5", "-1m", "abc", "5x", "5 s", "1e3", "inf", "nan", "99999999999", "1000000h",
                          "1" "0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                          "0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                          "0000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000"
                          "000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000s"}) {
    gs::Expected<double> v = gs::jobs::parse_time_budget(bad);
    CHECK_MESSAGE(!v.ok(), bad);
    if (!v.ok()) CHECK(v.status().message().find("--time-budget") != std::string::npos);
  }
  // The library option is checked too, before a run folder is made.
  gs::jobs::TrainRunOptions o;
  o.dataset = scene();
  o.out = (fs::path(tmp().path()) / "budget_bad").string();
  o.time_budget = -1;
  const gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  CHECK(st.code() == gs::StatusCode::kInvalidArgument);
  CHECK(st.message().find("time budget") != std::string::npos);
  CHECK_FALSE(fs::exists(o.out));

  // hbgs train: a clear error and no run folder.
  const std::string log = (fs::path(tmp().path()) / "budget_cli.log").string();
  for (const char* bad : {"0", "-3", "ten", "5x", "1e999"}) {
    const std::string out = (fs::path(tmp().path()) / "budget_cli_run").string();
    CHECK(run(std::string(GS_HBGS_EXE) + " train " + scene() + " --out " + out + " --time-budget=" + bad + " -q", log) != 0);
    gs::Expected<std::string> text = gs::platform::read_text_file(log);
    REQUIRE(text.ok());
    CHECK_MESSAGE(text->find("--time-budget") != std::string::npos, *text);
    CHECK_FALSE(fs::exists(out));
  }
}
