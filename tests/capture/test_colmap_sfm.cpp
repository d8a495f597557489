// SPDX-License-Identifier: MIT
// The SfM consistency check's comparison (gs::capture::compare_reconstructions) on made-up
// reconstructions: a check run in another frame and scale that agrees, one with views turned or
// moved, views missing from a run, corrupted views that must not tilt the alignment, and
// reconstructions whose centres lie on a line (no alignment, so no verdict).
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "gs/capture/colmap_sfm.h"
#include "gs/io/colmap.h"
#include "gs/pose/pose.h"

namespace {

using gs::capture::compare_reconstructions;
using gs::capture::SfmConsistency;

constexpr int kViews = 20;
constexpr double kRadius = 2.0;  // the ring's: the scene radius compare_reconstructions measures in

std::string view_name(int i) { return "frame_" + std::to_string(100 + i) + ".png"; }

// A camera at centre c with world-to-camera rotation exp(phi).
gs::Pose camera(const double c[3], const double phi[3]) {
  double R[9];
  gs::pose::so3_exp(phi, R);
  gs::Pose p;
  for (int k = 0; k < 9; ++k) p.R[k] = float(R[k]);
  for (int r = 0; r < 3; ++r) p.t[r] = float(-(R[3 * r] * c[0] + R[3 * r + 1] * c[1] + R[3 * r + 2] * c[2]));
  return p;
}

// Cameras on a ring of kRadius, bobbing up and down (not coplanar), each turned its own way.
std::vector<gs::Pose> ring() {
  std::vector<gs::Pose> poses;
  for (int i = 0; i < kViews; ++i) {
    const double a = 2 * M_PI * i / kViews;
    const double c[3] = {kRadius * std::cos(a), 0.3 * std::sin(3 * a), kRadius * std::sin(a)};
    const double phi[3] = {0.1 * std::sin(a), a, 0.05 * i};
    poses.push_back(camera(c, phi));
  }
  return poses;
}

gs::io::ColmapModel model_of(const std::vector<gs::Pose>& poses, const std::vector<int>& leave_out = {}) {
  gs::io::ColmapModel m;
  for (int i = 0; i < int(poses.size()); ++i) {
    bool left = false;
    for (int l : leave_out) left = left || l == i;
    if (left) continue;
    gs::io::ColmapImage im;
    im.id = uint32_t(i + 1);
    im.name = view_name(i);
    gs::io::pose_to_colmap(poses[i], im.qvec, im.tvec);
    m.images.push_back(im);
  }
  return m;
}

// The same cameras in another frame and scale (what a second reconstruction would give).
std::vector<gs::Pose> in_other_frame(const std::vector<gs::Pose>& poses) {
  gs::pose::Sim3 T;
  T.s = 2.5;
  const double phi[3] = {0.3, -0.2, 0.5};
  gs::pose::so3_exp(phi, T.R);
  T.t[0] = 1;
  T.t[1] = -2;
  T.t[2] = 3;
  std::vector<gs::Pose> out;
  for (const gs::Pose& p : poses) out.push_back(gs::pose::transform_pose(T, p));
  return out;
}

// View i turned by `deg` degrees about its own optical axis, its centre kept.
void turn(std::vector<gs::Pose>* poses, int i, double deg) {
  double c[3], R[9], D[9], RD[9];
  gs::pose::centre((*poses)[i], c);
  for (int k = 0; k < 9; ++k) R[k] = (*poses)[i].R[k];
  const double phi[3] = {0, 0, deg * M_PI / 180};
  gs::pose::so3_exp(phi, D);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) RD[3 * r + k] = D[3 * r] * R[k] + D[3 * r + 1] * R[3 + k] + D[3 * r + 2] * R[6 + k];
  double back[3];
  gs::pose::so3_log(RD, back);
  (*poses)[i] = camera(c, back);
}

// View i's centre moved by `distance` along x, its rotation kept.
void move(std::vector<gs::Pose>* poses, int i, double distance) {
  double c[3], R[9], phi[3];
  gs::pose::centre((*poses)[i], c);
  for (int k = 0; k < 9; ++k) R[k] = (*poses)[i].R[k];
  gs::pose::so3_log(R, phi);
  c[0] += distance;
  (*poses)[i] = camera(c, phi);
}

