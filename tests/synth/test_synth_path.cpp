// SPDX-License-Identifier: MIT
// Tests for the synth camera paths (generate_path): the hand-held test trajectory moves smoothly
// except at its cut, pans at the asked speed, shakes a little by seed; its files (frames, TUM,
// COLMAP, JSON, video) agree with the cameras, are deterministic and independent of the thread
// count; the frames are the datasets' scenes rendered at those poses.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/composite.h"
#include "gs/io/image.h"
#include "gs/io/tum.h"
#include "gs/pose/pose.h"
#include "hbgs/synth.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using gs::test::TempDir;
using hbgs::synth::PathEvents;
using hbgs::synth::PathOptions;

namespace {

PathOptions handheld(PathOptions::SceneKind scene) {
  PathOptions o;
  o.kind = PathOptions::Kind::kHandheld;
  o.scene = scene;
  o.width = scene == PathOptions::SceneKind::kObject ? 200 : 256;
  o.height = scene == PathOptions::SceneKind::kObject ? 200 : 192;
  o.frames = 300;
  return o;
}

// Tiny frames for the file tests: 16x12 (16x16 for the object), one sample per pixel.
PathOptions tiny(PathOptions::SceneKind scene) {
  PathOptions o = handheld(scene);
  o.width = 16;
  o.height = scene == PathOptions::SceneKind::kObject ? 16 : 12;
  o.samples_per_axis = 1;
  o.frames = 240;
  return o;
}

double distance(const gs::Pose& a, const gs::Pose& b) {
  double ca[3], cb[3];
  gs::pose::centre(a, ca);
  gs::pose::centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::map<std::string, std::string> read_tree(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) out[fs::relative(e.path(), root).string()] = slurp(e.path());
  return out;
}

}  // namespace

TEST_CASE("synth path: the hand-held trajectory is smooth but for its pan and its cut") {
  for (PathOptions::SceneKind scene : {PathOptions::SceneKind::kScene, PathOptions::SceneKind::kObject}) {
    const PathOptions o = handheld(scene);
    INFO("scene ", std::string(scene == PathOptions::SceneKind::kObject ? "object" : "built-in"));
    const std::vector<gs::Camera> cams = hbgs::synth::make_path_cameras(o);
    REQUIRE(cams.size() == 300);
    const PathEvents ev = hbgs::synth::path_events(o);
    // The pan: 60 degrees at 60 degrees/s plus 0.1 s of ramps = 1.1 s = 33 frame intervals.
    CHECK(ev.pan_last - ev.pan_first == 33);
    CHECK(ev.pan_first > 30);
    CHECK(ev.cut > ev.pan_last + 30);
    CHECK(ev.cut >= 180);       // not before 0.6 of the duration
    CHECK(ev.cut <= 300 - 30);  // at least a second after it
    std::vector<double> turn(cams.size() - 1), move(cams.size() - 1);
    for (size_t i = 0; i + 1 < cams.size(); ++i) {
      turn[i] = gs::pose::rotation_error_deg(cams[i].pose, cams[i + 1].pose);
      move[i] = distance(cams[i].pose, cams[i + 1].pose);
    }
    double pan_max = 0, pan_sum = 0, other_max = 0, other_move_max = 0, other_accel_max = 0;
    std::vector<double> other;
    for (size_t i = 0; i + 1 < cams.size(); ++i) {
      const int a = int(i);
      if (a + 1 == ev.cut) continue;
      if (a >= ev.pan_first && a < ev.pan_last) {
        pan_max = std::max(pan_max, turn[i]);
        pan_sum += turn[i];
        continue;
      }
      other_max = std::max(other_max, turn[i]);
      other_move_max = std::max(other_move_max, move[i]);
      other.push_back(turn[i]);
      // Smooth at 30 fps, not white noise: consecutive steps hardly differ.
      if (i + 2 < cams.size() && a + 2 != ev.cut && !(a + 1 >= ev.pan_first && a < ev.pan_last))
        other_accel_max = std::max(other_accel_max, std::fabs(turn[i + 1] - turn[i]));
    }
    MESSAGE("pan max ", pan_max, " sum ", pan_sum, "; elsewhere max ", other_max, " move ", other_move_max, " accel ",
         other_accel_max, "; cut turn ", turn[size_t(ev.cut - 1)], " move ", move[size_t(ev.cut - 1)]);
    // 60 degrees/s at 30 fps: 2 degrees per frame at the peak, shake and walk included.
    CHECK(pan_max > 1.85);
    CHECK(pan_max < 2.25);
    CHECK(pan_sum > 55.0);
    CHECK(pan_sum < 66.0);
    // Elsewhere at most half the pan's speed (the slow turns around it), mostly far less.
    CHECK(other_max < 1.0);
    std::nth_element(other.begin(), other.begin() + long(other.size() / 2), other.end());
    CHECK(other[other.size() / 2] < 0.4);
    CHECK(other_accel_max < 0.1);
    // The cut: a jump to a distant viewpoint.
    CHECK(turn[size_t(ev.cut - 1)] > 90.0);
    CHECK(move[size_t(ev.cut - 1)] > 50 * other_move_max);
  }
}

