// SPDX-License-Identifier: MIT
// The decoder workspace planned for the views (visible anchors, kept Gaussians) instead of every
// row: a view that needs more than the plan grows it and renders exactly as a full plan does; and
// stage times lent to the model renderer (bench_fixed_point --profile).
#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <vector>

#include "gs/model/decode.h"
#include "gs/model/model_renderer.h"
#include "gs/platform/thread_pool.h"
#include "gs/stage_times.h"
#include "support/model_fixtures.h"

using namespace gs;
using namespace gs::model;

namespace {

HybridModel scene_model() {
  HybridModel model = test::sphere_model(test::small_file_test_config(ImageFeatureMode::kPaper, 400, 1600), 3000, 3.0f, 7);
  std::mt19937_64 rng(7);
  std::normal_distribution<float> g(0.0f, 1.0f);
  test::randomise_anchor_rows(model, rng, g, 0.3f * model.voxel_size, -3.0f, 0.5f);
  for (size_t r = 0; r < model.anchor_count; ++r)
    for (int ch = 0; ch < kImageRawDim; ++ch) model.image_raw[r * kImageRawDim + size_t(ch)] = ch + 1 < kImageRawDim ? 0.5f : 1.0f;
  return model;
}

Camera camera_at(double distance) {
  const double C[3] = {distance, 0.5, 0.0}, at[3] = {0, 0, 0};
  return test::look_at(C, at, PinholeIntrinsics{60, 60, 32, 24, 64, 48});
}

}  // namespace

TEST_CASE("workspace plan: a view beyond the planned visible anchors grows the plan and renders as a full plan") {
  const HybridModel m = scene_model();
  const Camera close = camera_at(1.2), wide = camera_at(8.0);  // the close view sees a part of the sphere
  const std::vector<Camera> plan_views = {close};
  ModelRenderer full, planned;
  REQUIRE(full.init(m, 64, 48, nullptr).ok());
  REQUIRE(planned.init(m, 64, 48, nullptr, nullptr, &plan_views).ok());
  std::vector<float> a(64 * 48 * 3), b(a.size());
  size_t na = 0, nb = 0;
  for (const Camera* cam : {&close, &wide, &close}) {
    REQUIRE(full.render(m, *cam, a.data(), &na).ok());
    REQUIRE(planned.render(m, *cam, b.data(), &nb).ok());
    CHECK(na == nb);
    CHECK(na > 0);
    CHECK(a == b);  // bit-identical
  }
  AnchorParams<float> anchors;
  anchors.count = m.anchor_count;
  anchors.positions = m.positions.data();
  anchors.log_scales = m.log_scales.data();
  anchors.k = m.config.k;
  const size_t seen_close = select_visible_anchors(close, anchors, static_cast<uint32_t*>(nullptr));
  const size_t seen_wide = select_visible_anchors(wide, anchors, static_cast<uint32_t*>(nullptr));
  MESSAGE("visible anchors: close " << seen_close << ", wide " << seen_wide << " of " << m.anchor_count);
  CHECK(seen_close < seen_wide);  // the wide view really overflowed the plan
}

TEST_CASE("model renderer: stage times lent to it time the decode and renderer stages and change no pixel") {
  const HybridModel m = scene_model();
  const Camera cam = camera_at(3.0);
  platform::ThreadPool pool(2);
  ModelRenderer plain, profiled;
  REQUIRE(plain.init(m, 64, 48, &pool).ok());
  REQUIRE(profiled.init(m, 64, 48, &pool).ok());
  StageTimes times;
  profiled.set_stage_times(&times);
  std::vector<float> a(64 * 48 * 3), b(a.size());
  for (int rep = 0; rep < 2; ++rep) {
    REQUIRE(plain.render(m, cam, a.data()).ok());
    REQUIRE(profiled.render(m, cam, b.data()).ok());
    CHECK(a == b);  // bit-identical
  }
  // Every forward stage of a render ran and was timed; the training-only stages were not.
  for (int s : {kStageAnchorSelect, kStageImageMlpFwd, kStageDecoderInput, kStageDecoderMlpFwd, kStageDecodeFwd, kStageProject,
                kStageBin, kStageRasterFwd})
    CHECK_MESSAGE(times.ns[s] > 0, stage_name(s));
  for (int s : {kStageLoss, kStageRasterBwd, kStageMlpBwd, kStageAdam}) CHECK_MESSAGE(times.ns[s] == 0, stage_name(s));
  CHECK(times.projected > 0);
  CHECK(times.pixels == uint64_t(2 * 64 * 48));
  // Lent no longer: a later render adds nothing.
  profiled.set_stage_times(nullptr);
  const StageTimes before = times;
  REQUIRE(profiled.render(m, cam, b.data()).ok());
  CHECK(times.ns[kStageProject] == before.ns[kStageProject]);
  CHECK(times.pixels == before.pixels);
}
