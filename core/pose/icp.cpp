// SPDX-License-Identifier: MIT
// Trimmed point-to-point ICP with Sim(3) updates (see icp_sim3 in gs/pose/pose.h): nearest
// neighbours on a uniform grid, pairs trimmed at a multiple of the median distance, each update an
// unweighted Umeyama fit (fit_sim3).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "gs/pose/pose.h"
#include "gs/stats.h"

namespace gs::pose {
namespace {

// Uniform grid over the target points for nearest-neighbour queries within a search radius.
class PointGrid {
 public:
  PointGrid(const double* pts, size_t n, double cell) : pts_(pts), cell_(cell) {
    for (size_t i = 0; i < n; ++i) cells_[key_of(pts + 3 * i)].push_back(uint32_t(i));
  }
  // Nearest target point to p within the 27 cells around it; false when none.
  bool nearest(const double p[3], size_t* index, double* dist) const {
    const int64_t cx = coord(p[0]), cy = coord(p[1]), cz = coord(p[2]);
    double best = 1e300;
    size_t best_i = 0;
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(key(cx + dx, cy + dy, cz + dz));
          if (it == cells_.end()) continue;
          for (uint32_t i : it->second) {
            const double* q = pts_ + 3 * size_t(i);
            const double d = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
            if (d < best) best = d, best_i = i;
          }
        }
    if (best == 1e300) return false;
    *index = best_i;
    *dist = std::sqrt(best);
    return true;
  }

 private:
  int64_t coord(double v) const { return int64_t(std::floor(v / cell_)); }
  static uint64_t key(int64_t x, int64_t y, int64_t z) {
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  }
  uint64_t key_of(const double* p) const { return key(coord(p[0]), coord(p[1]), coord(p[2])); }
  const double* pts_;
  double cell_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
};

// Extent of a point set: RMS distance from its mean.
double rms_spread(const double* p, size_t n) {
  double m[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) m[k] += p[3 * i + k] / double(n);
  double s = 0;
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) s += (p[3 * i + k] - m[k]) * (p[3 * i + k] - m[k]);
  return std::sqrt(s / double(std::max<size_t>(n, 1)));
}

}  // namespace

Sim3 icp_sim3(const double* source, size_t ns, const double* target, size_t nt, const Sim3& initial,
                    int iterations, double trim, double* median_before, double* median_after, int* pairs_out,
                    int* iterations_run) {
  Sim3 T = initial;
  // Search radius: start wide (the initial frame may be off by a few % of the scene), shrink to a
  // few times the median pair distance as ICP converges; the grid cell equals the radius.
  double radius = 0.1 * rms_spread(target, nt);
  std::vector<double> moved(3 * ns), x, y, dists;
  int it = 0;
  double first_median = -1, last_median = 0;
  int pairs = 0;
  for (; it < iterations; ++it) {
    const PointGrid grid(target, nt, radius);
    for (size_t i = 0; i < ns; ++i) transform_point(T, source + 3 * i, moved.data() + 3 * i);
    x.clear(), y.clear(), dists.clear();
    std::vector<size_t> match(ns, size_t(-1));
    std::vector<double> md(ns, 0);
    for (size_t i = 0; i < ns; ++i) {
      size_t j;
      double d;
      if (grid.nearest(moved.data() + 3 * i, &j, &d) && d <= radius) {
        match[i] = j, md[i] = d;
        dists.push_back(d);
      }
    }
    if (dists.size() < 10) break;
    const double med = median(dists);
    if (first_median < 0) first_median = med;
    last_median = med;
    for (size_t i = 0; i < ns; ++i)
      if (match[i] != size_t(-1) && md[i] <= trim * med) {
        x.insert(x.end(), source + 3 * i, source + 3 * i + 3);
        y.insert(y.end(), target + 3 * match[i], target + 3 * match[i] + 3);
      }
    pairs = int(x.size() / 3);
    Sim3 next;
    if (!fit_sim3(x.data(), y.data(), nullptr, x.size() / 3, &next)) break;
    const double change = std::fabs(next.s / T.s - 1.0) + std::fabs(next.t[0] - T.t[0]) + std::fabs(next.t[1] - T.t[1]) +
                          std::fabs(next.t[2] - T.t[2]);
    T = next;
    radius = std::max(3.0 * trim * med, 1e-9);
    if (change < 1e-9 * (1.0 + std::fabs(T.s))) {
      ++it;
      break;
    }
  }
  if (median_before != nullptr) *median_before = first_median;
  if (median_after != nullptr) *median_after = last_median;
  if (pairs_out != nullptr) *pairs_out = pairs;
  if (iterations_run != nullptr) *iterations_run = it;
  return T;
}

}  // namespace gs::pose
