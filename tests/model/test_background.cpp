// SPDX-License-Identifier: MIT
// Backgrounds and masks (issue 15, object captures): parsing the background option, compositing a
// photo on a background through its mask, and training on masked views of a cloud in front of a
// cluttered background: the model must learn the object alone, so that its renders as rendered
// (on the training background) match the photos composited on that background, with its alpha
// following the mask.
#include <doctest/doctest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "gs/io/composite.h"
#include "gs/model/background.h"
#include "gs/model/evaluate.h"
#include "gs/model/trainer.h"
#include "support/reduced.h"
#include "support/train_scene.h"

namespace gs::model {
namespace {

TEST_CASE("background: black, white, random and r,g,b parse and name back to themselves and bad text is refused") {
  for (const char* text : {"black", "white", "random", "0.5,0.25,1", "0,0,0.125"}) {
    Expected<Background> b = parse_background(text);
    REQUIRE_MESSAGE(b.ok(), text);
    Expected<Background> again = parse_background(background_name(*b));
    REQUIRE(again.ok());
    CHECK(again->random == b->random);
    for (int c = 0; c < 3; ++c) CHECK(again->rgb[c] == b->rgb[c]);
  }
  CHECK(parse_background("white")->rgb[1] == 1.0f);
  CHECK(parse_background("random")->random);
  CHECK(background_name(*parse_background("1,1,1")) == "white");
  for (const char* bad : {"", "grey", "1,1", "1,1,1,1", "0.5,,1", "2,0,0", "-0.1,0,0", "nan,0,0", "0.5x,0,0", "1,1,1,"}) {
    Expected<Background> b = parse_background(bad);
    CHECK_MESSAGE(!b.ok(), bad);
    if (!b.ok()) CHECK(b.status().message().find("black, white, random or r,g,b") != std::string::npos);
  }
}

io::Image8 solid(int w, int h, int channels, uint8_t value) {
  io::Image8 im;
  im.width = w, im.height = h, im.channels = channels;
  im.pixels.assign(size_t(w) * size_t(h) * size_t(channels), value);
  return im;
}

TEST_CASE("composite: without a mask the target is the box mean and with one coverage mixes photo and background") {
  io::Image8 photo = solid(6, 4, 3, 0);
  for (size_t i = 0; i < photo.pixels.size(); ++i) photo.pixels[i] = uint8_t((i * 37) % 256);
  const float bg[3] = {1.0f, 0.5f, 0.25f};
  std::vector<float> plain(6 * 4 * 3), composited(plain.size());
  for (int s : {1, 2}) {
    io::box_downsample_rgb(photo.pixels.data(), 6, 4, s, plain.data());
    io::composite_target(photo, io::Image8{}, s, bg, composited.data());
    for (size_t i = 0; i < size_t(6 / s) * size_t(4 / s) * 3; ++i) CHECK(composited[i] == plain[i]);
    // A full mask is the photo (to float rounding), an empty one the background.
    io::composite_target(photo, solid(6, 4, 1, 255), s, bg, composited.data());
    for (size_t i = 0; i < size_t(6 / s) * size_t(4 / s) * 3; ++i) CHECK(composited[i] == doctest::Approx(plain[i]).epsilon(1e-6));
    io::composite_target(photo, solid(6, 4, 1, 0), s, bg, composited.data());
    for (size_t i = 0; i < size_t(6 / s) * size_t(4 / s) * 3; ++i) CHECK(composited[i] == doctest::Approx(bg[i % 3]).epsilon(1e-6));
  }
  // Half a 2x2 block covered: the mean of the covered photo pixels' share plus half the background.
  io::Image8 mask = solid(6, 4, 1, 0);
  mask.pixels[0] = mask.pixels[1] = 255;  // top row of the first block
  io::composite_target(photo, mask, 2, bg, composited.data());
  for (int c = 0; c < 3; ++c) {
    const double expect = (photo.pixels[size_t(c)] + photo.pixels[3 + size_t(c)]) / (4 * 255.0) + 0.5 * bg[c];
    CHECK(composited[size_t(c)] == doctest::Approx(expect).epsilon(1e-6));
  }
  // 8 bits: a coverage of 128 / 255 mixes 0 and 255 into the rounded value.
  const io::Image8 eight = io::composite_rgb8(solid(2, 1, 3, 0), solid(2, 1, 1, 128), bg);
  CHECK(eight.pixels[0] == uint8_t(std::lround(255.0 * (1 - 128 / 255.0))));
  CHECK(eight.pixels[1] == uint8_t(std::lround(127.5 * (1 - 128 / 255.0))));
  CHECK(io::composite_rgb8(photo, io::Image8{}, bg).pixels == photo.pixels);
}

// Trains 400 iterations on the scene's views (densification off) with the given background and
// evaluates every view on `eval_on` against the masked scene's photos composited on it.
EvalResult train_and_evaluate(const test::TrainScene& train_on, const test::TrainScene& masked, const Background& bg,
                              const float eval_on[3]) {
  std::vector<const Camera*> cams;
  for (const auto& v : train_on.views) cams.push_back(&v.camera);
  Expected<HybridModel> m = create_model(test::small_scene_model_config(), train_on.points.data(), train_on.points.size() / 3, cameras_extent(cams), 1);
  REQUIRE(m.ok());
  TrainOptions o;
  o.iterations = 400;
  o.seed = 3;
  o.stat_start = o.update_from = o.update_until = 1000000;
  o.background = bg;
  Expected<std::unique_ptr<Trainer>> t = Trainer::create(std::move(*m), train_on.ptrs, o, nullptr);
  REQUIRE_MESSAGE(t.ok(), t.status().to_string());
  for (int i = 0; i < o.iterations; ++i) REQUIRE((*t)->step(nullptr).ok());
  EvalOptions eo;
  eo.psnr_only = true;
  for (int c = 0; c < 3; ++c) eo.render.background[c] = eval_on[c];
  Expected<EvalResult> r = evaluate_views((*t)->model(), masked.ptrs, eo, nullptr);
  REQUIRE_MESSAGE(r.ok(), r.status().to_string());
  return *r;
}

// Full size only: three 400-iteration trainings took 95 s under qemu-aarch64. What emulation could
// break here is covered there already: the loss kernels are compared with the reference on each ISA
// (tests/loss) and test_trainer_qemu trains masked views on a random background.
TEST_CASE("trainer: masked views of an object before clutter train to the object alone on a white or random background" *
          GS_FULL_SIZE_ONLY) {
  const test::TrainScene masked(true);
  test::TrainScene unmasked(true);  // the same photos with the masks thrown away
  for (io::DatasetView& v : unmasked.views) v.mask = io::Image8{};
  const float white[3] = {1, 1, 1}, black[3] = {0, 0, 0};
  Background white_bg, random_bg;
  white_bg.rgb[0] = white_bg.rgb[1] = white_bg.rgb[2] = 1;
  random_bg.random = true;

  const EvalResult with_mask = train_and_evaluate(masked, masked, white_bg, white);
  const EvalResult random = train_and_evaluate(masked, masked, random_bg, black);
  const EvalResult without = train_and_evaluate(unmasked, masked, white_bg, white);
  MESSAGE("white, masks: PSNR " << with_mask.psnr << " dB, inside the mask " << with_mask.psnr_masked << " dB, alpha MAE "
                                << with_mask.alpha_mae << ", IoU " << with_mask.alpha_iou);
  MESSAGE("random, masks (evaluated on black): PSNR " << random.psnr << " dB, inside " << random.psnr_masked << " dB, alpha MAE "
                                                      << random.alpha_mae << ", IoU " << random.alpha_iou);
  MESSAGE("white, no masks: PSNR " << without.psnr << " dB, alpha MAE " << without.alpha_mae << ", IoU " << without.alpha_iou);
  REQUIRE(with_mask.views.size() == size_t(test::kSceneViews));
  CHECK(with_mask.psnr_masked > 0);
  // With masks the alpha follows the mask; a model that saw the clutter covers it (opaque almost
  // everywhere), so its alpha disagrees with the mask and its renders with the composite.
  CHECK(with_mask.alpha_iou > 0.9);
  CHECK(random.alpha_iou > 0.9);
  CHECK(with_mask.alpha_mae < 0.5 * without.alpha_mae);
  CHECK(with_mask.psnr > without.psnr + 3);
  CHECK(random.psnr > 20);
  CHECK(with_mask.psnr > 20);
}

}  // namespace
}  // namespace gs::model

