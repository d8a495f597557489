// SPDX-License-Identifier: MIT
// Anchor initialisation: voxelisation by sort (deterministic, no hashing order), auto voxel size, exact 3-NN scales.
#include "gs/model/anchors.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>

#include "gs/scene_init.h"

namespace gs::model {
namespace {

using Key = std::array<int64_t, 3>;

// Voxel keys floor(p / eps) [n]; double division so large coordinates / small eps stay exact enough.
Status voxel_keys(const float* xyz, size_t n, float eps, std::vector<Key>* keys) {
  if (n == 0 || xyz == nullptr) return invalid_argument("anchors: empty point set");
  if (!(eps > 0.0f) || !std::isfinite(eps))
    return invalid_argument("anchors: voxel size must be finite and > 0, got " + std::to_string(eps));
  keys->resize(n);
  constexpr double kLimit = 4.0e18;  // below 2^62: the key stays representable in int64
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const float v = xyz[3 * i + a];
      if (!std::isfinite(v)) return invalid_argument("anchors: point " + std::to_string(i) + " is not finite");
      const double g = std::floor(double(v) / double(eps));
      if (std::fabs(g) > kLimit)
        return invalid_argument("anchors: voxel size " + std::to_string(eps) + " is too small for point " +
                                std::to_string(i));
      (*keys)[i][a] = int64_t(g);
    }
  }
  return Status::Ok();
}

// Point indices sorted by (voxel key, index): equal keys are contiguous, lowest index first.
std::vector<size_t> sorted_order(const std::vector<Key>& keys) {
  std::vector<size_t> order(keys.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });
  return order;
}

double sq_dist(const float* p, const float* q) {
  const double dx = double(p[0]) - q[0], dy = double(p[1]) - q[1], dz = double(p[2]) - q[2];
  return dx * dx + dy * dy + dz * dz;
}

}  // namespace

Expected<size_t> count_occupied_voxels(const float* xyz, size_t n, float eps) {
  std::vector<Key> keys;
  GS_RETURN_IF_ERROR(voxel_keys(xyz, n, eps, &keys));
  std::sort(keys.begin(), keys.end());
  return size_t(std::unique(keys.begin(), keys.end()) - keys.begin());
}

Expected<float> choose_voxel_size(const float* xyz, size_t n, size_t max_anchors) {
  if (n == 0 || xyz == nullptr) return invalid_argument("anchors: empty point set");
  if (max_anchors == 0) return invalid_argument("anchors: max_anchors must be >= 1");
  float lo[3] = {xyz[0], xyz[1], xyz[2]}, hi[3] = {xyz[0], xyz[1], xyz[2]};
  float max_abs = 0.0f;
  for (size_t i = 0; i < 3 * n; ++i) {
    if (!std::isfinite(xyz[i])) return invalid_argument("anchors: point " + std::to_string(i / 3) + " is not finite");
    lo[i % 3] = std::min(lo[i % 3], xyz[i]), hi[i % 3] = std::max(hi[i % 3], xyz[i]);
    max_abs = std::max(max_abs, std::fabs(xyz[i]));
  }
  const float extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  // Start: median of the per-point mean 3-NN distance (world units); duplicates-only or n == 1
  // scenes have no spacing, so fall back to a fraction of the extent, or 1.
  float eps = 0.0f;
  if (n > 1) {
    std::vector<float> d = gs::mean_knn_distance(xyz, n, 3);
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    eps = d[d.size() / 2];
  }
  if (!(eps > 0.0f)) eps = extent > 0.0f ? extent * 1e-3f : 1.0f;
  // Past 2 * max|coordinate| every floor(p / eps) is -1 or 0: the count cannot drop further.
  const float stop = std::max(2.0f * max_abs, eps);
  for (;;) {
    Expected<size_t> count = count_occupied_voxels(xyz, n, eps);
    if (!count.ok()) return count.status();
    if (*count <= max_anchors) return eps;
    if (eps > stop)
      return capacity_exceeded("anchors: " + std::to_string(*count) + " voxels at any voxel size, budget " +
                               std::to_string(max_anchors));
    eps *= 1.25f;
  }
}

Expected<std::vector<size_t>> voxelise(const float* xyz, size_t n, float eps) {
  std::vector<Key> keys;
  GS_RETURN_IF_ERROR(voxel_keys(xyz, n, eps, &keys));
  const std::vector<size_t> order = sorted_order(keys);
  std::vector<size_t> anchors;
  for (size_t b = 0; b < n;) {
    size_t e = b + 1;
    while (e < n && keys[order[e]] == keys[order[b]]) ++e;
    double c[3] = {0, 0, 0};  // centroid in double: voxels can hold many points
    for (size_t j = b; j < e; ++j)
      for (int a = 0; a < 3; ++a) c[a] += xyz[3 * order[j] + a];
    for (double& v : c) v /= double(e - b);
    size_t best = order[b];
    double best_d = INFINITY;
    for (size_t j = b; j < e; ++j) {  // indices ascend within a voxel, so strict < keeps the lowest on ties
      const float* p = xyz + 3 * order[j];
      const double dx = p[0] - c[0], dy = p[1] - c[1], dz = p[2] - c[2];
      const double d = dx * dx + dy * dy + dz * dz;
      if (d < best_d) best_d = d, best = order[j];
    }
    anchors.push_back(best);
    b = e;
  }
  return anchors;
}