TEST_CASE("synth path: the shake is small, smooth and seeded") {
  // The built-in scene's walk does not depend on the seed, only the shake does.
  PathOptions a = handheld(PathOptions::SceneKind::kScene), b = a;
  b.seed = 2;
  const std::vector<gs::Camera> ca = hbgs::synth::make_path_cameras(a), cb = hbgs::synth::make_path_cameras(b);
  REQUIRE(ca.size() == cb.size());
  double max_move = 0, max_turn = 0;
  for (size_t i = 0; i < ca.size(); ++i) {
    max_move = std::max(max_move, distance(ca[i].pose, cb[i].pose));
    max_turn = std::max(max_turn, gs::pose::rotation_error_deg(ca[i].pose, cb[i].pose));
  }
  MESSAGE("two seeds' shakes differ by up to ", max_move, " m and ", max_turn, " degrees");
  // Each shake is ~2 mm and ~0.12 degrees RMS per axis: the difference of two is a few mm, tenths
  // of a degree.
  CHECK(max_move > 0.002);
  CHECK(max_move < 0.03);
  CHECK(max_turn > 0.1);
  CHECK(max_turn < 0.8);
  // Same seed, same path.
  const std::vector<gs::Camera> again = hbgs::synth::make_path_cameras(a);
  for (size_t i = 0; i < ca.size(); ++i) CHECK(std::equal(ca[i].pose.R, ca[i].pose.R + 9, again[i].pose.R));
}

TEST_CASE("synth path: invalid hand-held options are refused") {
  PathOptions o = handheld(PathOptions::SceneKind::kScene);
  o.frames = 200;
  const gs::Status st = hbgs::synth::validate_path(o);
  CHECK(!st.ok());
  CHECK(st.message().find("at least 237 frames") != std::string::npos);
  CHECK(hbgs::synth::make_path_cameras(o).empty());
  o.frames = 237;
  CHECK(hbgs::synth::validate_path(o).ok());
  PathOptions sweep;
  sweep.scene = PathOptions::SceneKind::kObject;
  CHECK(!hbgs::synth::validate_path(sweep).ok());
  PathOptions bg = handheld(PathOptions::SceneKind::kObject);
  bg.background[1] = 2.0f;
  CHECK(!hbgs::synth::validate_path(bg).ok());
}

