// SPDX-License-Identifier: MIT
// The one bilinear sampler of hbgs: the 2 x 2 neighbourhood of a position and the blend of its four
// values. Used by the image features, the photometric pose solvers (RGB, double, with derivatives)
// and the dataset's undistortion (any channel count, float, as it always computed).
#pragma once

#include <algorithm>
#include <cstddef>

namespace gs {

// The 2 x 2 neighbourhood of the position (x, y) in pixel-index units (pixel centres at integers) in
// an image [h, w]: columns x0, x1 and rows y0, y1 (clamped to the image, so at or past an edge
// both are the edge pixel) and the fractions fx = x - floor(x), fy = y - floor(y). R is the
// arithmetic's type (float or double).
template <class R>
struct BilinearCell {
  int x0, x1, y0, y1;
  R fx, fy;
};
template <class R>
inline BilinearCell<R> bilinear_cell(R x, R y, int w, int h) {
  int xf = int(x), yf = int(y);  // floor, without a libm call where the ISA has no rounding instruction
  if (R(xf) > x) --xf;
  if (R(yf) > y) --yf;
  return {std::clamp(xf, 0, w - 1), std::clamp(xf + 1, 0, w - 1), std::clamp(yf, 0, h - 1), std::clamp(yf + 1, 0, h - 1),
          x - R(xf), y - R(yf)};
}

// The blend of the four values a = (x0, y0), b = (x1, y0), d = (x0, y1), e = (x1, y1): rows first,
// in R.
template <class R, class T>
inline R bilinear_blend(const BilinearCell<R>& q, T a, T b, T d, T e) {
  return (1 - q.fy) * ((1 - q.fx) * R(a) + q.fx * R(b)) + q.fy * ((1 - q.fx) * R(d) + q.fx * R(e));
}

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
  const BilinearCell<double> q = bilinear_cell(x, y, w, h);
  const T* p00 = im + (size_t(q.y0) * size_t(w) + size_t(q.x0)) * 3;
  const T* p10 = im + (size_t(q.y0) * size_t(w) + size_t(q.x1)) * 3;
  const T* p01 = im + (size_t(q.y1) * size_t(w) + size_t(q.x0)) * 3;
  const T* p11 = im + (size_t(q.y1) * size_t(w) + size_t(q.x1)) * 3;
  for (int k = 0; k < 3; ++k) {
    const double a = p00[k], b = p10[k], d = p01[k], e = p11[k];
    c[k] = bilinear_blend(q, a, b, d, e);
    if (cu != nullptr) cu[k] = (1 - q.fy) * (b - a) + q.fy * (e - d);
    if (cv != nullptr) cv[k] = (1 - q.fx) * (d - a) + q.fx * (e - b);
  }
  return true;
}

}  // namespace gs
