// SPDX-License-Identifier: MIT
// PSNR and SSIM between two RGB images, with the conventions of the 3DGS evaluation scripts, so
// hbgs numbers can be put next to published ones.
//
// Images are [H, W, 3] interleaved RGB, row-major, no row padding. 8-bit values are divided by 255;
// float images are taken as they are (expected in [0, 1], not clamped).
// - PSNR = 20 log10(1 / sqrt(MSE)) = -10 log10(MSE) with MSE over all 3·H·W values (peak 1). This
//   is the one PSNR of hbgs: every PSNR it prints or writes (training, evaluation, render, bake,
//   benchmarks, examples) comes from psnr_from_sse() below.
//   Identical images give +infinity (std::numeric_limits<double>::infinity()), the mathematical
//   limit, as the 3DGS metric scripts and scikit-image give; no finite stand-in (such as 99 dB) is
//   used. Callers that average over views must decide what to do with it (the mean is +inf), and
//   hbgs's JSON writers write a non-finite PSNR as null (JSON has no infinity; README "Metrics").
// - SSIM (Wang et al. 2004) as 3DGS's ssim(): 11x11 Gaussian window, sigma 1.5, C1 = 0.01²,
//   C2 = 0.03², each channel filtered on its own with zero padding ('same' size, as F.conv2d with
//   padding 5 and groups = 3); the result is the mean of the SSIM map over channels and pixels.
//   Zero padding darkens the local means within 5 px of the border; that is part of the convention.
// Both compute in double; SSIM is the training loss's SSIM term (gs/simd/loss.h), so evaluation and
// training measure the same thing. W or H below 1 (or a null pointer) give NaN. SSIM allocates
// copies and scratch per call; neither function is meant for the training inner loop.
#pragma once

#include <cstddef>
#include <cstdint>

namespace gs::metrics {

// The formula: -10 log10(mse), mse = sse / count, the squared errors in units of the peak (values
// in [0, 1]). sse == 0 gives +infinity; count <= 0 (or a NaN) gives NaN.
double psnr_from_sse(double sse, double count);

double psnr_u8(const uint8_t* a, const uint8_t* b, int W, int H);  // a, b: [H, W, 3]
double psnr_f32(const float* a, const float* b, int W, int H);     // a, b: [H, W, 3] in [0, 1]
// The same over n values in any layout (a batch of views end to end, RGBA, grey); n = 0 gives NaN.
double psnr_u8(const uint8_t* a, const uint8_t* b, size_t n);
double psnr_f32(const float* a, const float* b, size_t n);
// PSNR inside a mask [H, W] (0..255): each pixel's three squared errors weighted by its coverage
// mask / 255, divided by 3 x the coverage sum. NaN when the mask covers nothing (or W, H < 1).
double psnr_u8_masked(const uint8_t* a, const uint8_t* b, const uint8_t* mask, int W, int H);
double ssim_u8(const uint8_t* a, const uint8_t* b, int W, int H);  // a, b: [H, W, 3]
double ssim_f32(const float* a, const float* b, int W, int H);     // a, b: [H, W, 3] in [0, 1]

// The normalised 1-D Gaussian behind the SSIM window (the 2-D window is its outer product):
// g[k] = exp(-(k - 5)² / (2·1.5²)) / sum, k = 0..10. Exposed for tests.
constexpr int kSsimWindow = 11;
void ssim_gaussian_1d(double g[kSsimWindow]);

}  // namespace gs::metrics
