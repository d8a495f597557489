// SPDX-License-Identifier: MIT
// Helpers for the splat format tests (test_splat_formats.cpp, splat_transform_interop.cpp): a
// seeded test cloud in front of a camera, rendering a cloud with gs::Renderer, PSNR, and the
// per-field error measures the quantisation bounds are stated in.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/metrics/image_metrics.h"
#include "gs/render.h"
#include "gs/scene_init.h"

namespace gs::io::test {

constexpr double kShC0 = 0.28209479177387814;

// n splats in a 4 x 3 x 3 box 3.5 to 6.5 units in front of splat_test_camera(): log scales for
// 0.015-0.15 units, random rotations, opacities 0.05-0.95, colours 0.05-0.95 and SH rest
// coefficients N(0, 0.15) clamped to +-0.9 (trained 3DGS scenes keep them well inside +-1).
inline GaussianCloud make_test_cloud(size_t n, int sh_degree, uint32_t seed) {
  GaussianCloud c;
  c.sh_degree = sh_degree;
  c.resize(n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const size_t K = size_t(sh_coeff_count(sh_degree));
  for (size_t i = 0; i < n; ++i) {
    c.means[3 * i + 0] = -2.0f + 4.0f * u(rng);
    c.means[3 * i + 1] = -1.5f + 3.0f * u(rng);
    c.means[3 * i + 2] = 3.5f + 3.0f * u(rng);
    for (int k = 0; k < 3; ++k) c.log_scales[3 * i + size_t(k)] = std::log(0.015f + 0.135f * u(rng));
    for (int k = 0; k < 4; ++k) c.quats[4 * i + size_t(k)] = g(rng);
    const float alpha = 0.05f + 0.9f * u(rng);
    c.opacity_logits[i] = std::log(alpha / (1.0f - alpha));
    for (int k = 0; k < 3; ++k) c.sh[i * K * 3 + size_t(k)] = float(((0.05 + 0.9 * u(rng)) - 0.5) / kShC0);
    for (size_t k = 3; k < K * 3; ++k) c.sh[i * K * 3 + k] = std::clamp(0.15f * g(rng), -0.9f, 0.9f);
  }
  return c;
}

// 160 x 120 pinhole at the origin looking down +z (the test cloud fills most of the view).
inline Camera splat_test_camera() {
  Camera cam;
  cam.intr.width = 160;
  cam.intr.height = 120;
  cam.intr.fx = cam.intr.fy = 150.0f;
  cam.intr.cx = 80.0f;
  cam.intr.cy = 60.0f;
  return cam;
}

// The cloud rendered from the camera, [H, W, 3]; empty on failure.
inline std::vector<float> render_cloud(const GaussianCloud& cloud, const Camera& cam) {
  std::vector<float> opacity;
  const GaussianParams params = activate(cloud, &opacity);
  RenderCapacity cap;
  cap.max_gaussians = std::max<size_t>(cloud.size(), 1);
  cap.max_isects = cloud.size() * 300 + 1024;
  cap.max_width = cam.intr.width;
  cap.max_height = cam.intr.height;
  cap.max_sh_degree = cloud.sh_degree;
  Renderer renderer;
  if (!renderer.init(cap, nullptr).ok()) return {};
  std::vector<float> rgb(size_t(cam.intr.width) * size_t(cam.intr.height) * 3);
  if (!renderer.forward(cam, params, RenderOptions{}, rgb.data()).ok()) return {};
  return rgb;
}

// PSNR in dB of two images with values clamped to [0, 1] (gs::metrics::psnr_f32: +inf when
// identical); -1 when the sizes differ or they are empty.
inline double psnr(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size() || a.empty()) return -1;
  std::vector<float> ca(a.size()), cb(b.size());
  for (size_t i = 0; i < a.size(); ++i) ca[i] = std::clamp(a[i], 0.0f, 1.0f), cb[i] = std::clamp(b[i], 0.0f, 1.0f);
  return metrics::psnr_f32(ca.data(), cb.data(), ca.size());
}

inline double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// Rotation angle in degrees between the rotations of two (w, x, y, z) quaternions of any norm.
inline double rotation_angle_deg(const float* a, const float* b) {
  double na = 0, nb = 0, dot = 0;
  for (int k = 0; k < 4; ++k) na += double(a[k]) * a[k], nb += double(b[k]) * b[k], dot += double(a[k]) * b[k];
  const double c = std::min(1.0, std::fabs(dot) / std::sqrt(na * nb));
  return 2.0 * std::acos(c) * 180.0 / M_PI;
}

}  // namespace gs::io::test
