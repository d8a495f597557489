// SPDX-License-Identifier: MIT
// Tests for gs::jobs::compare_poses (`hbgs compare-poses`): TUM trajectories matched by timestamp
// or by order, COLMAP models by name, with and without the Sim(3) fit; per-frame errors, ATE and
// RPE against known perturbations; lost and missing frames; the per-frame CSV and the JSON.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/tum.h"
#include "gs/jobs/pose_truth.h"
#include "gs/pose/pose.h"
#include "support/temp_dir.h"

using gs::io::TimedPose;
using gs::jobs::FrameComparison;
using gs::jobs::PoseCompareOptions;
using gs::test::TempDir;

namespace {

constexpr double kFps = 30.0;

// A pose from its camera centre c and the axis-angle phi of its world-to-camera rotation.
gs::Pose make_pose(const double phi[3], const double c[3]) {
  double R[9];
  gs::pose::so3_exp(phi, R);
  gs::Pose p;
  for (int r = 0; r < 3; ++r) {
    p.R[3 * r] = float(R[3 * r]), p.R[3 * r + 1] = float(R[3 * r + 1]), p.R[3 * r + 2] = float(R[3 * r + 2]);
    p.t[r] = float(-(R[3 * r] * c[0] + R[3 * r + 1] * c[1] + R[3 * r + 2] * c[2]));
  }
  return p;
}

// A smooth trajectory of n frames at kFps: a half circle of radius 2 with a turning camera.
std::vector<TimedPose> trajectory(int n) {
  std::vector<TimedPose> out;
  for (int i = 0; i < n; ++i) {
    const double s = double(i) / n;
    const double c[3] = {2 * std::cos(3.0 * s), 2 * std::sin(3.0 * s), 0.5 + 0.2 * s};
    const double phi[3] = {0.3 + 0.2 * s, -1.0 + 1.5 * s, 0.1 * std::sin(5 * s)};
    out.push_back({i / kFps, make_pose(phi, c)});
  }
  return out;
}

// The same camera moved by d (world units) without turning it.
gs::Pose moved(const gs::Pose& p, const double d[3]) {
  gs::Pose q = p;
  for (int r = 0; r < 3; ++r) q.t[r] = float(p.t[r] - (p.R[3 * r] * d[0] + p.R[3 * r + 1] * d[1] + p.R[3 * r + 2] * d[2]));
  return q;
}

// The same camera turned by `deg` about its own x axis (R <- Rx R, centre kept).
gs::Pose turned(const gs::Pose& p, double deg) {
  double c[3];
  gs::pose::centre(p, c);
  const double a = deg * 3.14159265358979323846 / 180;
  const double rx[9] = {1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a)};
  double phi[3];
  double R[9];
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      R[3 * r + k] = rx[3 * r] * p.R[k] + rx[3 * r + 1] * p.R[3 + k] + rx[3 * r + 2] * p.R[6 + k];
  gs::pose::so3_log(R, phi);
  return make_pose(phi, c);
}

