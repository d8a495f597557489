// SPDX-License-Identifier: MIT
// PSNR and SSIM: exact special cases, a hand-computed 1x1 SSIM, and SSIM of a noisy image against a
// direct (non-separable) double-precision 11x11 window sum written here.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "gs/metrics/image_metrics.h"

namespace gs::metrics {
namespace {

std::vector<uint8_t> random_image(int W, int H, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> im(size_t(W) * H * 3);
  // Smooth content plus texture, so SSIM is neither ~0 nor ~1.
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c)
        im[(size_t(y) * W + x) * 3 + c] =
            uint8_t(std::clamp(128.0 + 80.0 * std::sin(0.11 * x + 0.07 * y + c) + double(rng() % 41) - 20.0, 0.0, 255.0));
  return im;
}

std::vector<uint8_t> add_noise(const std::vector<uint8_t>& im, double sigma, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<uint8_t> out(im.size());
  for (size_t i = 0; i < im.size(); ++i) out[i] = uint8_t(std::clamp(std::round(im[i] + n(rng)), 0.0, 255.0));
  return out;
}

// 3DGS ssim() written the slow way: 2-D 11x11 window w(i,j) = g(i) g(j), zero outside the image.
double ssim_brute(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, int W, int H) {
  double g[kSsimWindow];
  double sum = 0;
  for (int k = 0; k < kSsimWindow; ++k) g[k] = std::exp(-double((k - 5) * (k - 5)) / (2 * 1.5 * 1.5)), sum += g[k];
  for (double& v : g) v /= sum;
  const double C1 = 1e-4, C2 = 9e-4;
  double total = 0;
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        double mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
        for (int dy = -5; dy <= 5; ++dy) {
          for (int dx = -5; dx <= 5; ++dx) {
            const int yy = y + dy, xx = x + dx;
            if (yy < 0 || yy >= H || xx < 0 || xx >= W) continue;
            const double w = g[dy + 5] * g[dx + 5];
            const double u = a[(size_t(yy) * W + xx) * 3 + c] / 255.0, v = b[(size_t(yy) * W + xx) * 3 + c] / 255.0;
            mx += w * u, my += w * v, sxx += w * u * u, syy += w * v * v, sxy += w * u * v;
          }
        }
        const double vx = sxx - mx * mx, vy = syy - my * my, cxy = sxy - mx * my;
        total += (2 * mx * my + C1) * (2 * cxy + C2) / ((mx * mx + my * my + C1) * (vx + vy + C2));
      }
    }
  }
  return total / (3.0 * W * H);
}

TEST_CASE("psnr: identical images give +infinity") {
  const auto im = random_image(17, 9, 1);
  const double p = psnr_u8(im.data(), im.data(), 17, 9);
  CHECK(std::isinf(p));
  CHECK(p > 0);
  std::vector<float> f(im.begin(), im.end());
  CHECK(std::isinf(psnr_f32(f.data(), f.data(), 17, 9)));
}

TEST_CASE("psnr: known MSE") {
  // 10x10x3 = 300 values, 3 of them off by 255 -> MSE = 3/300 = 0.01 -> 20 dB.
  std::vector<uint8_t> a(300, 0), b(300, 0);
  b[0] = b[101] = b[299] = 255;
  CHECK(psnr_u8(a.data(), b.data(), 10, 10) == doctest::Approx(20.0).epsilon(1e-12));
  // Uniform offset of 0.1 in float -> MSE 0.01 -> 20 dB.
  std::vector<float> fa(300, 0.25f), fb(300, 0.35f);
  CHECK(psnr_f32(fa.data(), fb.data(), 10, 10) == doctest::Approx(20.0).epsilon(1e-6));
  // Off by 1 level everywhere -> 20 log10(255) = 48.1308 dB.
  std::vector<uint8_t> c(300, 1);
  CHECK(psnr_u8(a.data(), c.data(), 10, 10) == doctest::Approx(20.0 * std::log10(255.0)).epsilon(1e-12));
}

