// SPDX-License-Identifier: MIT
// Anchor initialisation: closest-to-centroid rule, budgeted auto voxel size, 3-NN log-scales against
// brute force, determinism, errors, and the snowmiku_plush SfM points (skipped without ../shared).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/model/anchors.h"
#include "support/model_fixtures.h"

namespace gs::model {
namespace {

// SfM-like points around (0.3, -0.1, 0.7).
std::vector<float> sphere_points(size_t n, uint32_t seed) {
  const float centre[3] = {0.3f, -0.1f, 0.7f};
  return test::sphere_points(n, seed, centre);
}


TEST_CASE("voxelise: the anchor is the point closest to the voxel centroid") {
  // eps = 1, dyadic coordinates so every distance is exact. Voxel (0,0,0): points 0..3, centroid
  // (0.5, 0.5, 0.46875) -> point 2 is nearest. Voxel (2,0,0): points 4 and 6 are exactly 0.25 from
  // their centroid -> lowest index 4 wins. Voxel (-1,0,0): point 5 alone. Order by key: (-1), (0), (2).
  const std::vector<float> xyz = {
      0.125f, 0.125f, 0.125f,  0.875f, 0.875f, 0.875f,  0.5f, 0.5f, 0.625f,  0.5f, 0.5f, 0.25f,
      2.25f, 0.5f, 0.5f,       -0.5f, 0.25f, 0.375f,    2.75f, 0.5f, 0.5f,
  };
  auto r = voxelise(xyz.data(), xyz.size() / 3, 1.0f);
  REQUIRE_MESSAGE(r.ok(), r.status().to_string());
  CHECK(*r == std::vector<size_t>{5, 2, 4});
  // Point 2 moved to z = 0.875: centroid z = 0.53125, so point 3 (0.28125 away) beats point 2 (0.34375).
  std::vector<float> moved = xyz;
  moved[8] = 0.875f;
  auto m = voxelise(moved.data(), moved.size() / 3, 1.0f);
  REQUIRE(m.ok());
  CHECK(*m == std::vector<size_t>{5, 3, 4});
}

TEST_CASE("choose_voxel_size: the count never exceeds the budget and eps is monotone in it") {
  const std::vector<float> xyz = sphere_points(4000, 7);
  float prev_eps = INFINITY;
  for (size_t budget : {8, 20, 100, 500, 1000, 3000, 100000}) {
    auto eps = choose_voxel_size(xyz.data(), 4000, budget);
    REQUIRE_MESSAGE(eps.ok(), eps.status().to_string());
    auto count = count_occupied_voxels(xyz.data(), 4000, *eps);
    REQUIRE(count.ok());
    CHECK(*count <= budget);
    CHECK(*eps <= prev_eps);  // larger budget: same or smaller voxels
    auto voxels = voxelise(xyz.data(), 4000, *eps);
    REQUIRE(voxels.ok());
    CHECK(voxels->size() == *count);
    prev_eps = *eps;
  }
  // A budget below the 8 voxels a box straddling the origin needs cannot be met: clear error.
  auto tiny = choose_voxel_size(xyz.data(), 4000, 1);
  CHECK_FALSE(tiny.ok());
  CHECK(tiny.status().code() == StatusCode::kCapacityExceeded);
}

TEST_CASE("anchor_log_scales: exact 3-NN mean squared distance against brute force") {
  for (size_t m : {size_t(1), size_t(2), size_t(3), size_t(4), size_t(50), size_t(1500)}) {
    std::vector<float> pos = sphere_points(m, 11 + uint32_t(m));
    if (m == 1500) {  // an isolated far anchor exercises the brute-force fallback
      pos[0] = 40.0f, pos[1] = -30.0f, pos[2] = 25.0f;
    }
    const std::vector<float> ls = anchor_log_scales(pos.data(), m, 0.25f);
    REQUIRE(ls.size() == 6 * m);
    const size_t kk = std::min<size_t>(3, m - 1);
    for (size_t i = 0; i < m; ++i) {
      double d2 = 0.25 * 0.25;
      if (m > 1) {
        std::vector<double> d;
        for (size_t j = 0; j < m; ++j) {
          if (j == i) continue;
          double s = 0;
          for (int a = 0; a < 3; ++a) s += (double(pos[3 * i + a]) - pos[3 * j + a]) * (double(pos[3 * i + a]) - pos[3 * j + a]);
          d.push_back(s);
        }
        std::sort(d.begin(), d.end());
        d2 = 0;
        for (size_t j = 0; j < kk; ++j) d2 += d[j];
        d2 /= double(kk);
      }
      const float want = float(std::log(std::sqrt(std::max(d2, 1e-7))));
      for (int c = 0; c < 6; ++c) REQUIRE(ls[6 * i + c] == doctest::Approx(want).epsilon(1e-5));
    }
  }
  // Coincident anchors: d2 = 0 is clamped to 1e-7 (log-scale = log(sqrt(1e-7))).
  const std::vector<float> same = {1, 2, 3, 1, 2, 3};
  const std::vector<float> ls = anchor_log_scales(same.data(), 2, 1.0f);
  CHECK(ls[0] == doctest::Approx(std::log(std::sqrt(1e-7))));
}

TEST_CASE("init_anchors: shapes and zero initial values and determinism") {
  const std::vector<float> xyz = sphere_points(3000, 3);
  AnchorOptions opt;
  opt.max_anchors = 400;
  opt.k = 10;
  opt.feature_dim = 32;
  auto a = init_anchors(xyz.data(), 3000, opt);
  auto b = init_anchors(xyz.data(), 3000, opt);
  REQUIRE_MESSAGE(a.ok(), a.status().to_string());
  REQUIRE(b.ok());
  const size_t m = a->size();
  CHECK(m > 0);
  CHECK(m <= 400);
  CHECK(a->offsets.size() == m * 10 * 3);
  CHECK(a->log_scales.size() == m * 6);
  CHECK(a->features.size() == m * 32);
  CHECK(std::all_of(a->offsets.begin(), a->offsets.end(), [](float v) { return v == 0.0f; }));
  CHECK(std::all_of(a->features.begin(), a->features.end(), [](float v) { return v == 0.0f; }));
  CHECK(a->voxel_size == b->voxel_size);
  CHECK(a->positions == b->positions);
  CHECK(a->log_scales == b->log_scales);
  // Every anchor is an input point, and lies in a distinct voxel.
  for (size_t i = 0; i < m; ++i) {
    bool found = false;
    for (size_t j = 0; j < 3000 && !found; ++j)
      found = xyz[3 * j] == a->positions[3 * i] && xyz[3 * j + 1] == a->positions[3 * i + 1] && xyz[3 * j + 2] == a->positions[3 * i + 2];
    REQUIRE(found);
  }
  auto count = count_occupied_voxels(a->positions.data(), m, a->voxel_size);
  REQUIRE(count.ok());
  CHECK(*count == m);
  // A fixed voxel size is used as given; a single point gets log(eps) scales.
  opt.voxel_size = 0.5f;
  auto fixed = init_anchors(xyz.data(), 3000, opt);
  REQUIRE(fixed.ok());
  CHECK(fixed->voxel_size == 0.5f);
  auto one = init_anchors(xyz.data(), 1, opt);
  REQUIRE(one.ok());
  CHECK(one->size() == 1);
  CHECK(one->log_scales[0] == doctest::Approx(std::log(0.5f)));
}

TEST_CASE("anchors: errors for empty input and eps <= 0 and bad options") {
  const std::vector<float> xyz = {0, 0, 0, 1, 1, 1};
  CHECK(voxelise(xyz.data(), 0, 1.0f).status().code() == StatusCode::kInvalidArgument);
  CHECK(voxelise(nullptr, 0, 1.0f).status().code() == StatusCode::kInvalidArgument);
  CHECK(voxelise(xyz.data(), 2, 0.0f).status().code() == StatusCode::kInvalidArgument);
  CHECK(voxelise(xyz.data(), 2, -1.0f).status().code() == StatusCode::kInvalidArgument);
  CHECK(voxelise(xyz.data(), 2, NAN).status().code() == StatusCode::kInvalidArgument);
  CHECK(voxelise(xyz.data(), 2, 1e-30f).status().code() == StatusCode::kInvalidArgument);  // keys beyond int64
  CHECK(choose_voxel_size(xyz.data(), 0, 10).status().code() == StatusCode::kInvalidArgument);
  CHECK(choose_voxel_size(xyz.data(), 2, 0).status().code() == StatusCode::kInvalidArgument);
  AnchorOptions opt;
  CHECK(init_anchors(xyz.data(), 0, opt).status().code() == StatusCode::kInvalidArgument);
  opt.voxel_size = -0.1f;
  auto neg = init_anchors(xyz.data(), 2, opt);
  REQUIRE_FALSE(neg.ok());
  CHECK(neg.status().message().find("voxel_size") != std::string::npos);
  opt.voxel_size = 0.1f;
  opt.k = 0;
  CHECK_FALSE(init_anchors(xyz.data(), 2, opt).ok());
  const std::vector<float> bad = {0, NAN, 0};
  CHECK(count_occupied_voxels(bad.data(), 1, 1.0f).status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("init_anchors: snowmiku_plush SfM points (shared data)") {
  const std::string root = std::string(GS_SOURCE_DIR) + "/../shared/data/snowmiku_plush";
  if (!std::filesystem::exists(root + "/sparse/0")) {
    MESSAGE("skipped: " << root << "/sparse/0 is absent");
    return;
  }
  auto model = gs::io::read_colmap_model(root + "/sparse/0");
  REQUIRE_MESSAGE(model.ok(), model.status().to_string());
  std::vector<float> xyz;
  for (const auto& p : model->points)
    for (double v : p.xyz) xyz.push_back(float(v));
  const size_t n = model->points.size();
  REQUIRE(n > 0);
  for (size_t budget : {size_t(1000), size_t(100000)}) {
    AnchorOptions opt;
    opt.max_anchors = budget;
    auto a = init_anchors(xyz.data(), n, opt);
    REQUIRE_MESSAGE(a.ok(), a.status().to_string());
    CHECK(a->size() <= budget);
    CHECK(a->size() > 0);
    MESSAGE("snowmiku_plush: " << n << " points, budget " << budget << ": eps " << a->voxel_size << ", "
                               << a->size() << " anchors");
  }
}

}  // namespace
}  // namespace gs::model