std::vector<float> anchor_log_scales(const float* pos, size_t m, float fallback_dist) {
  std::vector<float> out(6 * m);
  auto put = [&](size_t i, double d2) {
    const float l = float(std::log(std::sqrt(std::max(d2, 1e-7))));
    std::fill(out.begin() + 6 * i, out.begin() + 6 * i + 6, l);
  };
  if (m == 0) return out;
  if (m == 1) {
    put(0, double(fallback_dist) * fallback_dist);
    return out;
  }
  const size_t kk = std::min<size_t>(3, m - 1);
  // Uniform grid, ~2 anchors per cell for a surface-like set; a point in a cell farther than r cells
  // (Chebyshev) from p's cell is at least r * cell away, which makes the shell search exact.
  double lo[3] = {pos[0], pos[1], pos[2]}, hi[3] = {pos[0], pos[1], pos[2]};
  for (size_t i = 0; i < m; ++i)
    for (int a = 0; a < 3; ++a) lo[a] = std::min<double>(lo[a], pos[3 * i + a]), hi[a] = std::max<double>(hi[a], pos[3 * i + a]);
  const double ext = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  const double cell = ext > 0 ? std::max(ext / std::sqrt(double(m) / 2.0), ext * 1e-6) : 1.0;
  int64_t dims[3];
  for (int a = 0; a < 3; ++a) dims[a] = int64_t(std::floor((hi[a] - lo[a]) / cell)) + 1;
  auto coord = [&](const float* p, int a) { return std::min<int64_t>(int64_t(std::floor((p[a] - lo[a]) / cell)), dims[a] - 1); };
  auto key = [&](int64_t x, int64_t y, int64_t z) { return uint64_t(x) + uint64_t(dims[0]) * (uint64_t(y) + uint64_t(dims[1]) * uint64_t(z)); };
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells;
  for (size_t i = 0; i < m; ++i) cells[key(coord(pos + 3 * i, 0), coord(pos + 3 * i, 1), coord(pos + 3 * i, 2))].push_back(uint32_t(i));
  const int64_t max_dim = std::max({dims[0], dims[1], dims[2]});
  std::vector<double> best;
  for (size_t i = 0; i < m; ++i) {
    const float* p = pos + 3 * i;
    const int64_t c[3] = {coord(p, 0), coord(p, 1), coord(p, 2)};
    for (int64_t r = 1;; ++r) {
      best.clear();
      const bool brute = double(2 * r + 1) * double(2 * r + 1) * double(2 * r + 1) > 4.0 * double(m) || r >= max_dim;
      if (brute) {  // isolated anchor: scanning all m is cheaper than a huge shell
        for (size_t j = 0; j < m; ++j)
          if (j != i) best.push_back(sq_dist(p, pos + 3 * j));
      } else {
        for (int64_t z = std::max<int64_t>(0, c[2] - r); z <= std::min(dims[2] - 1, c[2] + r); ++z)
          for (int64_t y = std::max<int64_t>(0, c[1] - r); y <= std::min(dims[1] - 1, c[1] + r); ++y)
            for (int64_t x = std::max<int64_t>(0, c[0] - r); x <= std::min(dims[0] - 1, c[0] + r); ++x) {
              auto it = cells.find(key(x, y, z));
              if (it == cells.end()) continue;
              for (uint32_t j : it->second)
                if (j != i) best.push_back(sq_dist(p, pos + 3 * j));
            }
      }
      if (best.size() < kk && !brute) continue;
      std::partial_sort(best.begin(), best.begin() + kk, best.end());
      const double reach = double(r) * cell;
      if (brute || best[kk - 1] <= reach * reach) {
        double s = 0;
        for (size_t j = 0; j < kk; ++j) s += best[j];
        put(i, s / double(kk));
        break;
      }
    }
  }
  return out;
}

Expected<AnchorSet> init_anchors(const float* xyz, size_t n, const AnchorOptions& opt) {
  if (opt.k < 1) return invalid_argument("anchors: k must be >= 1, got " + std::to_string(opt.k));
  if (opt.feature_dim < 1) return invalid_argument("anchors: feature_dim must be >= 1, got " + std::to_string(opt.feature_dim));
  if (!(opt.voxel_size >= 0.0f) || !std::isfinite(opt.voxel_size))
    return invalid_argument("anchors: voxel_size must be finite and >= 0 (0 = automatic), got " + std::to_string(opt.voxel_size));
  float eps = opt.voxel_size;
  if (eps == 0.0f) {
    Expected<float> chosen = choose_voxel_size(xyz, n, opt.max_anchors);
    if (!chosen.ok()) return chosen.status();
    eps = *chosen;
  }
  Expected<std::vector<size_t>> idx = voxelise(xyz, n, eps);
  if (!idx.ok()) return idx.status();
  AnchorSet s;
  s.voxel_size = eps;
  s.k = opt.k;
  s.feature_dim = opt.feature_dim;
  const size_t m = idx->size();
  s.positions.resize(3 * m);
  for (size_t i = 0; i < m; ++i)
    for (int a = 0; a < 3; ++a) s.positions[3 * i + a] = xyz[3 * (*idx)[i] + a];
  s.offsets.assign(m * size_t(opt.k) * 3, 0.0f);
  s.log_scales = anchor_log_scales(s.positions.data(), m, eps);
  s.features.assign(m * size_t(opt.feature_dim), 0.0f);
  return s;
}

}  // namespace gs::model