TEST_CASE("psnr: the formula, its convention at zero error, and NaN for no values") {
  CHECK(psnr_from_sse(1.0, 100.0) == doctest::Approx(20.0).epsilon(1e-15));  // MSE 0.01
  CHECK(psnr_from_sse(3.0, 3.0) == 0.0);                                      // MSE 1 (peak error everywhere)
  const double inf = psnr_from_sse(0.0, 12.0);
  CHECK(std::isinf(inf));
  CHECK(inf > 0);
  CHECK(inf == std::numeric_limits<double>::infinity());
  CHECK(std::isnan(psnr_from_sse(0.0, 0.0)));
  CHECK(std::isnan(psnr_from_sse(1.0, -1.0)));
  CHECK(std::isnan(psnr_from_sse(std::nan(""), 3.0)));
}

TEST_CASE("psnr: the value-count variants equal the [H, W, 3] ones bit for bit") {
  const auto a = random_image(13, 7, 3), b = add_noise(a, 6.0, 4);
  CHECK(psnr_u8(a.data(), b.data(), a.size()) == psnr_u8(a.data(), b.data(), 13, 7));
  const std::vector<float> fa(a.begin(), a.end()), fb(b.begin(), b.end());
  std::vector<float> ua(fa.size()), ub(fb.size());
  for (size_t i = 0; i < fa.size(); ++i) ua[i] = fa[i] / 255.0f, ub[i] = fb[i] / 255.0f;
  CHECK(psnr_f32(ua.data(), ub.data(), ua.size()) == psnr_f32(ua.data(), ub.data(), 13, 7));
  // Any layout: 5 values, one off by 51 -> MSE = 0.2^2 / 5 = 0.008 -> 20.969 dB.
  const uint8_t p[5] = {0, 10, 20, 30, 40}, q[5] = {0, 10, 71, 30, 40};
  CHECK(psnr_u8(p, q, 5) == doctest::Approx(-10.0 * std::log10(0.008)).epsilon(1e-12));
  CHECK(std::isinf(psnr_u8(p, p, 5)));
  CHECK(std::isnan(psnr_u8(p, q, size_t(0))));
}

TEST_CASE("psnr inside a mask: coverage weights, nothing covered gives NaN") {
  // 2 x 1 image: pixel 0 wrong by 255 in red only, pixel 1 exact.
  const uint8_t a[6] = {0, 0, 0, 9, 9, 9}, b[6] = {255, 0, 0, 9, 9, 9};
  const uint8_t all[2] = {255, 255}, first[2] = {255, 0}, second[2] = {0, 255}, none[2] = {0, 0};
  // Full mask: the plain PSNR (MSE 1/6).
  CHECK(psnr_u8_masked(a, b, all, 2, 1) == doctest::Approx(psnr_u8(a, b, 2, 1)).epsilon(1e-12));
  CHECK(psnr_u8_masked(a, b, all, 2, 1) == doctest::Approx(10.0 * std::log10(6.0)).epsilon(1e-12));
  // Only the wrong pixel: MSE 1/3.
  CHECK(psnr_u8_masked(a, b, first, 2, 1) == doctest::Approx(10.0 * std::log10(3.0)).epsilon(1e-12));
  // Only the exact pixel: no error inside the mask.
  CHECK(std::isinf(psnr_u8_masked(a, b, second, 2, 1)));
  // A third of the wrong pixel (85 / 255), all of the exact one: sse 1/3 over weight 3 (1/3 + 1) = 4.
  const uint8_t third[2] = {85, 255};
  CHECK(psnr_u8_masked(a, b, third, 2, 1) == doctest::Approx(10.0 * std::log10(12.0)).epsilon(1e-12));
  CHECK(std::isnan(psnr_u8_masked(a, b, none, 2, 1)));
  CHECK(std::isnan(psnr_u8_masked(a, b, nullptr, 2, 1)));
}

