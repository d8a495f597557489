// SPDX-License-Identifier: MIT
// The scene frame (gs/scene_frame.h): which scenes get a frame of their own, and that points, poses
// and Gaussians go into it and back in double precision (a camera at 1e7 units keeps its place).
#include <cmath>
#include <vector>

#include <doctest/doctest.h>

#include "gs/pose/pose.h"
#include "gs/scene_frame.h"

namespace {

using gs::SceneFrame;

// Centres on a circle of radius r around (cx, cy, cz): extent 1.1 r.
std::vector<double> ring(double cx, double cy, double cz, double r, int n = 12) {
  std::vector<double> c;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * 3.14159265358979323846 * i / n;
    c.insert(c.end(), {cx + r * std::cos(a), cy + r * std::sin(a), cz});
  }
  return c;
}

SceneFrame frame_of(const std::vector<double>& c) { return gs::choose_scene_frame(c.data(), c.size() / 3); }

}  // namespace

TEST_CASE("scene frame: ordinary scenes keep the identity, far ones are recentred on a grid, odd scales rescaled by powers of ten") {
  // Ordinary: within half the grid of the origin, extent 0.5..64 (COLMAP models: 4.9 to 7.1).
  CHECK(frame_of(ring(0.1, -1.4, 2.6, 6)).identity());
  CHECK(frame_of(ring(3.0, 0, 0, 6)).identity());    // grid 8: 3 rounds to 0
  CHECK(frame_of(ring(0, 0, 0, 0.5)).identity());    // extent 0.55
  CHECK(frame_of(ring(0, 0, 0, 55)).identity());     // extent 60.5
  CHECK(gs::choose_scene_frame(nullptr, 0).identity());

  // Far: the mean rounded to the power-of-two grid at or above the extent (8 here).
  const SceneFrame far = frame_of(ring(1e5 + 0.37, -1e5 + 2.6, 5e4, 6));
  CHECK(far.centre[0] == 1e5);
  CHECK(far.centre[1] == -1e5);
  CHECK(far.centre[2] == 5e4);
  CHECK(far.scale == 1);
  CHECK(frame_of(ring(4.5, 0, 0, 6)).centre[0] == 8);  // past half the grid: moved

  // Scales: millimetres and kilometres of a 6.6-unit scene come back by exactly 10^3.
  CHECK(frame_of(ring(0, 0, 0, 6e-3)).scale == doctest::Approx(1e3).epsilon(1e-15));
  CHECK(frame_of(ring(0, 0, 0, 6e3)).scale == doctest::Approx(1e-3).epsilon(1e-15));
  CHECK(frame_of(ring(0, 0, 0, 0.3)).scale == 10);
  const SceneFrame both = frame_of(ring(2e6, 0, 0, 6e3));
  CHECK(both.scale == doctest::Approx(1e-3).epsilon(1e-15));
  CHECK(both.centre[0] == 244 * 8192.0);  // the multiple of 8192 (extent 6,600) nearest to 2e6

  CHECK(*gs::scene_frame_problem(far) == 0);
  SceneFrame bad;
  bad.scale = 0;
  CHECK(*gs::scene_frame_problem(bad) != 0);
  bad.scale = 1, bad.centre[1] = NAN;
  CHECK(*gs::scene_frame_problem(bad) != 0);
}

TEST_CASE("scene frame: a pose 1e7 units out keeps its camera centre through the frame and back") {
  SceneFrame f;
  f.centre[0] = 1e7, f.centre[1] = -1e7, f.centre[2] = 2.5e6;
  f.scale = 1e-3;
  const double axis[3] = {0.3, -0.2, 0.9};
  double R[9];
  gs::pose::so3_exp(axis, R);
  const double C[3] = {1e7 + 1234.5678, -1e7 - 987.654321, 2.5e6 + 55.5};  // the true centre, user units
  double t[3];
  for (int i = 0; i < 3; ++i) t[i] = -(R[3 * i] * C[0] + R[3 * i + 1] * C[1] + R[3 * i + 2] * C[2]);
  const gs::Pose p = gs::pose_to_frame(f, R, t);
  // In the frame the centre is (C - centre) / 1000, a small number float holds to 1e-7 relative.
  double cf[3];
  for (int k = 0; k < 3; ++k) cf[k] = -(double(p.R[k]) * p.t[0] + double(p.R[3 + k]) * p.t[1] + double(p.R[6 + k]) * p.t[2]);
  CHECK(cf[0] == doctest::Approx(1.2345678).epsilon(1e-6));
  CHECK(cf[1] == doctest::Approx(-0.987654321).epsilon(1e-6));
  // Back in the user's frame with the stored rotation: the centre within 1e-3 units of 1e7 (float
  // alone keeps 1 unit there).
  double t_back[3];
  gs::pose_to_user(f, p, R, t_back);
  double c_back[3];
  for (int k = 0; k < 3; ++k) c_back[k] = -(R[k] * t_back[0] + R[3 + k] * t_back[1] + R[6 + k] * t_back[2]);
  for (int k = 0; k < 3; ++k) CHECK(std::abs(c_back[k] - C[k]) <= 1e-3);

  // Points and Gaussians: to the frame and back, log-scales shifted by log(scale).
  double x[3], u[3];
  gs::point_to_frame(f, C, x);
  gs::point_to_user(f, x, u);
  for (int k = 0; k < 3; ++k) CHECK(u[k] == doctest::Approx(C[k]).epsilon(1e-15));
  gs::GaussianCloud cloud;
  cloud.resize(1);
  cloud.means = {0.5f, -0.25f, 2.0f};
  cloud.log_scales = {-1.0f, -2.0f, -3.0f};
  gs::GaussianCloud user = cloud;
  gs::cloud_to_user(f, &user);
  CHECK(user.means[0] == float(1e7 + 500));
  CHECK(user.log_scales[0] == doctest::Approx(-1.0 + std::log(1000.0)).epsilon(1e-6));
  gs::cloud_to_frame(f, &user);
  for (int k = 0; k < 3; ++k) CHECK(user.log_scales[size_t(k)] == doctest::Approx(cloud.log_scales[size_t(k)]).epsilon(1e-6));
  CHECK(user.means[2] == doctest::Approx(2.0).epsilon(1e-4));
  // The identity frame touches nothing, bit for bit.
  gs::GaussianCloud same = cloud;
  gs::cloud_to_user(SceneFrame{}, &same);
  CHECK(same.means == cloud.means);
  CHECK(same.log_scales == cloud.log_scales);
}