TEST_CASE("synth path: the files agree with the cameras and the frames are the dataset's scene") {
  for (PathOptions::SceneKind scene : {PathOptions::SceneKind::kScene, PathOptions::SceneKind::kObject}) {
    const bool object = scene == PathOptions::SceneKind::kObject;
    INFO("scene ", std::string(object ? "object" : "built-in"));
    PathOptions o = tiny(scene);
    o.seed = 3;
    o.background[0] = 0.25f, o.background[1] = 0.5f, o.background[2] = 1.0f;
    TempDir dir("synth_path_files");
    const gs::Expected<hbgs::synth::PathSummary> summary = hbgs::synth::generate_path(o, dir.path());
    REQUIRE(summary.ok());
    const std::vector<gs::Camera> cams = hbgs::synth::make_path_cameras(o);
    REQUIRE(cams.size() == size_t(o.frames));

    // TUM: times i / fps and the poses to its 9 significant digits.
    const auto tum = gs::io::read_tum_trajectory(dir.path() + "/" + hbgs::synth::kPathTumFile);
    REQUIRE(tum.ok());
    REQUIRE(tum->size() == cams.size());
    for (size_t i = 0; i < cams.size(); ++i) {
      CHECK(std::fabs((*tum)[i].time - double(i) / o.fps) < 1e-6);
      CHECK(gs::pose::rotation_error_deg((*tum)[i].pose, cams[i].pose) < 1e-4);
      CHECK(distance((*tum)[i].pose, cams[i].pose) < 1e-6);
    }
    // COLMAP: exactly the cameras, named like the frames.
    const auto model = gs::io::read_colmap_text(dir.path() + "/" + hbgs::synth::kPathTruePosesDir);
    REQUIRE(model.ok());
    REQUIRE(model->images.size() == cams.size());
    for (size_t i = 0; i < cams.size(); ++i) {
      const gs::Pose p = gs::io::pose_from_colmap(model->images[i].qvec, model->images[i].tvec);
      CHECK(std::equal(p.R, p.R + 9, cams[i].pose.R));
      CHECK(std::equal(p.t, p.t + 3, cams[i].pose.t));
      CHECK(fs::exists(dir.path() + "/frames/" + model->images[i].name));
    }
    // The JSON names the events and the scene.
    const nlohmann::json j = nlohmann::json::parse(slurp(dir.path() + "/" + hbgs::synth::kPathJsonFile));
    const PathEvents ev = hbgs::synth::path_events(o);
    CHECK(j["fps"].get<double>() == o.fps);
    CHECK(j["frames"].get<int>() == o.frames);
    CHECK(j["pan"]["first_frame"].get<int>() == ev.pan_first);
    CHECK(j["pan"]["last_frame"].get<int>() == ev.pan_last);
    CHECK(j["cut"]["frame"].get<int>() == ev.cut);
    CHECK(j["scene"]["kind"].get<std::string>() == (object ? "object" : "scene"));
    CHECK(j["scene"]["seed"].get<int>() == 3);
    CHECK(j["scene"]["dataset_radius"].get<double>() > 0.5);

    // Frames: the scene of the same seed as the dataset renders it at these poses (with one sample
    // per pixel the jitter stream plays no part); the object's subject composited on the background.
    std::unique_ptr<hbgs::synth::Scene> s;
    if (object) {
      // The camera distance only places the cluttered capture's clutter: none here.
      auto made = hbgs::synth::Scene::create_object(o.seed, false, 1.0);
      REQUIRE(made.ok());
      s = std::move(made.value());
    } else {
      auto made = hbgs::synth::Scene::create(o.seed);
      REQUIRE(made.ok());
      s = std::move(made.value());
    }
    for (int i : {0, ev.pan_first + 10, ev.cut - 1, ev.cut, o.frames - 1}) {
      char name[64];
      std::snprintf(name, sizeof name, "%s/frames/frame_%06d.png", dir.path().c_str(), i);
      const auto frame = gs::io::read_image(name);
      REQUIRE(frame.ok());
      gs::io::Image8 expected;
      if (object) {
        gs::io::Image8 rgba;
        s->render_layers(cams[size_t(i)], 1, 0, 1, nullptr, &rgba);
        const size_t n = size_t(rgba.width) * size_t(rgba.height);
        gs::io::Image8 rgb{rgba.width, rgba.height, 3, std::vector<uint8_t>(3 * n)}, alpha{rgba.width, rgba.height, 1, std::vector<uint8_t>(n)};
        for (size_t p = 0; p < n; ++p) {
          for (int ch = 0; ch < 3; ++ch) rgb.pixels[3 * p + size_t(ch)] = rgba.pixels[4 * p + size_t(ch)];
          alpha.pixels[p] = rgba.pixels[4 * p + 3];
        }
        expected = gs::io::composite_rgb8(rgb, alpha, o.background);
      } else {
        expected = s->render(cams[size_t(i)], 1, 0, 1);
      }
      INFO("frame ", i);
      CHECK(frame->channels == 3);
      CHECK(frame->pixels == expected.pixels);
    }
  }
}

TEST_CASE("synth path: identical options give identical files, whatever the thread count") {
  PathOptions o = tiny(PathOptions::SceneKind::kObject);
  o.samples_per_axis = 2;  // the jitter stream in play
  o.video = true;
  TempDir a("synth_path_t1"), b("synth_path_t2");
  o.threads = 1;
  const auto sa = hbgs::synth::generate_path(o, a.path());
  REQUIRE(sa.ok());
  o.threads = 3;
  const auto sb = hbgs::synth::generate_path(o, b.path());
  REQUIRE(sb.ok());
  CHECK(sa->video_written == sb->video_written);
  if (!sa->video_written) MESSAGE("no video compared: ", sa->video_note);
  const auto ta = read_tree(a.path()), tb = read_tree(b.path());
  CHECK(ta.size() == size_t(o.frames) + 5 + (sa->video_written ? 1 : 0));  // + TUM, JSON, 3 COLMAP files
  CHECK(ta == tb);
}

TEST_CASE("synth path: without ffmpeg the frames are written and the video is skipped with the reason") {
  PathOptions o = tiny(PathOptions::SceneKind::kScene);
  o.video = true;
  o.ffmpeg = "/nonexistent/ffmpeg-for-hbgs-tests";
  TempDir dir("synth_path_no_ffmpeg");
  const auto s = hbgs::synth::generate_path(o, dir.path());
  REQUIRE(s.ok());
  CHECK(!s->video_written);
  CHECK(s->video_note.find("not found") != std::string::npos);
  CHECK(fs::exists(dir.path() + "/frames/frame_000239.png"));
  CHECK(!fs::exists(dir.path() + "/" + hbgs::synth::kPathVideoFile));
  const nlohmann::json j = nlohmann::json::parse(slurp(dir.path() + "/" + hbgs::synth::kPathJsonFile));
  CHECK(j["files"]["video"].is_null());
}