TEST_CASE("psnr and ssim: empty sizes give NaN") {
  uint8_t px[3] = {0, 0, 0};
  CHECK(std::isnan(psnr_u8(px, px, 0, 1)));
  CHECK(std::isnan(ssim_u8(px, px, 1, 0)));
  CHECK(std::isnan(ssim_u8(nullptr, px, 1, 1)));
}

TEST_CASE("ssim: identical images give 1") {
  const auto im = random_image(41, 23, 2);
  CHECK(ssim_u8(im.data(), im.data(), 41, 23) == doctest::Approx(1.0).epsilon(1e-14));
  // Also a constant image, where every variance is small (padding makes it non-zero at borders).
  std::vector<uint8_t> flat(size_t(20) * 20 * 3, 77);
  CHECK(ssim_u8(flat.data(), flat.data(), 20, 20) == doctest::Approx(1.0).epsilon(1e-14));
}

TEST_CASE("ssim: hand-computed 1x1 image") {
  // One pixel: only the window's centre weight w0 = g[5]² touches the image, so per channel
  // mu_x = w0 x, E[x²] = w0 x², var_x = w0 (1 - w0) x², cov = w0 (1 - w0) x y.
  double g[kSsimWindow];
  ssim_gaussian_1d(g);
  // g[5] = 1 / sum_k exp(-(k-5)²/4.5): the sum is 1 + 2 (e^-1/4.5 + e^-4/4.5 + ... + e^-25/4.5).
  double s = 1;
  for (int d = 1; d <= 5; ++d) s += 2 * std::exp(-d * d / 4.5);
  CHECK(g[5] == doctest::Approx(1 / s).epsilon(1e-15));
  CHECK(g[5] == doctest::Approx(0.26601).epsilon(1e-4));  // the textbook value for sigma 1.5
  const double w0 = g[5] * g[5];
  const uint8_t a[3] = {200, 50, 0}, b[3] = {100, 60, 255};
  double expect = 0;
  for (int c = 0; c < 3; ++c) {
    const double x = a[c] / 255.0, y = b[c] / 255.0;
    const double mx = w0 * x, my = w0 * y;
    const double vx = w0 * (1 - w0) * x * x, vy = w0 * (1 - w0) * y * y, cxy = w0 * (1 - w0) * x * y;
    expect += (2 * mx * my + 1e-4) * (2 * cxy + 9e-4) / ((mx * mx + my * my + 1e-4) * (vx + vy + 9e-4)) / 3;
  }
  CHECK(ssim_u8(a, b, 1, 1) == doctest::Approx(expect).epsilon(1e-13));
}

TEST_CASE("ssim: noisy image matches a brute-force 2-D window") {
  const int W = 53, H = 37;  // odd, not square, larger than the window on both sides
  const auto a = random_image(W, H, 3);
  const auto b = add_noise(a, 12.0, 4);
  const double fast = ssim_u8(a.data(), b.data(), W, H);
  const double slow = ssim_brute(a, b, W, H);
  MESSAGE("ssim noisy = " << fast << "  brute force = " << slow);
  CHECK(fast > 0.2);
  CHECK(fast < 0.99);
  CHECK(std::abs(fast - slow) < 1e-12);
  // Float overload on the same data.
  std::vector<float> fa(a.size()), fb(b.size());
  for (size_t i = 0; i < a.size(); ++i) fa[i] = float(a[i] / 255.0), fb[i] = float(b[i] / 255.0);
  CHECK(std::abs(ssim_f32(fa.data(), fb.data(), W, H) - slow) < 1e-6);
  // Symmetric in its arguments.
  CHECK(std::abs(ssim_u8(b.data(), a.data(), W, H) - fast) < 1e-14);
  // Images narrower than the window (borders on both sides of every pixel).
  const auto c = random_image(4, 7, 5);
  const auto d = add_noise(c, 20.0, 6);
  CHECK(std::abs(ssim_u8(c.data(), d.data(), 4, 7) - ssim_brute(c, d, 4, 7)) < 1e-12);
}

}  // namespace
}  // namespace gs::metrics
