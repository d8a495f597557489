// SPDX-License-Identifier: MIT
// Gaussian initialisation from SfM points and activation of a GaussianCloud for rendering.
#include "gs/scene_init.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "gs/constants.h"

namespace gs {
namespace {

struct Grid {
  float origin[3];
  float cell;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells;
  static uint64_t key(int64_t x, int64_t y, int64_t z) {
    return (uint64_t(x & 0x1FFFFF) << 42) | (uint64_t(y & 0x1FFFFF) << 21) | uint64_t(z & 0x1FFFFF);
  }
  int64_t coord(float v, int axis) const { return int64_t(std::floor((v - origin[axis]) / cell)); }
};

}  // namespace

std::vector<float> mean_knn_distance(const float* xyz, size_t n, int k) {
  std::vector<float> out(n, 1.0f);
  if (n < 2) return out;
  float lo[3] = {xyz[0], xyz[1], xyz[2]}, hi[3] = {xyz[0], xyz[1], xyz[2]};
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], xyz[3 * i + a]), hi[a] = std::max(hi[a], xyz[3 * i + a]);
  // Cell size so that a cell holds ~2 points on average for a surface-like (2D) distribution.
  const float ext = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-6f});
  Grid g;
  std::copy(lo, lo + 3, g.origin);
  g.cell = std::max(ext / std::sqrt(float(n) / 2.0f), ext * 1e-6f);
  for (size_t i = 0; i < n; ++i)
    g.cells[Grid::key(g.coord(xyz[3 * i], 0), g.coord(xyz[3 * i + 1], 1), g.coord(xyz[3 * i + 2], 2))].push_back(uint32_t(i));
  const int kk = int(std::min<size_t>(size_t(k), n - 1));
  std::vector<float> best;
  for (size_t i = 0; i < n; ++i) {
    const float* p = xyz + 3 * i;
    const int64_t c[3] = {g.coord(p[0], 0), g.coord(p[1], 1), g.coord(p[2], 2)};
    // Grow the search shell until the k-th best distance is inside the searched radius (exact).
    for (int64_t r = 1;; ++r) {
      best.clear();
      for (int64_t dz = -r; dz <= r; ++dz)
        for (int64_t dy = -r; dy <= r; ++dy)
          for (int64_t dx = -r; dx <= r; ++dx) {
            auto it = g.cells.find(Grid::key(c[0] + dx, c[1] + dy, c[2] + dz));
            if (it == g.cells.end()) continue;
            for (uint32_t j : it->second) {
              if (j == i) continue;
              const float* q = xyz + 3 * j;
              best.push_back(std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                                       (p[2] - q[2]) * (p[2] - q[2])));
            }
          }
      if (int(best.size()) >= kk) {
        std::partial_sort(best.begin(), best.begin() + kk, best.end());
        if (best[kk - 1] <= float(r) * g.cell || (2 * r + 1) * g.cell > 4 * ext) {
          float s = 0;
          for (int j = 0; j < kk; ++j) s += best[j];
          out[i] = s / float(kk);
          break;
        }
      }
      if ((2 * r + 1) * g.cell > 4 * ext) break;  // every point searched (duplicates only)
    }
  }
  return out;
}

GaussianCloud gaussians_from_points(const float* xyz, const uint8_t* rgb, size_t n, float opacity) {
  GaussianCloud c;
  c.sh_degree = 0;
  c.resize(n);
  const std::vector<float> d = mean_knn_distance(xyz, n, 3);
  const float logit = std::log(opacity / (1.0f - opacity));
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      c.means[3 * i + a] = xyz[3 * i + a];
      c.log_scales[3 * i + a] = std::log(std::max(d[i], 1e-7f));
      c.sh[3 * i + a] = (float(rgb[3 * i + a]) / 255.0f - 0.5f) / float(kShC0);
    }
    c.quats[4 * i] = 1.0f;
    c.quats[4 * i + 1] = c.quats[4 * i + 2] = c.quats[4 * i + 3] = 0.0f;
    c.opacity_logits[i] = logit;
  }
  return c;
}

GaussianParams activate(const GaussianCloud& cloud, std::vector<float>* opacity_storage) {
  const size_t n = cloud.size();
  opacity_storage->resize(n);
  for (size_t i = 0; i < n; ++i) (*opacity_storage)[i] = 1.0f / (1.0f + std::exp(-cloud.opacity_logits[i]));
  GaussianParams p;
  p.count = n;
  p.means = cloud.means.data();
  p.log_scales = cloud.log_scales.data();
  p.quats = cloud.quats.data();
  p.opacities = opacity_storage->data();
  p.sh = cloud.sh.data();
  p.sh_degree = cloud.sh_degree;
  return p;
}

}  // namespace gs
