// SPDX-License-Identifier: MIT
// The frame alignment behind `--pose-init sfm`: ICP (Sim(3)) of a reconstruction's points onto the
// dataset's points must recover the true transform from a start a few degrees and percent off,
// with part of the source points noisy or outliers, as COLMAP's points are. The COLMAP part runs in
// the `cli_train_pose_init_sfm` end-to-end test.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gs/capture/sfm_pose_init.h"

namespace {

// Points on three textured-object-like surfaces: a ground plane patch, a sphere and a box face.
std::vector<double> scene_points(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> p;
  for (int i = 0; i < n; ++i) {
    const int kind = i % 3;
    if (kind == 0) {
      p.insert(p.end(), {2.0 * u(rng), 2.0 * u(rng), 0.0});
    } else if (kind == 1) {
      double v[3] = {u(rng), u(rng), u(rng)};
      const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + 1e-9;
      p.insert(p.end(), {0.5 + 0.6 * v[0] / len, -0.3 + 0.6 * v[1] / len, 0.6 + 0.6 * v[2] / len});
    } else {
      p.insert(p.end(), {-0.8 + 0.4 * u(rng), 0.7, 0.5 + 0.5 * u(rng)});
    }
  }
  return p;
}

double rotation_deg(const double A[9], const double B[9]) {
  double tr = 0;  // trace(A B^T)
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) tr += A[3 * r + k] * B[3 * r + k];
  return std::acos(std::clamp((tr - 1) / 2, -1.0, 1.0)) * 180.0 / M_PI;
}

}  // namespace

TEST_CASE("ICP Sim3 recovers the frame from a few degrees off with noise and outliers") {
  std::mt19937_64 rng(7);
  const std::vector<double> target = scene_points(rng, 6000);
  // The reconstruction's frame: scale 0.37, rotated, shifted. source = truth^-1(target subset).
  gs::pose::Sim3 truth;
  const double phi[3] = {0.4, 1.1, -0.6};
  gs::pose::so3_exp(phi, truth.R);
  truth.s = 2.7;
  truth.t[0] = 0.3, truth.t[1] = -0.2, truth.t[2] = 0.9;
  // Inverse: x = R^T (y - t) / s.
  std::normal_distribution<double> noise(0.0, 0.004);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  std::vector<double> source;
  for (size_t i = 0; i < target.size() / 3; i += 3) {
    double y[3] = {target[3 * i], target[3 * i + 1], target[3 * i + 2]};
    if (i % 30 == 0) y[0] = u(rng), y[1] = u(rng), y[2] = u(rng);  // 10 % outliers
    for (double& v : y) v += noise(rng);
    double d[3] = {y[0] - truth.t[0], y[1] - truth.t[1], y[2] - truth.t[2]}, x[3];
    for (int r = 0; r < 3; ++r) x[r] = (truth.R[r] * d[0] + truth.R[3 + r] * d[1] + truth.R[6 + r] * d[2]) / truth.s;
    source.insert(source.end(), x, x + 3);
  }
  // Start: 4 degrees and 5 % of the scale off, shifted by 0.1.
  gs::pose::Sim3 wrong;
  const double off[3] = {0.04, -0.05, 0.03};
  gs::pose::so3_exp(off, wrong.R);
  wrong.s = 1.05;
  wrong.t[0] = 0.1;
  const gs::pose::Sim3 start = gs::pose::compose(wrong, truth);
  CHECK(rotation_deg(start.R, truth.R) > 3.0);

  double before = 0, after = 0;
  int pairs = 0, iterations = 0;
  const gs::pose::Sim3 got = gs::pose::icp_sim3(source.data(), source.size() / 3, target.data(), target.size() / 3,
                                                   start, 60, 2.5, &before, &after, &pairs, &iterations);
  MESSAGE("ICP: median distance ", before, " -> ", after, ", ", pairs, " pairs, ", iterations, " iterations");
  CHECK(rotation_deg(got.R, truth.R) < 0.1);
  CHECK(got.s == doctest::Approx(truth.s).epsilon(0.005));
  for (int k = 0; k < 3; ++k) CHECK(got.t[k] == doctest::Approx(truth.t[k]).epsilon(0.01).scale(1.0));
  CHECK(after < 0.5 * before);
  CHECK(pairs > int(source.size() / 3 / 2));
}

TEST_CASE("SfM pose init refuses too few views or points before running COLMAP") {
  std::vector<gs::Camera> cams(2);
  std::vector<const gs::io::Image8*> images(2, nullptr);
  std::vector<std::string> names = {"a", "b"};
  const float pts[3] = {0, 0, 0};
  gs::capture::SfmPoseInitOptions o;
  gs::Status st = gs::capture::init_poses_by_sfm(images, names, &cams, pts, 1, "/nonexistent/work", o, {}, nullptr);
  REQUIRE(!st.ok());
  CHECK(st.message().find("at least 3 views") != std::string::npos);
  cams.resize(3), images.resize(3), names.push_back("c");
  st = gs::capture::init_poses_by_sfm(images, names, &cams, pts, 1, "/nonexistent/work", o, {}, nullptr);
  REQUIRE(!st.ok());
  CHECK(st.message().find("SfM points") != std::string::npos);
}