const gs::capture::ViewAgreement& view(const SfmConsistency& c, int i) {
  for (const gs::capture::ViewAgreement& v : c.views)
    if (v.name == view_name(i)) return v;
  FAIL("no view " << view_name(i));
  return c.views.front();
}

}  // namespace

TEST_CASE("consistency check: a reconstruction in another frame and scale agrees on every view") {
  const std::vector<gs::Pose> chosen = ring();
  const SfmConsistency c = compare_reconstructions(model_of(chosen), {model_of(in_other_frame(chosen))}, 5.0, 0.1);
  CHECK(c.check_runs == 1);
  CHECK(c.aligned_runs == 1);
  CHECK(c.suspect == 0);
  REQUIRE(c.views.size() == size_t(kViews));
  CHECK(c.rotation_max_deg < 0.01);  // float poses: rounding only
  for (const gs::capture::ViewAgreement& v : c.views) {
    CHECK(v.check_runs == 1);
    CHECK(v.disagreeing == 0);
    CHECK(v.centre_fraction < 1e-4);
  }
  CHECK(c.views.front().name < c.views.back().name);  // sorted by name
}

TEST_CASE("consistency check: views turned or moved in a check run are suspect, with the measured difference") {
  const std::vector<gs::Pose> chosen = ring();
  std::vector<gs::Pose> other = in_other_frame(chosen);
  turn(&other, 4, 15.0);
  turn(&other, 7, 4.0);        // under the 5 degree limit: not suspect
  move(&other, 9, 2.5 * 0.3 * kRadius);  // 0.3 of the radius in the check run's scale (2.5)
  const SfmConsistency c = compare_reconstructions(model_of(chosen), {model_of(other)}, 5.0, 0.1);
  CHECK(c.suspect == 2);
  CHECK(c.suspect_names() == std::vector<std::string>{view_name(4), view_name(9)});
  CHECK(view(c, 4).rotation_deg == doctest::Approx(15.0).epsilon(1e-3));
  CHECK(view(c, 4).centre_fraction < 1e-3);
  CHECK(view(c, 7).rotation_deg == doctest::Approx(4.0).epsilon(1e-3));
  CHECK_FALSE(view(c, 7).suspect);
  // The trimmed alignment leaves the moved view out, so it is measured where it is: 0.3 of the ring's
  // radius (the scene radius is the farthest centre's distance from their mean: 1 % more).
  CHECK(view(c, 9).centre_fraction == doctest::Approx(0.3).epsilon(0.02));
  CHECK(view(c, 9).rotation_deg < 0.01);
  CHECK(view(c, 0).rotation_deg < 0.01);
  // A larger rotation limit leaves view 4 alone; a centre limit above 0.3 leaves view 9 alone.
  CHECK(compare_reconstructions(model_of(chosen), {model_of(other)}, 20.0, 0.5).suspect == 0);
}

TEST_CASE("consistency check: many corrupted views do not tilt the alignment of the others") {
  const std::vector<gs::Pose> chosen = ring();
  std::vector<gs::Pose> other = in_other_frame(chosen);
  for (int i : {1, 2, 3, 11, 12}) move(&other, i, 2.5 * kRadius);  // 5 of 20 views a radius away
  const SfmConsistency c = compare_reconstructions(model_of(chosen), {model_of(other)}, 5.0, 0.1);
  CHECK(c.suspect_names() == std::vector<std::string>{view_name(1), view_name(2), view_name(3), view_name(11), view_name(12)});
  for (int i : {0, 4, 5, 10, 19}) {
    CHECK(view(c, i).rotation_deg < 0.01);
    CHECK(view(c, i).centre_fraction < 1e-3);
  }
}

