// SPDX-License-Identifier: MIT
// PSNR and SSIM between two RGB images, with the conventions of the 3DGS evaluation scripts, so
// hbgs numbers can be put next to published ones.
//
// Images are [H, W, 3] interleaved RGB, row-major, no row padding. 8-bit values are divided by 255;
// float images are taken as they are (expected in [0, 1], not clamped).
// - PSNR = 20 log10(1 / sqrt(MSE)) with MSE over all 3·H·W values (peak 1). Identical images give
//   +infinity (std::numeric_limits<double>::infinity()), not a large finite number, so callers that
//   average over views must decide what to do with it.
// - SSIM (Wang et al. 2004) as 3DGS's ssim(): 11x11 Gaussian window, sigma 1.5, C1 = 0.01²,
//   C2 = 0.03², each channel filtered on its own with zero padding ('same' size, as F.conv2d with
//   padding 5 and groups = 3); the result is the mean of the SSIM map over channels and pixels.
//   Zero padding darkens the local means within 5 px of the border; that is part of the convention.
// Both compute in double; SSIM is the training loss's SSIM term (gs/simd/loss.h), so evaluation and
// training measure the same thing. W or H below 1 (or a null pointer) give NaN. SSIM allocates
// copies and scratch per call; neither function is meant for the training inner loop.
#pragma once

#include <cstdint>

namespace gs::metrics {

double psnr_u8(const uint8_t* a, const uint8_t* b, int W, int H);  // a, b: [H, W, 3]
double psnr_f32(const float* a, const float* b, int W, int H);     // a, b: [H, W, 3] in [0, 1]
double ssim_u8(const uint8_t* a, const uint8_t* b, int W, int H);  // a, b: [H, W, 3]
double ssim_f32(const float* a, const float* b, int W, int H);     // a, b: [H, W, 3] in [0, 1]

// The normalised 1-D Gaussian behind the SSIM window (the 2-D window is its outer product):
// g[k] = exp(-(k - 5)² / (2·1.5²)) / sum, k = 0..10. Exposed for tests.
constexpr int kSsimWindow = 11;
void ssim_gaussian_1d(double g[kSsimWindow]);

}  // namespace gs::metrics
