// SPDX-License-Identifier: MIT
// Scaffold-style anchor initialisation from SfM points (ALGORITHM.md Part A item 2, Part B 2.1-2.2).
#pragma once

#include <cstddef>
#include <vector>

#include "gs/status.h"

namespace gs::model {

struct AnchorOptions {
  float voxel_size = 0.0f;     // eps in world units; 0 = choose from the point spacing (choose_voxel_size)
  size_t max_anchors = 100000; // budget for the automatic eps (ignored when voxel_size > 0)
  int k = 10;                  // offsets (neural Gaussians) per anchor
  int feature_dim = 32;        // anchor feature f dimension F
};

// Row-major float arrays; M = size().
struct AnchorSet {
  float voxel_size = 0.0f;       // eps actually used, world units
  std::vector<float> positions;  // [M, 3], each an actual SfM point (fixed during training)
  std::vector<float> offsets;    // [M, k, 3], zeros
  std::vector<float> log_scales; // [M, 6], all 6 = log(sqrt(max(d2, 1e-7))), d2 = mean sq. 3-NN anchor distance
  std::vector<float> features;   // [M, F], zeros
  int k = 0;
  int feature_dim = 0;
  size_t size() const { return positions.size() / 3; }
};

// Number of distinct voxels floor(p / eps) occupied by xyz [n, 3]. Errors: empty input, eps <= 0
// or not finite, non-finite points, or voxel coordinates too large for int64 (eps far too small).
Expected<size_t> count_occupied_voxels(const float* xyz, size_t n, float eps);

// Automatic eps: starts at the median over points of the mean 3-NN distance and grows by x1.25
// until the occupied-voxel count is <= max_anchors. Growth continues past the scene extent because
// a voxel grid can still straddle a box; it stops (kCapacityExceeded) only when further growth
// cannot reduce the count (eps > 2 * max |coordinate|), which happens only for budgets < 8.
// Deterministic; the result is non-increasing in max_anchors (same geometric sequence).
Expected<float> choose_voxel_size(const float* xyz, size_t n, size_t max_anchors);

// hybridBA voxelisation: groups points by floor(p / eps) and returns, per occupied voxel, the index
// of the point closest to the voxel's centroid (ties: lowest index), ordered by voxel key
// (x, then y, then z, lexicographic). No shuffle: the result does not depend on a seed.
Expected<std::vector<size_t>> voxelise(const float* xyz, size_t n, float eps);

// Per-anchor log-scales [m, 6] from the exact mean squared distance to the min(3, m - 1) nearest
// other anchors; m == 1 uses d2 = fallback_dist^2 (the voxel size).
std::vector<float> anchor_log_scales(const float* positions, size_t m, float fallback_dist);

// Voxelise (with the given or automatic eps) and build the initial per-anchor parameters.
Expected<AnchorSet> init_anchors(const float* xyz, size_t n, const AnchorOptions& options);

}  // namespace gs::model
