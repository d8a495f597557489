// SPDX-License-Identifier: MIT
// PSNR and SSIM with the 3DGS evaluation conventions (see gs/metrics/image_metrics.h).
#include "gs/metrics/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "gs/simd/loss.h"

namespace gs::metrics {
namespace {


double nan() { return std::numeric_limits<double>::quiet_NaN(); }

template <class T>
double psnr_impl(const T* a, const T* b, size_t n, double scale) {
  if (!a || !b || n == 0) return nan();
  double sse = 0;
  for (size_t i = 0; i < n; ++i) {
    const double d = (double(a[i]) - double(b[i])) * scale;
    sse += d * d;
  }
  return psnr_from_sse(sse, double(n));
}

size_t rgb_values(int W, int H) { return W < 1 || H < 1 ? 0 : size_t(W) * size_t(H) * 3; }

// SSIM is the training loss's SSIM term (simd/ref/loss_ref.cpp, the one implementation in hbgs),
// evaluated in double on copies of the images scaled to [0, 1].
template <class T>
double ssim_impl(const T* a, const T* b, int W, int H, double scale) {
  if (!a || !b || W < 1 || H < 1) return nan();
  const size_t n = size_t(W) * H * 3;
  std::vector<double> x(n), y(n), scratch(simd::loss_scratch_floats(W, H));
  for (size_t i = 0; i < n; ++i) x[i] = double(a[i]) * scale, y[i] = double(b[i]) * scale;
  const simd::LossParams params = simd::make_loss_params();
  double l1 = 0, ssim = 0;
  simd::loss_fwd_ref<double>(&params, W, H, x.data(), y.data(), scratch.data(), &l1, &ssim);
  return ssim;
}

}  // namespace

void ssim_gaussian_1d(double g[kSsimWindow]) {
  const simd::LossParams params = simd::make_loss_params();
  static_assert(kSsimWindow == int(sizeof(params.window) / sizeof(params.window[0])), "one SSIM window");
  std::copy(params.window, params.window + kSsimWindow, g);
}

double psnr_from_sse(double sse, double count) {
  if (!(count > 0) || !(sse >= 0)) return nan();
  if (sse == 0) return std::numeric_limits<double>::infinity();
  return -10.0 * std::log10(sse / count);  // = 20 log10(1 / sqrt(MSE))
}

double psnr_u8(const uint8_t* a, const uint8_t* b, int W, int H) { return psnr_impl(a, b, rgb_values(W, H), 1.0 / 255.0); }
double psnr_f32(const float* a, const float* b, int W, int H) { return psnr_impl(a, b, rgb_values(W, H), 1.0); }
double psnr_u8(const uint8_t* a, const uint8_t* b, size_t n) { return psnr_impl(a, b, n, 1.0 / 255.0); }
double psnr_f32(const float* a, const float* b, size_t n) { return psnr_impl(a, b, n, 1.0); }

double psnr_u8_masked(const uint8_t* a, const uint8_t* b, const uint8_t* mask, int W, int H) {
  if (!a || !b || !mask || W < 1 || H < 1) return nan();
  const size_t n = size_t(W) * size_t(H);
  double sse = 0, weight = 0;
  for (size_t p = 0; p < n; ++p) {
    const double cover = mask[p] / 255.0;
    for (size_t c = 0; c < 3; ++c) {
      const double e = (double(a[3 * p + c]) - double(b[3 * p + c])) / 255.0;
      sse += cover * e * e;
    }
    weight += 3 * cover;
  }
  return psnr_from_sse(sse, weight);
}

double ssim_u8(const uint8_t* a, const uint8_t* b, int W, int H) { return ssim_impl(a, b, W, H, 1.0 / 255.0); }
double ssim_f32(const float* a, const float* b, int W, int H) { return ssim_impl(a, b, W, H, 1.0); }

}  // namespace gs::metrics
