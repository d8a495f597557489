// SPDX-License-Identifier: MIT
// Private to gs_model: plain 3D Gaussians (a GaussianCloud: a baked model, or a 3DGS scene read from
// a PLY, .splat or .spz file) seen from a camera the way the anchor model's decode is: the Gaussians
// that can reach the (possibly widened) image, with activated opacities and their SH colours
// evaluated for the camera centre, in buffers the renderer takes. The model renderer, evaluation and
// registration use it where they would decode anchors. decode() allocates nothing after reserve().
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/model/decode.h"
#include "gs/render.h"
#include "gs/simd/ref.h"

namespace gs::model::detail {

class CloudDecoder {
 public:
  void reserve(size_t n, int sh_degree) {
    const size_t K = size_t(sh_coeff_count(sh_degree));
    g_ = ColoredGaussians{};
    g_.resize(n);
    sh_.assign(n * K * 3, 0.0f);
    capacity_ = n;
  }
  size_t capacity() const { return capacity_; }

  // Selects the Gaussians whose 3-sigma sphere (largest axis) lies in front of the near plane and
  // touches the image of cam, as select_visible_anchors does for anchors; returns their count.
  size_t decode(const GaussianCloud& c, const Camera& cam) {
    const size_t N = std::min(c.size(), capacity_);
    const int K = sh_coeff_count(c.sh_degree);
    const float* R = cam.pose.R;
    const float* t = cam.pose.t;
    const double fmax = std::max(cam.intr.fx, cam.intr.fy);
    size_t n = 0;
    for (size_t i = 0; i < N; ++i) {
      const float* p = &c.means[3 * i];
      const double x = R[0] * double(p[0]) + R[1] * double(p[1]) + R[2] * double(p[2]) + t[0];
      const double y = R[3] * double(p[0]) + R[4] * double(p[1]) + R[5] * double(p[2]) + t[1];
      const double z = R[6] * double(p[0]) + R[7] * double(p[1]) + R[8] * double(p[2]) + t[2];
      if (!(z > 0.2)) continue;
      const float* ls = &c.log_scales[3 * i];
      const double r = 3.0 * std::exp(double(std::max(ls[0], std::max(ls[1], ls[2])))) * fmax / z + 1.0;  // px
      const double u = cam.intr.fx * x / z + cam.intr.cx, v = cam.intr.fy * y / z + cam.intr.cy;
      if (u + r < 0 || u - r > cam.intr.width || v + r < 0 || v - r > cam.intr.height) continue;
      std::copy(p, p + 3, &g_.means[3 * n]);
      std::copy(ls, ls + 3, &g_.log_scales[3 * n]);
      std::copy(&c.quats[4 * i], &c.quats[4 * i] + 4, &g_.quats[4 * n]);
      g_.opacities[n] = 1.0f / (1.0f + std::exp(-c.opacity_logits[i]));
      std::copy(&c.sh[i * size_t(K) * 3], &c.sh[(i + 1) * size_t(K) * 3], &sh_[n * size_t(K) * 3]);
      ++n;
    }
    double centre[3];
    camera_centre(cam.pose, centre);
    const float campos[3] = {float(centre[0]), float(centre[1]), float(centre[2])};
    simd::sh_fwd_ref<float>(n, c.sh_degree, g_.means.data(), sh_.data(), campos, g_.colors.data());
    count_ = n;
    return n;
  }

  // The last decode's Gaussians with their colours (SH evaluated for its camera).
  GaussianParams params() const { return g_.params(count_); }
  uint64_t bytes() const {
    return uint64_t(g_.means.size() + g_.log_scales.size() + g_.quats.size() + g_.opacities.size() + g_.colors.size() +
                    sh_.size()) * 4;
  }

 private:
  ColoredGaussians g_;  // capacity_ rows, the first count_ decoded
  std::vector<float> sh_;
  size_t capacity_ = 0, count_ = 0;
};

// Renderer capacity for rendering up to n plain Gaussians at max_width x max_height (16 tile pairs
// per Gaussian before a re-plan, as the PLY render job plans).
inline RenderCapacity cloud_render_capacity(size_t n, int max_width, int max_height) {
  RenderCapacity rc;
  rc.max_gaussians = std::max<size_t>(n, 1);
  rc.max_isects = rc.max_gaussians * 16;
  rc.max_width = max_width;
  rc.max_height = max_height;
  rc.max_sh_degree = 0;  // colours are evaluated by the decoder
  return rc;
}

}  // namespace gs::model::detail
