// SPDX-License-Identifier: MIT
// Baking the anchor model into plain Gaussians (gs/model/bake.h) and using plain Gaussians where a
// model is used (ModelRenderer, evaluate_views, Registrar): on the generated 8-view scene, a model
// trained briefly is baked at SH degrees 0 and 3; the fit reproduces the model's renders, the
// distillation improves on it, the cloud renders the same through the model renderer as through the
// renderer's own SH path, and registration against the cloud recovers a perturbed pose as well as
// registration against the model does.
#include <doctest/doctest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "gs/model/bake.h"
#include "gs/model/evaluate.h"
#include "gs/model/model_renderer.h"
#include "gs/model/trainer.h"
#include "gs/pose/pose.h"
#include "gs/model/register.h"
#include "gs/render.h"
#include "gs/scene_init.h"
#include "support/alloc_counter.h"
#include "support/train_scene.h"

namespace gs::model {
namespace {

const test::TrainScene& scene() {
  static const test::TrainScene s;
  return s;
}

// The model as created on the scene's points, untrained.
HybridModel untrained() {
  std::vector<const Camera*> cams;
  for (const auto& v : scene().views) cams.push_back(&v.camera);
  Expected<HybridModel> m = create_model(test::small_scene_model_config(), scene().points.data(), scene().points.size() / 3,
                                         cameras_extent(cams), 1);
  REQUIRE(m.ok());
  return std::move(m).value();
}

// A model trained 300 iterations on the scene (no densification), made once.
const HybridModel& trained() {
  static const HybridModel m = [] {
    TrainOptions o;
    o.iterations = 300;
    o.seed = 2;
    o.stat_start = o.update_from = o.update_until = 1000000;
    Expected<std::unique_ptr<Trainer>> t = Trainer::create(untrained(), scene().ptrs, o, nullptr);
    REQUIRE(t.ok());
    for (int i = 0; i < o.iterations; ++i) REQUIRE((*t)->step(nullptr).ok());
    return (*t)->model();
  }();
  return m;
}

std::vector<Camera> cameras() {
  std::vector<Camera> out;
  for (const auto& v : scene().views) out.push_back(v.camera);
  return out;
}

TEST_CASE("bake: the fit reproduces the model's renders, distillation improves it, and degree 3 is not worse than 0") {
  BakeOptions o;
  BakeStats s0, s3, sd;
  o.sh_degree = 0;
  Expected<GaussianCloud> c0 = bake_model(trained(), cameras(), o, nullptr, &s0);
  REQUIRE_MESSAGE(c0.ok(), c0.status().to_string());
  o.sh_degree = 3;
  Expected<GaussianCloud> c3 = bake_model(trained(), cameras(), o, nullptr, &s3);
  REQUIRE(c3.ok());
  o.distill_iterations = 200;
  Expected<GaussianCloud> cd = bake_model(trained(), cameras(), o, nullptr, &sd);
  REQUIRE(cd.ok());
  MESSAGE("candidates " << s3.candidates << ", seen " << s3.seen << ", kept " << s3.kept << "; PSNR against the model's renders: SH0 "
                        << s0.psnr_fit << " dB, SH3 " << s3.psnr_fit << " dB, SH3 + 200 distillation steps " << sd.psnr_distilled
                        << " dB (" << sd.distill_seconds << " s)");
  CHECK(c3->sh_degree == 3);
  CHECK(c3->sh.size() == c3->size() * 16 * 3);
  CHECK(c0->sh.size() == c0->size() * 3);
  CHECK(s3.kept > 0);
  CHECK(s3.kept <= s3.seen);
  CHECK(s3.seen <= s3.candidates);
  CHECK(s0.psnr_fit > 22);
  CHECK(s3.psnr_fit >= s0.psnr_fit - 0.1);
  CHECK(sd.psnr_distilled > s3.psnr_fit + 0.5);
  for (float v : cd->means) CHECK(std::isfinite(v));
  // The same bake twice is the same cloud (the distillation's camera order is seeded).
  Expected<GaussianCloud> again = bake_model(trained(), cameras(), o, nullptr);
  REQUIRE(again.ok());
  CHECK(again->means == cd->means);
  CHECK(again->sh == cd->sh);
}

TEST_CASE("bake: bad options and inputs are refused with a message") {
  // Refusing bad input needs no trained model, and training one took 20-35 s of this case under qemu.
  const HybridModel m = untrained();
  BakeOptions o;
  CHECK(bake_model(m, {}, o, nullptr).status().message().find("no cameras") != std::string::npos);
  o.sh_degree = 4;
  CHECK(bake_model(m, cameras(), o, nullptr).status().message().find("sh_degree") != std::string::npos);
  o = BakeOptions{};
  o.min_opacity = 1.0f;
  CHECK_FALSE(bake_model(m, cameras(), o, nullptr).ok());
  std::vector<Camera> bad = cameras();
  bad[0].intr.fx = -1;
  CHECK_FALSE(bake_model(m, bad, BakeOptions{}, nullptr).ok());
}

TEST_CASE("model renderer: a cloud renders as the renderer's own SH path renders it, and evaluation takes clouds") {
  BakeOptions o;
  o.sh_degree = 2;
  Expected<GaussianCloud> cloud = bake_model(trained(), cameras(), o, nullptr);
  REQUIRE(cloud.ok());
  ModelRenderer mr;
  REQUIRE(mr.init(*cloud, test::kSceneW, test::kSceneH, nullptr).ok());
  Renderer direct;
  RenderCapacity cap;
  cap.max_gaussians = cloud->size();
  cap.max_isects = 64 * cloud->size();
  cap.max_width = test::kSceneW;
  cap.max_height = test::kSceneH;
  cap.max_sh_degree = 2;
  REQUIRE(direct.init(cap, nullptr).ok());
  std::vector<float> opacity;
  const GaussianParams gp = activate(*cloud, &opacity);
  std::vector<float> a(size_t(test::kSceneW) * test::kSceneH * 3), b(a.size());
  double worst = 0;
  for (const auto& v : scene().views) {
    size_t n = 0;
    REQUIRE(mr.render(*cloud, v.camera, a.data(), &n).ok());
    REQUIRE(direct.forward(v.camera, gp, RenderOptions{}, b.data()).ok());
    CHECK(n > 0);
    for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, double(std::fabs(a[i] - b[i])));
  }
  MESSAGE("largest difference " << worst);
  CHECK(worst < 1e-4);
  // Rendering the cloud again allocates nothing.
  test::AllocationScope scope;
  REQUIRE(mr.render(*cloud, scene().views[1].camera, a.data()).ok());
  CHECK(scope.count() == 0);
  Expected<EvalResult> model_eval = evaluate_views(trained(), scene().ptrs, EvalOptions{}, nullptr);
  Expected<EvalResult> cloud_eval = evaluate_views(*cloud, scene().ptrs, EvalOptions{}, nullptr);
  REQUIRE(model_eval.ok());
  REQUIRE(cloud_eval.ok());
  MESSAGE("PSNR against the images: model " << model_eval->psnr << " dB, baked SH2 " << cloud_eval->psnr << " dB");
  CHECK(cloud_eval->psnr > model_eval->psnr - 3);
}

TEST_CASE("registration: a perturbed pose is recovered against a baked cloud, allocation-free after set-up") {
  BakeOptions o;
  o.distill_iterations = 100;
  Expected<GaussianCloud> cloud = bake_model(trained(), cameras(), o, nullptr);
  REQUIRE(cloud.ok());
  pose::RegisterOptions ro;
  Expected<std::unique_ptr<pose::Registrar>> reg =
      pose::Registrar::create(*cloud, trained().scene_extent, test::kSceneW, test::kSceneH, ro, nullptr);
  REQUIRE_MESSAGE(reg.ok(), reg.status().to_string());
  const io::DatasetView& v = scene().views[2];
  Pose start = v.camera.pose;
  const double xi[6] = {0.02, -0.01, 0.015, 0.03, -0.02, 0.02};  // about 2.3 degrees and 3 % of the radius
  pose::apply_left_twist(xi, &start);
  pose::RegisterResult r;
  REQUIRE((*reg)->register_view(v.image.pixels.data(), v.camera.intr, start, &r).ok());  // warm-up
  test::AllocationScope scope;
  REQUIRE((*reg)->register_view(v.image.pixels.data(), v.camera.intr, start, &r).ok());
  CHECK(scope.count() == 0);
  const double before = pose::rotation_error_deg(start, v.camera.pose), after = pose::rotation_error_deg(r.pose, v.camera.pose);
  Expected<std::unique_ptr<pose::Registrar>> model_reg = pose::Registrar::create(trained(), test::kSceneW, test::kSceneH, ro, nullptr);
  REQUIRE(model_reg.ok());
  pose::RegisterResult rm;
  REQUIRE((*model_reg)->register_view(v.image.pixels.data(), v.camera.intr, start, &rm).ok());
  MESSAGE("rotation error " << before << " -> " << after << " degrees against the cloud (verdict "
                            << std::string(pose::verdict_name(r.verdict)) << "), "
                            << pose::rotation_error_deg(rm.pose, v.camera.pose) << " against the model");
  // On 64 x 48 views of a 300-iteration model registration itself is weak, and where it ends depends
  // on the build's rounding (the model ends 0.82 degrees off in the release build, 1.73 under
  // ASan+UBSan, which optimises and vectorises differently and so trains a slightly different
  // model): the cloud must improve the start and do as well as the model it was baked from.
  CHECK(after < before);
  CHECK(after < 1.5 * pose::rotation_error_deg(rm.pose, v.camera.pose) + 0.1);
  CHECK(r.converged());
}

}  // namespace
}  // namespace gs::model