namespace gs::model {
namespace {

// Pixels a view has no source for (io::DatasetView::valid: undistortion's outside, written as 0):
// training leaves them out of the loss and evaluation out of its figures. The left and right
// quarters of every view lose their source and go black: trained with the valid maps the model
// matches the clean photos about as well as one trained on them, trained on the black pixels it
// learns black there; and evaluation of one model gives the same figures whatever the missing
// pixels hold.
// Full size only, as the case above (84 s under qemu-aarch64): the valid maps are scalar bookkeeping
// in front of the loss kernels that tests/loss compares on each ISA.
TEST_CASE("trainer and evaluation: pixels without a source are left out, not trained or measured as black" *
          GS_FULL_SIZE_ONLY) {
  const test::TrainScene clean(false);
  test::TrainScene cut(false), black(false);
  for (test::TrainScene* s : {&cut, &black}) {
    for (io::DatasetView& v : s->views) {
      io::Image8 valid = solid(v.image.width, v.image.height, 1, 255);
      for (int y = 0; y < v.image.height; ++y)
        for (int x = 0; x < v.image.width; ++x) {
          if (x >= v.image.width / 4 && x < 3 * v.image.width / 4) continue;
          const size_t p = size_t(y) * size_t(v.image.width) + size_t(x);
          valid.pixels[p] = 0;
          for (size_t c = 0; c < 3; ++c) v.image.pixels[3 * p + c] = 0;
        }
      if (s == &cut) v.valid = std::move(valid);
    }
  }
  const float bg[3] = {0, 0, 0};
  const Background black_bg;
  // Measured on the views' centre halves (the cut views with their valid maps): every model saw
  // those pixels of every view.
  const EvalResult on_clean = train_and_evaluate(clean, cut, black_bg, bg);
  const EvalResult with_valid = train_and_evaluate(cut, cut, black_bg, bg);
  const EvalResult as_black = train_and_evaluate(black, cut, black_bg, bg);
  MESSAGE("PSNR on the views' centre halves: trained on the clean views " << on_clean.psnr << " dB; on the centre halves "
          "with the valid maps " << with_valid.psnr << " dB; with the outer quarters as black " << as_black.psnr << " dB");
  // The views orbit the cloud, so one view's outer quarters see what another's centre sees: trained
  // as black they darken it.
  // Measured: 32.93 (clean), 31.71 (valid maps), 26.56 dB (black).
  CHECK(with_valid.psnr > on_clean.psnr - 2);
  CHECK(as_black.psnr < with_valid.psnr - 3);

  // Evaluation: the same model on views whose missing pixels hold black or the clean photo's
  // values gives the same figures; they are those over the valid pixels only.
  std::vector<const Camera*> cams;
  for (const auto& v : clean.views) cams.push_back(&v.camera);
  Expected<HybridModel> m = create_model(test::small_scene_model_config(), clean.points.data(), clean.points.size() / 3, cameras_extent(cams), 1);
  REQUIRE(m.ok());
  test::TrainScene filled(false);
  for (size_t i = 0; i < filled.views.size(); ++i) filled.views[i].valid = cut.views[i].valid;
  EvalOptions eo;
  Expected<EvalResult> a = evaluate_views(*m, cut.ptrs, eo, nullptr);
  Expected<EvalResult> b = evaluate_views(*m, filled.ptrs, eo, nullptr);
  Expected<EvalResult> whole = evaluate_views(*m, black.ptrs, eo, nullptr);
  REQUIRE(a.ok());
  REQUIRE(b.ok());
  REQUIRE(whole.ok());
  CHECK(a->psnr == b->psnr);
  CHECK(a->ssim == b->ssim);
  CHECK(a->psnr != whole->psnr);
}

}  // namespace
}  // namespace gs::model
