// SPDX-License-Identifier: MIT
// "Every view earns its place" end to end (hbgs train; docs/POSES.md): a sound reconstruction (the
// generated scene, exact poses) with three training views turned 10-40 degrees about their
// centres. The view check holds exactly those views back from the first iteration (so none trains
// at its wrong pose), and each one either rejoins training once a registration against the model
// converges, ending within 0.3 degrees of its true pose, or is reported as still held. With pose
// optimisation and with fixed poses (where the registration is the only thing that moves a view).
// About a minute per run on 2 cores (the built-in scene at 256x192, 500 iterations): at 128x96 the
// model is too coarse at the first registration for 0.3 degrees (0.37 measured once).
#include <algorithm>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/platform/file.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;
using gs::test::run;

nlohmann::json results_in(const std::string& run_dir) {
  gs::Expected<std::string> text = gs::platform::read_text_file(run_dir + "/results.json");
  REQUIRE_MESSAGE(text.ok(), text.status().to_string());
  nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  REQUIRE(j.is_object());
  REQUIRE(j.size() == 1);  // {"ours_<iterations>": {...}}
  return j.begin().value();
}

TEST_CASE("view repair: three views turned 10-40 degrees are held back, then repaired or reported") {
  const std::string tmp = std::string(GS_TEST_TMP) + "/view_repair";
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  const std::string scene = tmp + "/scene";
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + scene + " --quiet") == 0);
  // Two runs (CI time): seed 1 with pose optimisation, seed 2 with fixed poses; six views in all.
  const std::pair<const char*, int> runs[] = {{"--optimize-poses", 1}, {"", 2}};
  for (const auto& [mode, seed] : runs) {
    {
      const std::string out = tmp + "/run" + std::to_string(seed) + (*mode ? "_opt" : "_fixed");
      CAPTURE(out);
      REQUIRE(run(std::string(GS_HBGS_EXE) + " train " + scene + " --out " + out + " --iterations 500 --eval-every 0 --threads 2 " +
                  "--pose-noise rot:10-40,views:3,seed:" + std::to_string(seed) + " " + mode + " > " + out + ".log 2>&1") == 0);
      const nlohmann::json poses = results_in(out)["poses"];
      const nlohmann::json& input = poses["train_input"]["per_view_rotation_deg"];
      const nlohmann::json& final = poses["train_final"]["per_view_rotation_deg"];
      const nlohmann::json& held = poses["held_back"];
      std::vector<std::string> moved, suspect = held["contradicted_by_points"].get<std::vector<std::string>>();
      for (auto it = input.begin(); it != input.end(); ++it)
        if (it.value().get<double>() > 1) moved.push_back(it.key());
      REQUIRE(moved.size() == 3);
      const std::vector<std::string> released = held["repaired"].get<std::vector<std::string>>();
      const std::vector<std::string> still = held["still_held"].get<std::vector<std::string>>();
      for (const std::string& name : moved) {
        CAPTURE(name);
        const double before = input[name].get<double>(), after = final[name].get<double>();
        const bool repaired = std::find(released.begin(), released.end(), name) != released.end();
        const bool kept_out = std::find(still.begin(), still.end(), name) != still.end();
        MESSAGE(out << ": " << name << " " << before << " degrees off at the start, "
                    << (repaired ? "repaired to " + std::to_string(after) + " degrees" : kept_out ? "still held out" : "TRAINED"));
        // Held back from the start: never trained at its wrong pose.
        CHECK(std::find(suspect.begin(), suspect.end(), name) != suspect.end());
        CHECK((repaired || kept_out));
        if (repaired) CHECK(after < 0.3);
      }
      // The sound views: none held out for good (a correct view the points doubted rejoins too).
      CHECK(still.size() <= moved.size());
    }
  }
}

TEST_CASE("view repair: a view the point alignment moves far is held back even when the points do not contradict it") {
  // One training view turned 3 degrees (seed 1: 0019.png) on the generated scene, the others exact:
  // the points still agree with it well above a quarter of the typical margin (not suspect), but the
  // point alignment moves it over 3x the median move and puts it back. That is how the two views
  // COLMAP placed 6-8 degrees off in the failed end-to-end runs looked (docs/POSES.md), so it is held
  // back from the first iteration; one iteration is enough to see it (no registration pass runs).
  const std::string tmp = std::string(GS_TEST_TMP) + "/view_repair_far";
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  const std::string scene = tmp + "/scene", out = tmp + "/run";
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + scene + " --quiet") == 0);
  REQUIRE(run(std::string(GS_HBGS_EXE) + " train " + scene + " --out " + out + " --iterations 1 --eval-every 0 --threads 2 " +
              "--optimize-poses --pose-noise rot:3,views:1,seed:1 > " + out + ".log 2>&1") == 0);
  const nlohmann::json poses = results_in(out)["poses"];
  const nlohmann::json& input = poses["train_input"]["per_view_rotation_deg"];
  std::vector<std::string> turned;
  for (auto it = input.begin(); it != input.end(); ++it)
    if (it.value().get<double>() > 1) turned.push_back(it.key());
  REQUIRE(turned.size() == 1);
  const nlohmann::json& held = poses["held_back"];
  const auto names = [&](const char* key) { return held[key].get<std::vector<std::string>>(); };
  CHECK(names("moved_far_by_point_alignment") == turned);
  CHECK(names("contradicted_by_points").empty());
  CHECK(names("still_held") == turned);
  CHECK(poses["point_alignment"]["kept_start_pose"].get<std::vector<std::string>>() == turned);
  // With --no-view-check nothing is held: the check is the one switch for both.
  REQUIRE(run(std::string(GS_HBGS_EXE) + " train " + scene + " --out " + out + "_nocheck --iterations 1 --eval-every 0 --threads 2 " +
              "--optimize-poses --pose-noise rot:3,views:1,seed:1 --no-view-check > " + out + "_nocheck.log 2>&1") == 0);
  CHECK(results_in(out + "_nocheck")["poses"]["held_back"]["still_held"].empty());
}

}  // namespace
