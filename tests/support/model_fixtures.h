// SPDX-License-Identifier: MIT
// Fixtures shared by the model tests: SfM-like points on a noisy sphere, small hybrid models with
// random rows, look-at cameras and raw file bytes (for truncating and corrupting model and
// checkpoint files).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <doctest/doctest.h>

#include "gs/camera.h"
#include "gs/model/hybrid_model.h"

namespace gs::test {

// n points [n, 3] on a noisy sphere of radius 2 around centre: surface-like, like SfM points.
inline std::vector<float> sphere_points(size_t n, uint32_t seed, const float centre[3] = nullptr) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<float> xyz(3 * n);
  for (size_t i = 0; i < n; ++i) {
    float v[3] = {g(rng), g(rng), g(rng)};
    const float r = 2.0f * (1.0f + 0.02f * g(rng)) / std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + 1e-12f);
    for (int c = 0; c < 3; ++c) xyz[3 * i + size_t(c)] = (centre ? centre[c] : 0.0f) + v[c] * r;
  }
  return xyz;
}

// A small model configuration for the model file and codec tests: 4 offsets, 8-wide features,
// 12-wide MLPs, 5-wide image features behind a 7-wide hidden layer.
inline model::ModelConfig small_file_test_config(model::ImageFeatureMode mode, size_t max_anchors, size_t max_gaussians) {
  model::ModelConfig c;
  c.k = 4;
  c.feature_dim = 8;
  c.hidden = 12;
  c.image_features = mode;
  c.image_feature_dim = 5;
  c.image_feature_hidden = 7;
  c.max_anchors = max_anchors;
  c.max_gaussians = max_gaussians;
  return c;
}

// create_model on `points` sphere_points (seeded with seed, as is the model); fails the test on error.
inline model::HybridModel sphere_model(const model::ModelConfig& c, size_t points, float scene_extent, uint64_t seed) {
  const std::vector<float> xyz = sphere_points(points, uint32_t(seed));
  Expected<model::HybridModel> m = model::create_model(c, xyz.data(), points, scene_extent, seed);
  REQUIRE_MESSAGE(m.ok(), m.status().to_string());
  return std::move(*m);
}

// Overwrites the live anchor rows with draws g() of one normal distribution, in this order: offsets
// (offset_sigma g), log scales (log_scale_mean + log_scale_sigma g), features (g). g is shared with
// the caller so that further draws continue the same stream.
inline void randomise_anchor_rows(model::HybridModel& m, std::mt19937_64& rng, std::normal_distribution<float>& g,
                                  float offset_sigma, float log_scale_mean, float log_scale_sigma) {
  const size_t M = m.anchor_count;
  for (size_t i = 0; i < M * size_t(m.config.k) * 3; ++i) m.offsets[i] = offset_sigma * g(rng);
  for (size_t i = 0; i < M * 6; ++i) m.log_scales[i] = log_scale_mean + log_scale_sigma * g(rng);
  for (size_t i = 0; i < M * size_t(m.config.feature_dim); ++i) m.features[i] = g(rng);
}

// Camera at centre C looking at `at`, y down roughly along -world y: x = z x up, y = z x x, a
// right-handed frame (x right, y down, z forward); world-to-camera pose.
inline Camera look_at(const double C[3], const double at[3], const PinholeIntrinsics& intr) {
  double z[3] = {at[0] - C[0], at[1] - C[1], at[2] - C[2]};
  const double zn = std::sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  for (double& v : z) v /= zn;
  const double up[3] = {0, -1, 0};
  double x[3] = {z[1] * up[2] - z[2] * up[1], z[2] * up[0] - z[0] * up[2], z[0] * up[1] - z[1] * up[0]};
  const double xn = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (double& v : x) v /= xn;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  Camera cam;
  cam.intr = intr;
  for (int c = 0; c < 3; ++c) {
    cam.pose.R[c] = float(x[c]);
    cam.pose.R[3 + c] = float(y[c]);
    cam.pose.R[6 + c] = float(z[c]);
  }
  for (int r = 0; r < 3; ++r)
    cam.pose.t[r] = float(-(double(cam.pose.R[3 * r]) * C[0] + double(cam.pose.R[3 * r + 1]) * C[1] +
                            double(cam.pose.R[3 * r + 2]) * C[2]));
  return cam;
}

// The registration and tracking tests' object: a squashed ellipsoid and an off-centre ball (a sphere
// alone looks the same from an orbit around it, which no photometric method can disambiguate),
// k = 4, no image features, features and offsets drawn from a seeded normal so the render is
// textured. Fails the test on error.
inline model::HybridModel asymmetric_object_model() {
  std::vector<float> pts = sphere_points(2400, 5);
  for (size_t i = 0; i < pts.size(); i += 3) pts[i + 1] *= 0.6f, pts[i + 2] *= 0.45f;
  const float ball_centre[3] = {1.6f, -0.9f, -0.4f};
  const std::vector<float> ball = sphere_points(600, 6, ball_centre);
  for (size_t i = 0; i < ball.size(); i += 3)
    for (int c = 0; c < 3; ++c) pts.push_back(ball_centre[c] + 0.35f * (ball[i + size_t(c)] - ball_centre[c]));
  model::ModelConfig cfg;
  cfg.k = 4;
  cfg.max_anchors = 3000;
  cfg.max_gaussians = 12000;
  cfg.image_features = model::ImageFeatureMode::kNone;
  Expected<model::HybridModel> m = model::create_model(cfg, pts.data(), pts.size() / 3, 4.0f, 1);
  REQUIRE(m.ok());
  model::HybridModel model = std::move(m).value();
  std::mt19937 rng(2);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (float& f : model.features) f = 2.0f * g(rng);
  for (float& o : model.offsets) o = 0.5f * g(rng);
  return model;
}

inline std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

inline void write_bytes(const std::string& path, const std::vector<uint8_t>& b) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

}  // namespace gs::test
