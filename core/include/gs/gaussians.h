// SPDX-License-Identifier: MIT
// GaussianCloud: an owning, structure-of-arrays set of 3D Gaussians (the 3DGS parameterisation),
// used by IO (PLY) and by callers of the renderer. The renderer itself only sees raw pointers.
#pragma once

#include <cstddef>
#include <vector>

namespace gs {

// Number of SH coefficients per colour channel for a degree (0..3): (d+1)^2.
constexpr int sh_coeff_count(int degree) { return (degree + 1) * (degree + 1); }

struct GaussianCloud {
  int sh_degree = 0;                  // 0..3
  std::vector<float> means;           // [N, 3] world units
  std::vector<float> log_scales;      // [N, 3] natural log of the per-axis standard deviation
  std::vector<float> quats;           // [N, 4] (w, x, y, z), not necessarily normalised
  std::vector<float> opacity_logits;  // [N] opacity = sigmoid(logit)
  std::vector<float> sh;              // [N, K, 3], K = sh_coeff_count(sh_degree); coefficient-major, RGB last

  size_t size() const { return opacity_logits.size(); }
  void resize(size_t n) {
    means.resize(n * 3);
    log_scales.resize(n * 3);
    quats.resize(n * 4);
    opacity_logits.resize(n);
    sh.resize(n * size_t(sh_coeff_count(sh_degree)) * 3);
  }
};

}  // namespace gs
