// SPDX-License-Identifier: MIT
// A small generated training dataset for the model tests: 8 views of 64 x 48 around a random cloud of
// coloured Gaussians rendered with gs::Renderer, and SfM-like points sampled from its means.
// Masked variant (object captures): each view's mask is the cloud's rendered coverage (alpha) and
// its photo shows the cloud in front of a cluttered checkerboard, so only the mask tells the
// object from the background.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/model/hybrid_model.h"
#include "gs/render.h"
#include "support/model_fixtures.h"

namespace gs::test {

constexpr int kSceneW = 64, kSceneH = 48, kSceneViews = 8;

struct TrainScene {
  std::vector<io::DatasetView> views;
  std::vector<const io::DatasetView*> ptrs;
  std::vector<float> points;

  explicit TrainScene(bool masked = false) {
    std::mt19937_64 rng(2024);
    std::uniform_real_distribution<float> u(-1, 1), u01(0, 1);
    std::normal_distribution<float> nrm(0, 1);
    const size_t n = 500;
    ColoredGaussians g;
    g.resize(n);
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) g.means[3 * i + size_t(c)] = 1.1f * u(rng);
      for (int c = 0; c < 3; ++c) g.log_scales[3 * i + size_t(c)] = std::log(0.06f + 0.12f * u01(rng));
      for (int c = 0; c < 4; ++c) g.quats[4 * i + size_t(c)] = nrm(rng);
      g.opacities[i] = 0.5f + 0.45f * u01(rng);
      // Colour varies smoothly in space plus noise, so that neighbouring anchors can share features.
      for (int c = 0; c < 3; ++c)
        g.colors[3 * i + size_t(c)] = std::clamp(0.5f + 0.4f * g.means[3 * i + size_t(c)] + 0.15f * u(rng), 0.0f, 1.0f);
    }
    Renderer r;
    RenderCapacity cap;
    cap.max_gaussians = n;
    cap.max_width = kSceneW;
    cap.max_height = kSceneH;
    cap.max_sh_degree = 0;
    REQUIRE(r.init(cap, nullptr).ok());
    const GaussianParams gp = g.params();
    std::vector<float> rgb(size_t(kSceneW) * kSceneH * 3);
    views.resize(kSceneViews);
    const PinholeIntrinsics intr{58, 58, 0.5f * kSceneW + 0.7f, 0.5f * kSceneH - 0.4f, kSceneW, kSceneH};
    for (int v = 0; v < kSceneViews; ++v) {
      const double a = 2 * 3.14159265358979323846 * v / kSceneViews;
      const double C[3] = {4.2 * std::sin(a), -1.0 - 0.5 * std::cos(3 * a), -4.2 * std::cos(a)};
      const double at[3] = {0.1 * std::cos(a), 0, 0.1 * std::sin(a)};
      io::DatasetView& dv = views[size_t(v)];
      dv.name = "view_" + std::to_string(v) + ".png";
      dv.image_id = uint32_t(v + 1);
      dv.camera = look_at(C, at, intr);
      REQUIRE(r.forward(dv.camera, gp, RenderOptions{}, rgb.data()).ok());
      if (masked) {
        // Photo = cloud + transmittance x clutter (a 4 px checkerboard of two colours); mask = alpha.
        const float* T = r.final_transmittance();
        dv.mask.width = kSceneW;
        dv.mask.height = kSceneH;
        dv.mask.channels = 1;
        dv.mask.pixels.resize(size_t(kSceneW) * kSceneH);
        for (int y = 0; y < kSceneH; ++y)
          for (int x = 0; x < kSceneW; ++x) {
            const size_t p = size_t(y) * kSceneW + size_t(x);
            const bool odd = ((x / 4) + (y / 4) + v) % 2 != 0;
            const float clutter[3] = {odd ? 0.9f : 0.2f, odd ? 0.3f : 0.7f, odd ? 0.1f : 0.8f};
            for (int c = 0; c < 3; ++c) rgb[3 * p + size_t(c)] += T[p] * clutter[c];
            dv.mask.pixels[p] = uint8_t(std::lround(255.0 * (1.0 - double(T[p]))));
          }
      }
      dv.image = io::image_from_float_rgb(rgb.data(), kSceneW, kSceneH);
    }
    for (auto& v : views) ptrs.push_back(&v);
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) points.push_back(g.means[3 * i + size_t(c)] + 0.01f * nrm(rng));
  }
};

// A small model for this scene (4 offsets, 16-wide features and MLPs, no image features, at most
// 400 anchors): quick to train in tests.
inline model::ModelConfig small_scene_model_config() {
  model::ModelConfig c;
  c.k = 4;
  c.feature_dim = 16;
  c.hidden = 16;
  c.image_features = model::ImageFeatureMode::kNone;
  c.max_anchors = 400;
  c.max_gaussians = 4000;
  return c;
}

}  // namespace gs::test