// The world changed by a similarity: X' = s Rz(yaw) X + t.
std::vector<TimedPose> similar(const std::vector<TimedPose>& in, double s, double yaw_deg, const double t[3]) {
  gs::pose::Sim3 T;
  T.s = s;
  const double a = yaw_deg * 3.14159265358979323846 / 180;
  const double R[9] = {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
  std::copy(R, R + 9, T.R);
  std::copy(t, t + 3, T.t);
  std::vector<TimedPose> out = in;
  for (TimedPose& p : out) p.pose = gs::pose::transform_pose(T, p.pose);
  return out;
}

std::string write_tum(const TempDir& dir, const std::string& name, const std::vector<TimedPose>& poses) {
  const std::string path = dir.path() + "/" + name;
  REQUIRE(gs::io::write_tum_trajectory(poses, path).ok());
  return path;
}

std::string frame_name(int i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%06d.png", i);
  return buf;
}

// A COLMAP model of the poses, images named frame_NNNNNN.png in the given order of indices.
std::string write_colmap(const TempDir& dir, const std::string& name, const std::vector<TimedPose>& poses,
                         const std::vector<int>& order) {
  gs::io::ColmapModel m;
  gs::io::ColmapCamera cam;
  cam.id = 1;
  cam.model = "PINHOLE";
  cam.width = 64, cam.height = 48;
  cam.params = {50, 50, 32, 24};
  m.cameras.push_back(cam);
  uint32_t id = 1;
  for (int i : order) {
    gs::io::ColmapImage im;
    im.id = id++;
    im.camera_id = 1;
    im.name = frame_name(i);
    gs::io::pose_to_colmap(poses[size_t(i)].pose, im.qvec, im.tvec);
    m.images.push_back(im);
  }
  const std::string path = dir.path() + "/" + name;
  REQUIRE(gs::io::write_colmap_text(m, path).ok());
  return path;
}

std::string slurp(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

}  // namespace

TEST_CASE("compare poses: a TUM trajectory against itself has no error") {
  TempDir dir("compare_self");
  const std::string truth = write_tum(dir, "truth.txt", trajectory(60));
  for (bool align : {true, false}) {
    PoseCompareOptions o;
    o.align = align;
    const auto c = gs::jobs::compare_poses(truth, truth, o);
    REQUIRE(c.ok());
    CHECK(c->matching == "time");
    CHECK(c->names.size() == 60);
    CHECK(c->missing == 0);
    CHECK(c->unmatched == 0);
    CHECK(c->errors.aligned == align);
    // The same poses: exactly zero without the fit, round-off with it.
    const double tol = align ? 1e-4 : 0.0;
    CHECK(c->errors.rotation_max_deg <= tol);
    CHECK(c->errors.ate_rmse <= tol);
    CHECK(c->rpe.pairs == 59);
    CHECK(c->rpe.rotation_max_deg <= tol);
    CHECK(c->rpe.translation_max <= tol);
  }
}

TEST_CASE("compare poses: known perturbations give their errors") {
  TempDir dir("compare_known");
  const std::vector<TimedPose> truth_poses = trajectory(60);
  const std::string truth = write_tum(dir, "truth.txt", truth_poses);

  SUBCASE("every camera turned by 0.5 degrees and moved by 1 cm: per frame, ATE") {
    std::vector<TimedPose> est = truth_poses;
    const double d[3] = {0.006, 0.0, 0.008};  // 1 cm
    for (TimedPose& p : est) p.pose = moved(turned(p.pose, 0.5), d);
    PoseCompareOptions o;
    o.align = false;
    o.radius = 2.0;
    o.per_frame_csv = dir.path() + "/per_frame.csv";
    const auto c = gs::jobs::compare_poses(truth, write_tum(dir, "est.txt", est), o);
    REQUIRE(c.ok());
    CHECK(c->errors.rotation_mean_deg == doctest::Approx(0.5).epsilon(1e-3));
    CHECK(c->errors.rotation_max_deg == doctest::Approx(0.5).epsilon(1e-3));
    CHECK(c->errors.translation_mean == doctest::Approx(0.01).epsilon(1e-3));
    CHECK(c->errors.ate_rmse == doctest::Approx(0.01).epsilon(1e-3));
    CHECK(c->scene_radius == 2.0);
    REQUIRE(c->frames.size() == 60);
    CHECK(c->frames[7].centre_frac == doctest::Approx(0.005).epsilon(1e-3));
    // The CSV: a header and one row per true frame.
    const std::string csv = slurp(o.per_frame_csv);
    CHECK(csv.rfind("index,name,time,status,rotation_deg,centre_error,centre_error_frac\n", 0) == 0);
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 61);
    CHECK(csv.find("\n7,,0.233333,compared,") != std::string::npos);
  }

  SUBCASE("one camera moved by 1 cm: RPE of the two pairs around it") {
    std::vector<TimedPose> est = truth_poses;
    const double d[3] = {0.0, 0.01, 0.0};
    est[20].pose = moved(est[20].pose, d);
    PoseCompareOptions o;
    o.align = false;
    const auto c = gs::jobs::compare_poses(truth, write_tum(dir, "est.txt", est), o);
    REQUIRE(c.ok());
    CHECK(c->rpe.pairs == 59);
    CHECK(c->rpe.translation_max == doctest::Approx(0.01).epsilon(1e-3));
    CHECK(c->rpe.translation_mean == doctest::Approx(0.02 / 59).epsilon(1e-2));
    CHECK(c->rpe.translation_median < 1e-6);
    CHECK(c->rpe.rotation_max_deg < 1e-4);
    CHECK(c->errors.ate_rmse == doctest::Approx(0.01 / std::sqrt(60.0)).epsilon(1e-3));
  }

  SUBCASE("another frame and scale: the Sim(3) fit removes it, --no-align does not") {
    const double t[3] = {1.0, -2.0, 0.5};
    const std::string est = write_tum(dir, "est.txt", similar(truth_poses, 1.7, 25.0, t));
    const auto aligned = gs::jobs::compare_poses(truth, est);
    REQUIRE(aligned.ok());
    CHECK(aligned->errors.aligned);
    CHECK(aligned->errors.scale == doctest::Approx(1 / 1.7).epsilon(1e-5));
    CHECK(aligned->errors.rotation_max_deg < 1e-3);
    CHECK(aligned->errors.ate_rmse < 1e-5);
    CHECK(aligned->rpe.translation_max < 1e-5);  // the estimate's motions scaled back by the fit
    PoseCompareOptions raw;
    raw.align = false;
    const auto c = gs::jobs::compare_poses(truth, est, raw);
    REQUIRE(c.ok());
    CHECK(!c->errors.aligned);
    CHECK(c->errors.rotation_mean_deg == doctest::Approx(25.0).epsilon(1e-3));
    CHECK(c->errors.ate_rmse > 1.0);
  }
}

