// SPDX-License-Identifier: MIT
// A global image descriptor for finding views of the same place: the grey levels of a small image,
// zero mean, unit norm, so the dot product of two is their normalised cross-correlation. Used by
// the tracker's relocalisation (its coarsest pyramid level), the registrar's relocalisation
// candidates (renders box-filtered to at least kDescriptorWidth x kDescriptorHeight) and the
// trainer's held-back views (the training photos at kDescriptorWidth x kDescriptorHeight).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace gs::pose::detail {

inline constexpr int kDescriptorWidth = 32, kDescriptorHeight = 24;

// rgb [pixels, 3] (any scale) -> out [pixels].
inline void grey_descriptor(const float* rgb, size_t pixels, float* out) {
  double mean = 0;
  for (size_t i = 0; i < pixels; ++i) mean += (rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2]) / 3.0;
  mean /= double(std::max<size_t>(pixels, 1));
  double sq = 0;
  for (size_t i = 0; i < pixels; ++i) {
    const double g = (rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2]) / 3.0 - mean;
    out[i] = float(g);
    sq += g * g;
  }
  const float inv = sq > 0 ? float(1.0 / std::sqrt(sq)) : 0.0f;
  for (size_t i = 0; i < pixels; ++i) out[i] *= inv;
}

// 1 - normalised cross-correlation of two descriptors of dim values (0: alike, 2: inverted); the
// ranking distance of the tracker's and the registrar's relocalisation candidates.
inline float descriptor_distance(const float* a, const float* b, size_t dim) {
  double dot = 0;
  for (size_t i = 0; i < dim; ++i) dot += double(a[i]) * b[i];
  return float(1.0 - dot);
}

}  // namespace gs::pose::detail
