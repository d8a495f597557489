// SPDX-License-Identifier: MIT
// Photometric alignment of noisy training poses to the SfM points (gs/model/point_alignment.h) on
// the real fox scene (../shared/data/fox; skipped without it): every training pose rotated by 2
// degrees and moved by 2 % of the camera radius, then aligned with the points' COLMAP colours and
// with leave-one-out means; plus the refusal of bad inputs (no data needed).
#include <doctest/doctest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/model/point_alignment.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose.h"

namespace gs::model {
namespace {

TEST_CASE("point alignment: fox training poses from a 2 degree and 2 percent start (shared data)") {
  const std::string root = std::string(GS_SOURCE_DIR) + "/../shared/data/fox";
  if (!std::filesystem::exists(root + "/sparse/0")) {
    MESSAGE("skipped: " << root << "/sparse/0 is absent");
    return;
  }
  Expected<io::Dataset> ds = io::load_dataset(root);
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  std::vector<Pose> truth;
  std::vector<Camera> start;
  std::vector<const io::Image8*> images;
  for (const io::DatasetView& v : ds->views)
    if (!v.is_test) {
      truth.push_back(v.camera.pose);
      start.push_back(v.camera);
      images.push_back(&v.image);
    }
  double centre[3], radius = 0;
  pose::scene_frame(truth.data(), truth.size(), centre, &radius);
  pose::PoseNoise noise;
  noise.kind = pose::PoseNoise::kFixed;
  noise.rotation_deg = 2;
  noise.translation_frac = 0.02;
  std::vector<Pose> noisy = truth;
  pose::perturb_poses(noise, centre, radius, noisy.data(), noisy.size());
  for (size_t i = 0; i < start.size(); ++i) start[i].pose = noisy[i];
  platform::ThreadPool pool(2);
  const size_t n = ds->points_xyz.size() / 3;
  for (bool colours : {true, false}) {
    std::vector<Camera> cams = start;
    PointAlignReport rep;
    REQUIRE(align_poses_to_points(ds->points_xyz.data(), colours ? ds->points_rgb.data() : nullptr, n, images, &cams,
                                  PointAlignOptions{}, &pool, &rep)
                .ok());
    std::vector<Pose> end;
    for (const Camera& c : cams) end.push_back(c.pose);
    const pose::PoseErrors before = pose::pose_errors(noisy.data(), truth.data(), truth.size(), radius, false);
    const pose::PoseErrors after = pose::pose_errors(end.data(), truth.data(), truth.size(), radius, false);
    MESSAGE(std::string(colours ? "point colours" : "leave-one-out means")
            << ": rotation " << before.rotation_mean_deg << " -> " << after.rotation_mean_deg << " deg, centre "
            << before.translation_mean_frac << " -> " << after.translation_mean_frac << " of the radius, " << rep.seconds << " s");
    // Measured (unaligned): point colours 2.0 -> 0.22 deg and 0.020 -> 0.0055 of the radius; the
    // leave-one-out means 2.0 -> 1.17 deg (they pull less, but still towards the truth).
    if (colours) {
      CHECK(after.rotation_mean_deg < 0.25 * before.rotation_mean_deg);
      CHECK(after.translation_mean_frac < 0.35 * before.translation_mean_frac);
    } else {
      CHECK(after.rotation_mean_deg < before.rotation_mean_deg);
    }
  }
}

TEST_CASE("point alignment: bad inputs are refused") {
  const float xyz[3 * 12] = {};
  io::Image8 im;
  im.width = 8, im.height = 6, im.channels = 3;
  im.pixels.assign(8 * 6 * 3, 100);
  Camera cam;
  cam.intr = PinholeIntrinsics{8, 8, 4, 3, 8, 6};
  std::vector<const io::Image8*> images = {&im, &im};
  std::vector<Camera> one(1, cam), two(2, cam);
  CHECK(align_poses_to_points(xyz, nullptr, 12, {&im}, &one, {}, nullptr, nullptr).code() == StatusCode::kInvalidArgument);
  CHECK(align_poses_to_points(xyz, nullptr, 5, images, &two, {}, nullptr, nullptr).code() == StatusCode::kInvalidArgument);
  two[1].intr.width = 9;
  CHECK(align_poses_to_points(xyz, nullptr, 12, images, &two, {}, nullptr, nullptr).code() == StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace gs::model