TEST_CASE("compare poses: timestamps, lost and missing frames") {
  TempDir dir("compare_lost");
  const std::vector<TimedPose> truth_poses = trajectory(60);
  const std::string truth = write_tum(dir, "truth.txt", truth_poses);
  // The estimate: frames 10..14 missing, times off by 0.4 of a frame interval, one pose far away in
  // time, and frames 30, 31, 32 marked lost (one of them, 12, is also missing).
  std::vector<TimedPose> est;
  for (int i = 0; i < 60; ++i) {
    if (i >= 10 && i < 15) continue;
    TimedPose p = truth_poses[size_t(i)];
    p.time += 0.4 / kFps;
    if (i >= 30 && i <= 32) p.pose = turned(p.pose, 30.0);  // wrong, and marked lost
    est.push_back(p);
  }
  est.push_back({100.0, truth_poses[0].pose});
  const std::string est_path = write_tum(dir, "est.txt", est);
  {
    std::ofstream lost(dir.path() + "/lost.txt");
    lost << "# lost frames\n" << 30 / kFps << "\n" << 31 / kFps + 0.1 / kFps << " tracking lost\n"
         << 32 / kFps << "\n" << 12 / kFps << "\n";
  }
  PoseCompareOptions o;
  o.align = false;
  o.lost_path = dir.path() + "/lost.txt";
  o.json_path = dir.path() + "/c.json";
  const auto c = gs::jobs::compare_poses(truth, est_path, o);
  REQUIRE(c.ok());
  CHECK(c->matching == "time");
  CHECK(c->time_tolerance == doctest::Approx(0.5 / kFps).epsilon(1e-4));
  CHECK(c->truth_images == 60);
  CHECK(c->estimate_images == 56);
  CHECK(c->names.size() == 52);
  CHECK(c->lost == 3);
  CHECK(c->missing == 5);
  CHECK(c->missing_listed_lost == 1);
  CHECK(c->unmatched == 1);
  CHECK(c->errors.rotation_max_deg < 1e-4);  // the wrong frames are not counted
  CHECK(c->frames[11].status == FrameComparison::Status::kMissing);
  CHECK(c->frames[31].status == FrameComparison::Status::kLost);
  CHECK(c->frames[33].status == FrameComparison::Status::kCompared);
  // RPE pairs: consecutive true frames both compared: 59 - 6 (around 10..14) - 4 (around 30..32).
  CHECK(c->rpe.pairs == 49);
  const nlohmann::json j = nlohmann::json::parse(slurp(o.json_path));
  CHECK(j["lost"] == 3);
  CHECK(j["missing"] == 5);
  CHECK(j["alignment"] == "none");
  CHECK(j["per_frame"].size() == 60);
  CHECK(j["per_frame"][31]["status"] == "lost");
  CHECK(j["rpe"]["pairs"] == 49);

  // Without the lost list the wrong frames count.
  PoseCompareOptions all;
  all.align = false;
  const auto counted = gs::jobs::compare_poses(truth, est_path, all);
  REQUIRE(counted.ok());
  CHECK(counted->names.size() == 55);
  CHECK(counted->errors.rotation_max_deg == doctest::Approx(30.0).epsilon(1e-3));
}

