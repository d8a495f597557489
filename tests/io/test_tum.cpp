// SPDX-License-Identifier: MIT
// TUM trajectory files: round trip, the camera-centre convention, and refused lines.
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "gs/io/tum.h"
#include "gs/pose/pose.h"
#include "support/temp_dir.h"

using namespace gs;

namespace {
Pose turned_pose(double angle, double tx, double ty, double tz) {
  const double q[4] = {std::cos(angle / 2), 0.3 * std::sin(angle / 2), std::sqrt(0.91) * std::sin(angle / 2), 0};
  double R[9];
  pose::rotation_from_quaternion(q, R);
  Pose p;
  for (int i = 0; i < 9; ++i) p.R[i] = float(R[i]);
  p.t[0] = float(tx), p.t[1] = float(ty), p.t[2] = float(tz);
  return p;
}
}  // namespace

TEST_CASE("TUM trajectory: written centres and camera-to-world quaternions read back as the same poses") {
  std::vector<io::TimedPose> poses;
  for (int i = 0; i < 5; ++i) poses.push_back({i / 30.0, turned_pose(0.4 * i - 0.7, 0.1 * i, -0.2, 1.5 + i)});
  test::TempDir dir;
  const std::string path = dir.path() + "/t.tum";
  REQUIRE(io::write_tum_trajectory(poses, path).ok());
  Expected<std::vector<io::TimedPose>> back = io::read_tum_trajectory(path);
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  REQUIRE(back->size() == poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    CHECK((*back)[i].time == doctest::Approx(poses[i].time).epsilon(1e-6));
    for (int k = 0; k < 9; ++k) CHECK((*back)[i].pose.R[k] == doctest::Approx(poses[i].pose.R[k]).epsilon(1e-6));
    for (int k = 0; k < 3; ++k) CHECK((*back)[i].pose.t[k] == doctest::Approx(poses[i].pose.t[k]).epsilon(1e-6));
  }
  // The line holds the camera centre -R^T t and the rotation's conjugate, scalar last.
  io::TimedPose p{2.5, turned_pose(0.0, 1, 2, 3)};  // identity rotation: centre (-1, -2, -3), q = (0, 0, 0, 1)
  CHECK(io::tum_line(p) == "2.500000 -1 -2 -3 0 0 0 1");
  io::TimedPose o{0.0, turned_pose(0.0, 0, 0, 4)};  // zero coordinates print as 0, not -0
  CHECK(io::tum_line(o) == "0.000000 0 0 -4 0 0 0 1");
}

TEST_CASE("TUM trajectory: comments and blank lines are skipped, malformed lines are refused by line") {
  Expected<std::vector<io::TimedPose>> ok = io::parse_tum_trajectory("# header\n\n1.0 0 0 0 0 0 0 1\r\n  2 1 2 3 0 0 0 2\n", "a.tum");
  REQUIRE_MESSAGE(ok.ok(), ok.status().to_string());
  REQUIRE(ok->size() == 2);
  CHECK((*ok)[1].pose.t[0] == doctest::Approx(-1));  // normalised quaternion, identity: t = -c
  struct Bad {
    const char* text;
    const char* message;
  };
  for (const Bad& b : {Bad{"1 2 3\n", "a.tum:1: expected 8 numbers (timestamp tx ty tz qx qy qz qw), found 3"},
                       Bad{"# c\n1 0 0 0 0 0 0 1 9\n", "a.tum:2: expected 8 numbers (timestamp tx ty tz qx qy qz qw), found more"},
                       Bad{"1 0 0 x 0 0 0 1\n", "a.tum:1: expected a number, found \"x 0 0 0 1\""},
                       Bad{"1 0 0 nan 0 0 0 1\n", "a.tum:1: value 4 is not finite"},
                       Bad{"1 0 0 0 0 0 0 0\n", "a.tum:1: quaternion norm 0.000000 is not close to 1"}}) {
    CAPTURE(b.text);
    Expected<std::vector<io::TimedPose>> r = io::parse_tum_trajectory(b.text, "a.tum");
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message() == b.message);
  }
  CHECK_FALSE(io::read_tum_trajectory("/nonexistent/x.tum").ok());
}