TEST_CASE("consistency check: suspect needs at least half of the check runs that registered the view") {
  const std::vector<gs::Pose> chosen = ring();
  std::vector<gs::Pose> turned = in_other_frame(chosen);
  turn(&turned, 5, 30.0);
  const gs::io::ColmapModel agree = model_of(in_other_frame(chosen));
  const gs::io::ColmapModel agree_without_5 = model_of(in_other_frame(chosen), {5});
  // 1 of 2: suspect; 1 of 3: not; 1 of 2 registering it (the third left it out): suspect.
  CHECK(compare_reconstructions(model_of(chosen), {model_of(turned), agree}, 5.0, 0.1).suspect_names() ==
        std::vector<std::string>{view_name(5)});
  const SfmConsistency three = compare_reconstructions(model_of(chosen), {model_of(turned), agree, agree}, 5.0, 0.1);
  CHECK(three.suspect == 0);
  CHECK(view(three, 5).disagreeing == 1);
  CHECK(view(three, 5).check_runs == 3);
  CHECK(view(three, 5).rotation_deg == doctest::Approx(30.0).epsilon(1e-3));  // the largest over the runs
  const SfmConsistency missing = compare_reconstructions(model_of(chosen), {model_of(turned), agree, agree_without_5}, 5.0, 0.1);
  CHECK(view(missing, 5).check_runs == 2);
  CHECK(view(missing, 5).suspect);
  // A view no check run registered has no verdict.
  const SfmConsistency none = compare_reconstructions(model_of(chosen), {agree_without_5}, 5.0, 0.1);
  CHECK(view(none, 5).check_runs == 0);
  CHECK_FALSE(view(none, 5).suspect);
  CHECK(none.suspect == 0);
}

TEST_CASE("consistency check: no verdict without an alignment (too few shared views, centres on a line)") {
  std::vector<gs::Pose> line;
  for (int i = 0; i < 8; ++i) {
    const double c[3] = {0.2 * i, 0, 0}, phi[3] = {0, 0.1 * i, 0};
    line.push_back(camera(c, phi));
  }
  std::vector<gs::Pose> turned = line;
  turn(&turned, 2, 40.0);
  SfmConsistency c = compare_reconstructions(model_of(line), {model_of(turned)}, 5.0, 0.1);
  CHECK(c.check_runs == 1);
  CHECK(c.aligned_runs == 0);
  CHECK(c.suspect == 0);
  for (const gs::capture::ViewAgreement& v : c.views) CHECK(v.check_runs == 0);
  // Two shared views: no Sim(3) either.
  std::vector<int> all_but_two;
  for (int i = 2; i < kViews; ++i) all_but_two.push_back(i);
  const std::vector<gs::Pose> chosen = ring();
  c = compare_reconstructions(model_of(chosen), {model_of(in_other_frame(chosen), all_but_two)}, 5.0, 0.1);
  CHECK(c.aligned_runs == 0);
  CHECK(c.suspect == 0);
}

TEST_CASE("consistency check: of several mappings the one the others agree with most is chosen, the first on a tie") {
  // The first mapping corrupted (6 of 20 views turned 20 degrees), three check runs sound in
  // frames of their own: a check run is chosen, and the others doubt none of its views. With a
  // sound first mapping nothing changes, and a run with too few images never takes part.
  using gs::capture::choose_most_consistent;
  const std::vector<gs::Pose> truth = ring();
  std::vector<gs::Pose> corrupted = truth;
  for (int i : {2, 3, 4, 5, 6, 7}) turn(&corrupted, i, 20.0);
  const gs::io::ColmapModel sound = model_of(in_other_frame(truth));
  SfmConsistency c;
  const size_t pick = choose_most_consistent({model_of(corrupted), sound, model_of(truth), sound}, 10, 5.0, 0.1, &c);
  CHECK(pick != 0);
  CHECK(c.suspect == 0);
  CHECK(compare_reconstructions(model_of(corrupted), {sound, model_of(truth), sound}, 5.0, 0.1).suspect == 6);
  CHECK(choose_most_consistent({model_of(truth), sound, model_of(corrupted), sound}, 10, 5.0, 0.1, &c) == 0);
  CHECK(c.suspect == 0);
  // Too few images (10 needed): the sound runs that registered only 8 cannot be chosen.
  std::vector<int> twelve;
  for (int i = 8; i < kViews; ++i) twelve.push_back(i);
  const gs::io::ColmapModel small = model_of(truth, twelve);
  CHECK(choose_most_consistent({model_of(corrupted), small, small, small}, 10, 5.0, 0.1, &c) == 0);
}
