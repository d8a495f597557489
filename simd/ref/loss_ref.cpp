// SPDX-License-Identifier: MIT
// Reference photometric loss (L1 + SSIM, forward and backward), the spec of simd/kernels/loss/.
// Each blur is separable: a vertical 11-tap pass straight from the images (rows outside the image
// count as zero), then a horizontal pass on the interleaved row, where the same pixel's channel
// sits 3 values away and values outside the row count as zero. The backward pulls the SSIM-map
// cotangents back through the blurs with the transposed convolution, which for this symmetric
// window with zero padding is the same zero-padded blur, so it reuses the two passes.
#include <algorithm>
#include <cmath>

#include "gs/simd/loss.h"

namespace gs::simd {
namespace {

constexpr int kMoments = 5;  // B(x), B(y), B(x^2), B(y^2), B(x y)

template <class T>
struct Plan {
  size_t n;       // values per image row, 3 W
  size_t stride;  // scratch row stride
  T* scratch;
  // Interior of scratch row k (zero padding of kLossRowPad values on each side).
  T* row(int k) const { return scratch + size_t(k) * stride + kLossRowPad; }
};

// Vertical pass of the five moments for image row r into v[0..4]. Pairs of rows symmetric about r
// are added before weighting (the window is symmetric); a missing row adds nothing.
template <class T>
void moments_vertical(const T* w, size_t n, int32_t height, const T* x, const T* y, int32_t r, T* const* v) {
  for (size_t i = 0; i < n; ++i) {
    const T xc = x[size_t(r) * n + i], yc = y[size_t(r) * n + i];
    const T qc[kMoments] = {xc, yc, xc * xc, yc * yc, xc * yc};
    T acc[kMoments];
    for (int q = 0; q < kMoments; ++q) acc[q] = w[kSsimRadius] * qc[q];
    for (int k = 1; k <= kSsimRadius; ++k) {
      T s[kMoments] = {0, 0, 0, 0, 0};
      const int32_t pair[2] = {r - k, r + k};
      for (int32_t rr : pair) {
        if (rr < 0 || rr >= height) continue;
        const T xv = x[size_t(rr) * n + i], yv = y[size_t(rr) * n + i];
        const T qv[kMoments] = {xv, yv, xv * xv, yv * yv, xv * yv};
        for (int q = 0; q < kMoments; ++q) s[q] += qv[q];
      }
      for (int q = 0; q < kMoments; ++q) acc[q] += w[kSsimRadius + k] * s[q];
    }
    for (int q = 0; q < kMoments; ++q) v[q][i] = acc[q];
  }
}

// Horizontal pass at value i of a vertically blurred row (taps 3 values apart: same channel).
template <class T>
T blur_horizontal(const T* w, size_t n, const T* v, size_t i) {
  auto at = [&](long j) { return (j < 0 || j >= long(n)) ? T(0) : v[j]; };
  T acc = w[kSsimRadius] * v[i];
  for (int k = 1; k <= kSsimRadius; ++k) acc += w[kSsimRadius + k] * (at(long(i) - 3 * k) + at(long(i) + 3 * k));
  return acc;
}

template <class T>
void window_of(const LossParams* p, T* w) {
  for (int k = 0; k < kSsimTaps; ++k) w[k] = T(p->window[k]);
}

}  // namespace

template <class T>
void loss_fwd_ref(const LossParams* p, int32_t width, int32_t height, const T* image, const T* target, T* scratch,
                  double* out_l1, double* out_ssim) {
  T w[kSsimTaps];
  window_of(p, w);
  const T c1 = T(p->c1), c2 = T(p->c2);
  const Plan<T> pl{3 * size_t(width), loss_row_stride(width), scratch};
  T* v[kMoments];
  for (int q = 0; q < kMoments; ++q) v[q] = pl.row(q);
  double sum_l1 = 0, sum_ssim = 0;  // double: sums of up to millions of O(1) terms
  for (int32_t r = 0; r < height; ++r) {
    moments_vertical(w, pl.n, height, image, target, r, v);
    for (size_t i = 0; i < pl.n; ++i) {
      T m[kMoments];
      for (int q = 0; q < kMoments; ++q) m[q] = blur_horizontal(w, pl.n, v[q], i);
      sum_ssim += double(ssim_elem(m[0], m[1], m[2], m[3], m[4], c1, c2));
      const size_t e = size_t(r) * pl.n + i;
      sum_l1 += double(std::fabs(image[e] - target[e]));
    }
  }
  const double count = double(pl.n) * double(height);
  *out_l1 = sum_l1 / count;
  *out_ssim = sum_ssim / count;
}

namespace {

// The backward over image rows [r0, r1) (loss_bwd_ref is r0 = 0, r1 = height): the cotangent rows
// r0 - 5 .. r1 + 4 inside the image are computed; add_ssim(row, term) for each SSIM-map term of
// the rows of [r0, r1) and add_l1(row, term) for each |d| of them, in increasing order.
template <class T, class AddL1, class AddSsim>
void loss_bwd_band(const LossParams* p, int32_t width, int32_t height, int32_t r0, int32_t r1, const T* image,
                   const T* target, double v_loss, T* scratch, T* v_image, AddL1&& add_l1, AddSsim&& add_ssim) {
  T w[kSsimTaps];
  window_of(p, w);
  const T c1 = T(p->c1), c2 = T(p->c2);
  const Plan<T> pl{3 * size_t(width), loss_row_stride(width), scratch};
  const double count = double(pl.n) * double(height);
  // dL/dSSIM_map(e) = -lambda / count and dL/dL1(e) = (1 - lambda) / count, times the upstream.
  const T v_map = T(-p->lambda * v_loss / count);
  const T v_abs = T((1 - p->lambda) * v_loss / count);
  T* v[kMoments];
  for (int q = 0; q < kMoments; ++q) v[q] = pl.row(q);
  // Ring of cotangent rows (of B(x), B(x^2), B(x y)) for image rows r - 5 .. r + 5; row k lives
  // in slot k mod 11. Then their vertical blur for row r, zero-padded for the horizontal pass.
  constexpr int kRing = kMoments;
  constexpr int kVg = kRing + 3 * kSsimTaps;
  auto ring = [&](int32_t k, int g) { return pl.row(kRing + 3 * (k % kSsimTaps) + g); };
  T* vg[3] = {pl.row(kVg), pl.row(kVg + 1), pl.row(kVg + 2)};
  int32_t next = std::max(0, r0 - kSsimRadius);  // next cotangent row to compute
  for (int32_t r = r0; r < r1; ++r) {
    for (; next < height && next <= r + kSsimRadius; ++next) {
      moments_vertical(w, pl.n, height, image, target, next, v);
      for (size_t i = 0; i < pl.n; ++i) {
        T m[kMoments];
        for (int q = 0; q < kMoments; ++q) m[q] = blur_horizontal(w, pl.n, v[q], i);
        T g_mx, g_exx, g_exy;
        const T s = ssim_elem_vjp(m[0], m[1], m[2], m[3], m[4], c1, c2, v_map, &g_mx, &g_exx, &g_exy);
        if (next >= r0 && next < r1) add_ssim(next, double(s));
        ring(next, 0)[i] = g_mx;
        ring(next, 1)[i] = g_exx;
        ring(next, 2)[i] = g_exy;
      }
    }
    // Vertical pass of the cotangent maps (transposed blur), rows outside the image are zero.
    for (size_t i = 0; i < pl.n; ++i) {
      for (int g = 0; g < 3; ++g) {
        T acc = w[kSsimRadius] * ring(r, g)[i];
        for (int k = 1; k <= kSsimRadius; ++k) {
          T s = 0;
          if (r - k >= 0) s += ring(r - k, g)[i];
          if (r + k < height) s += ring(r + k, g)[i];
          acc += w[kSsimRadius + k] * s;
        }
        vg[g][i] = acc;
      }
    }
    for (size_t i = 0; i < pl.n; ++i) {
      const size_t e = size_t(r) * pl.n + i;
      const T x = image[e], y = target[e], d = x - y;
      const T b_mx = blur_horizontal(w, pl.n, vg[0], i);
      const T b_exx = blur_horizontal(w, pl.n, vg[1], i);
      const T b_exy = blur_horizontal(w, pl.n, vg[2], i);
      // d exx / dx = 2 x and d exy / dx = y at every window that covers this value.
      const T sgn = d > T(0) ? T(1) : (d < T(0) ? T(-1) : T(0));  // subgradient 0 at the kink
      v_image[e] = v_abs * sgn + (b_mx + (x + x) * b_exx + y * b_exy);
      add_l1(r, double(std::fabs(d)));
    }
  }
}

}  // namespace

template <class T>
void loss_bwd_ref(const LossParams* p, int32_t width, int32_t height, const T* image, const T* target, double v_loss,
                  T* scratch, T* v_image, double* out_l1, double* out_ssim) {
  double sum_l1 = 0, sum_ssim = 0;  // double: sums of up to millions of O(1) terms
  loss_bwd_band(p, width, height, 0, height, image, target, v_loss, scratch, v_image,
                [&](int32_t, double t) { sum_l1 += t; }, [&](int32_t, double t) { sum_ssim += t; });
  const double count = double(3 * size_t(width)) * double(height);
  if (out_l1) *out_l1 = sum_l1 / count;
  if (out_ssim) *out_ssim = sum_ssim / count;
}

template <class T>
void loss_bwd_rows_ref(const LossParams* p, int32_t width, int32_t height, int32_t row_begin, int32_t row_end,
                       const T* image, const T* target, double v_loss, T* scratch, T* v_image, double* row_l1,
                       double* row_ssim) {
  for (int32_t r = row_begin; r < row_end; ++r) row_l1[r] = row_ssim[r] = 0;
  loss_bwd_band(p, width, height, row_begin, row_end, image, target, v_loss, scratch, v_image,
                [&](int32_t r, double t) { row_l1[r] += t; }, [&](int32_t r, double t) { row_ssim[r] += t; });
}

template void loss_fwd_ref<float>(const LossParams*, int32_t, int32_t, const float*, const float*, float*, double*,
                                  double*);
template void loss_fwd_ref<double>(const LossParams*, int32_t, int32_t, const double*, const double*, double*, double*,
                                   double*);
template void loss_bwd_ref<float>(const LossParams*, int32_t, int32_t, const float*, const float*, double, float*,
                                  float*, double*, double*);
template void loss_bwd_rows_ref<float>(const LossParams*, int32_t, int32_t, int32_t, int32_t, const float*,
                                       const float*, double, float*, float*, double*, double*);
template void loss_bwd_rows_ref<double>(const LossParams*, int32_t, int32_t, int32_t, int32_t, const double*,
                                        const double*, double, double*, double*, double*, double*);
template void loss_bwd_ref<double>(const LossParams*, int32_t, int32_t, const double*, const double*, double, double*,
                                   double*, double*, double*);

}  // namespace gs::simd