TEST_CASE("compare poses: COLMAP models by name as before, by order against a TUM file") {
  TempDir dir("compare_colmap");
  const std::vector<TimedPose> truth_poses = trajectory(40);
  std::vector<int> forward, backward;
  for (int i = 0; i < 40; ++i) forward.push_back(i), backward.push_back(39 - i);
  std::vector<TimedPose> est_poses = truth_poses;
  for (TimedPose& p : est_poses) p.pose = turned(p.pose, 1.0);
  const std::string truth_model = write_colmap(dir, "truth", truth_poses, forward);
  const std::string est_model = write_colmap(dir, "est", est_poses, backward);
  const std::string truth_tum = write_tum(dir, "truth.txt", truth_poses);

  // By name: compared in the estimate's order (its relative rotations too), errors as for TUM.
  const auto c = gs::jobs::compare_pose_models(truth_model, est_model, dir.path() + "/c.json");
  REQUIRE(c.ok());
  CHECK(c->matching == "name");
  REQUIRE(c->names.size() == 40);
  CHECK(c->names.front() == frame_name(39));
  CHECK(c->errors.aligned);
  CHECK(c->rpe.pairs == 39);
  CHECK(c->frames.front().name == frame_name(0));
  const nlohmann::json j = nlohmann::json::parse(slurp(dir.path() + "/c.json"));
  for (const char* key : {"matched", "aligned", "scale", "scene_radius", "rotation_deg", "centre", "ate_rmse",
                          "relative_rotation_deg", "per_image"})
    CHECK(j.contains(key));
  CHECK(j["per_image"][0]["name"] == frame_name(39));

  // A TUM file against a COLMAP model: only by order.
  const auto refused = gs::jobs::compare_poses(truth_tum, est_model);
  REQUIRE(!refused.ok());
  CHECK(refused.status().message().find("--by-order") != std::string::npos);
  PoseCompareOptions by_order;
  by_order.by_order = true;
  const auto ordered = gs::jobs::compare_poses(truth_tum, est_model, by_order);
  REQUIRE(ordered.ok());
  CHECK(ordered->matching == "order");
  CHECK(ordered->names.size() == 40);
  CHECK(ordered->errors.rotation_mean_deg == doctest::Approx(c->errors.rotation_mean_deg).epsilon(1e-4));
  // By order needs as many poses on both sides.
  std::vector<int> fewer(forward.begin(), forward.begin() + 30);
  const auto short_est = gs::jobs::compare_poses(truth_tum, write_colmap(dir, "short", est_poses, fewer), by_order);
  REQUIRE(!short_est.ok());
  CHECK(short_est.status().message().find("the truth has 40, the estimate 30") != std::string::npos);
  // Lost frames by name.
  {
    std::ofstream lost(dir.path() + "/lost.txt");
    lost << frame_name(3) << "\n" << frame_name(4) << "\n";
  }
  PoseCompareOptions named;
  named.lost_path = dir.path() + "/lost.txt";
  const auto named_lost = gs::jobs::compare_poses(truth_model, est_model, named);
  REQUIRE(named_lost.ok());
  CHECK(named_lost->lost == 2);
  CHECK(named_lost->names.size() == 38);
}
