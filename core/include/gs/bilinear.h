// SPDX-License-Identifier: MIT
// The one bilinear sampler of RGB images (image features, the photometric pose solvers).
#pragma once

#include <algorithm>
#include <cstddef>

namespace gs {

// Bilinear colour c [3] of an RGB image [h, w, 3] (8-bit or float, values as stored) at the
// continuous pixel position (u, v), pixel centres at i + 0.5; with cu, cv (optional) its
// derivatives w.r.t. u and v. clamp: the position is clamped to the edge pixels' centres (always
// true); otherwise false (c untouched) when the 2 x 2 neighbourhood leaves the image.
template <class T>
inline bool sample_bilinear_rgb(const T* im, int w, int h, double u, double v, bool clamp, double c[3],
                                double cu[3] = nullptr, double cv[3] = nullptr) {
  double x = u - 0.5, y = v - 0.5;
  if (clamp) {
    x = std::min(std::max(x, 0.0), double(w - 1));
    y = std::min(std::max(y, 0.0), double(h - 1));
  } else if (!(x >= 0.0 && y >= 0.0 && x < double(w - 1) && y < double(h - 1))) {
    return false;
  }
  const int x0 = int(x), y0 = int(y);
  const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const double fx = x - x0, fy = y - y0;
  const T* p00 = im + (size_t(y0) * size_t(w) + size_t(x0)) * 3;
  const T* p10 = im + (size_t(y0) * size_t(w) + size_t(x1)) * 3;
  const T* p01 = im + (size_t(y1) * size_t(w) + size_t(x0)) * 3;
  const T* p11 = im + (size_t(y1) * size_t(w) + size_t(x1)) * 3;
  for (int k = 0; k < 3; ++k) {
    const double a = p00[k], b = p10[k], d = p01[k], e = p11[k];
    c[k] = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * d + fx * e);
    if (cu != nullptr) cu[k] = (1 - fy) * (b - a) + fy * (e - d);
    if (cv != nullptr) cv[k] = (1 - fx) * (d - a) + fx * (e - b);
  }
  return true;
}

}  // namespace gs
