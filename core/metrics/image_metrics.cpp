// SPDX-License-Identifier: MIT
// PSNR and SSIM with the 3DGS evaluation conventions (see gs/metrics/image_metrics.h).
#include "gs/metrics/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace gs::metrics {
namespace {

constexpr double kC1 = 0.01 * 0.01;  // (K1 · L)² with L = 1 (data range of images in [0, 1])
constexpr double kC2 = 0.03 * 0.03;
constexpr int kRadius = kSsimWindow / 2;

double nan() { return std::numeric_limits<double>::quiet_NaN(); }

template <class T>
double psnr_impl(const T* a, const T* b, int W, int H, double scale) {
  if (!a || !b || W < 1 || H < 1) return nan();
  const size_t n = size_t(W) * H * 3;
  double sse = 0;
  for (size_t i = 0; i < n; ++i) {
    const double d = (double(a[i]) - double(b[i])) * scale;
    sse += d * d;
  }
  if (sse == 0) return std::numeric_limits<double>::infinity();
  return -10.0 * std::log10(sse / double(n));  // = 20 log10(1 / sqrt(MSE))
}

// Per channel: blur x, y, x², y², xy with the separable window (rows, then columns, zero outside
// the image: padding is separable because a row of zeros stays zero after the row pass), then
// average the SSIM map. The column pass is done one output row at a time straight into the sum.
template <class T>
double ssim_impl(const T* a, const T* b, int W, int H, double scale) {
  if (!a || !b || W < 1 || H < 1) return nan();
  double g[kSsimWindow];
  ssim_gaussian_1d(g);
  const size_t hw = size_t(W) * H;
  std::vector<double> rows(5 * hw);  // row-blurred [5][H, W]: x, y, x², y², xy
  double total = 0;
  for (int c = 0; c < 3; ++c) {
    for (int yy = 0; yy < H; ++yy) {
      for (int xx = 0; xx < W; ++xx) {
        double s[5] = {0, 0, 0, 0, 0};
        for (int k = -kRadius; k <= kRadius; ++k) {
          const int ix = xx + k;
          if (ix < 0 || ix >= W) continue;
          const size_t i = (size_t(yy) * W + ix) * 3 + c;
          const double u = double(a[i]) * scale, v = double(b[i]) * scale, wk = g[k + kRadius];
          s[0] += wk * u, s[1] += wk * v, s[2] += wk * u * u, s[3] += wk * v * v, s[4] += wk * u * v;
        }
        for (int m = 0; m < 5; ++m) rows[m * hw + size_t(yy) * W + xx] = s[m];
      }
    }
    double channel_sum = 0;
    std::vector<double> col(5 * size_t(W));
    for (int yy = 0; yy < H; ++yy) {
      std::fill(col.begin(), col.end(), 0.0);
      for (int k = -kRadius; k <= kRadius; ++k) {
        const int iy = yy + k;
        if (iy < 0 || iy >= H) continue;
        const double wk = g[k + kRadius];
        for (int m = 0; m < 5; ++m) {
          const double* r = rows.data() + m * hw + size_t(iy) * W;
          double* o = col.data() + size_t(m) * W;
          for (int xx = 0; xx < W; ++xx) o[xx] += wk * r[xx];
        }
      }
      for (int xx = 0; xx < W; ++xx) {
        const double mu_x = col[xx], mu_y = col[W + xx];
        const double var_x = col[2 * W + xx] - mu_x * mu_x, var_y = col[3 * W + xx] - mu_y * mu_y;
        const double cov = col[4 * W + xx] - mu_x * mu_y;
        channel_sum += ((2 * mu_x * mu_y + kC1) * (2 * cov + kC2)) /
                       ((mu_x * mu_x + mu_y * mu_y + kC1) * (var_x + var_y + kC2));
      }
    }
    total += channel_sum;
  }
  return total / double(3 * hw);
}

}  // namespace

void ssim_gaussian_1d(double g[kSsimWindow]) {
  const double sigma = 1.5;
  double sum = 0;
  for (int k = 0; k < kSsimWindow; ++k) {
    const double d = k - kRadius;
    g[k] = std::exp(-d * d / (2 * sigma * sigma));
    sum += g[k];
  }
  for (int k = 0; k < kSsimWindow; ++k) g[k] /= sum;
}

double psnr_u8(const uint8_t* a, const uint8_t* b, int W, int H) { return psnr_impl(a, b, W, H, 1.0 / 255.0); }
double psnr_f32(const float* a, const float* b, int W, int H) { return psnr_impl(a, b, W, H, 1.0); }
double ssim_u8(const uint8_t* a, const uint8_t* b, int W, int H) { return ssim_impl(a, b, W, H, 1.0 / 255.0); }
double ssim_f32(const float* a, const float* b, int W, int H) { return ssim_impl(a, b, W, H, 1.0); }

}  // namespace gs::metrics
