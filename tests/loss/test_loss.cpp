// SPDX-License-Identifier: MIT
// Photometric loss kernels (loss.h): finite-difference gradient check of the double reference with
// the L1 kink excluded and counted, SSIM identities and a brute-force 2D (non-separable) SSIM, and
// every SIMD kernel table against the float reference on sizes around the lane counts and the
// 11-tap window, with canaries after the gradient and the scratch.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gs/simd/kernel_table.h"
#include "gs/simd/loss.h"
#include "support/simd_isa.h"

namespace {

using gs::simd::LossParams;
constexpr float kCanary = -12345.0f;

// Random image pair in [0, 1] with saturated 0/1 values in both and, where `equal_fraction` says,
// image == target exactly (the L1 kink).
template <class T>
void random_pair(std::mt19937_64& rng, int W, int H, double equal_fraction, std::vector<T>* image,
                 std::vector<T>* target) {
  std::uniform_real_distribution<double> u(0, 1);
  const size_t n = size_t(3) * W * H;
  image->resize(n);
  target->resize(n);
  auto value = [&]() {
    const double k = u(rng);
    return k < 0.1 ? 0.0 : (k < 0.2 ? 1.0 : u(rng));  // 10% black, 10% white
  };
  for (size_t e = 0; e < n; ++e) {
    (*target)[e] = T(value());
    (*image)[e] = u(rng) < equal_fraction ? (*target)[e] : T(value());
  }
}

double loss_of(const LossParams& p, int W, int H, const std::vector<double>& image, const std::vector<double>& target,
               std::vector<double>* scratch) {
  double l1 = 0, ssim = 0;
  gs::simd::loss_fwd_ref<double>(&p, W, H, image.data(), target.data(), scratch->data(), &l1, &ssim);
  return gs::simd::loss_value(&p, l1, ssim);
}

// 4-point central differences with h = 1e-4. Truncation: the loss varies on a scale of
// sqrt(C2 / w_centre) ~ 0.1 in one value (the variance terms are quadratic in it and sit next to
// C2 = 9e-4), so the O(h^4) error is ~(1e-4 / 0.1)^4 ~ 1e-12 relative. Rounding: L is O(1) and
// carries ~1e-16 of rounding, i.e. ~1e-12 of gradient noise after dividing by h. Gradients per
// value are ~1/(3 W H) ~ 1e-3 .. 1e-2 here, so a relative 1e-6 plus an absolute 1e-10 is far above
// both and far below any real mistake (a wrong term is O(1) relative). Measured worst relative
// error 1.1e-9 with lambda 0.2 and 1.8e-8 for the SSIM term alone (see the MESSAGEs).
constexpr double kStep = 1e-4;
constexpr double kRelTol = 1e-6;
constexpr double kAbsTol = 1e-10;

// Probes every `stride`-th value (3 channels interleaved, so an odd or even stride still visits
// every channel and every border distance); each probe costs four O(W H) forwards.
void fd_check(int W, int H, uint64_t seed, double lambda, size_t stride) {
  CAPTURE(W); CAPTURE(H); CAPTURE(seed); CAPTURE(lambda);
  std::mt19937_64 rng(seed);
  std::vector<double> image, target;
  random_pair(rng, W, H, 0.15, &image, &target);
  const LossParams p = gs::simd::make_loss_params(lambda);
  std::vector<double> scratch(gs::simd::loss_scratch_floats(W, H));
  const size_t n = image.size();
  std::vector<double> v_image(n);
  double l1 = 0, ssim = 0, l1_fwd = 0, ssim_fwd = 0;
  gs::simd::loss_bwd_ref<double>(&p, W, H, image.data(), target.data(), 1.0, scratch.data(), v_image.data(), &l1, &ssim);
  gs::simd::loss_fwd_ref<double>(&p, W, H, image.data(), target.data(), scratch.data(), &l1_fwd, &ssim_fwd);
  CHECK(l1 == doctest::Approx(l1_fwd).epsilon(1e-14));
  CHECK(ssim == doctest::Approx(ssim_fwd).epsilon(1e-14));
  int probes = 0, kinks = 0, failures = 0, equal = 0;
  double worst = 0;
  for (size_t e = 0; e < n; e += stride) {
    equal += image[e] == target[e] ? 1 : 0;
    // Boundary band: the +-2h stencil crosses |x - y|'s kink, so the difference quotient is
    // meaningless there (STYLE.md 8): count it, never loosen the tolerance for it.
    if (std::fabs(image[e] - target[e]) < 2.5 * kStep) {
      ++kinks;
      continue;
    }
    const double x0 = image[e];
    double l[4];
    const double offsets[4] = {-2 * kStep, -kStep, kStep, 2 * kStep};
    for (int k = 0; k < 4; ++k) {
      image[e] = x0 + offsets[k];
      l[k] = loss_of(p, W, H, image, target, &scratch);
    }
    image[e] = x0;
    const double fd = (8 * (l[2] - l[1]) - (l[3] - l[0])) / (12 * kStep);
    const double diff = std::fabs(fd - v_image[e]);
    const double scale = std::max(std::fabs(fd), std::fabs(v_image[e]));
    ++probes;
    worst = std::max(worst, diff / std::max(scale, 1e-300));
    if (diff > kRelTol * scale + kAbsTol) {
      ++failures;
      if (failures <= 5) MESSAGE("value " << e << ": finite difference " << fd << " vs analytic " << v_image[e]);
    }
  }
  MESSAGE(W << "x" << H << " lambda " << lambda << ": " << probes << " probes, " << kinks << " in the L1 kink band (" << equal
            << " exactly equal), worst relative error " << worst);
  CHECK(failures == 0);
  CHECK(kinks >= equal);
  CHECK(kinks <= equal + int(n / stride / 50) + 1);  // random values fall in the 2.5e-4 band rarely
}

// Brute-force SSIM: 2D window from its own formula, direct zero-padded 'same' correlation per channel.
double ssim_brute_force(int W, int H, const std::vector<double>& x, const std::vector<double>& y) {
  double g[11], gsum = 0;
  for (int k = 0; k < 11; ++k) gsum += g[k] = std::exp(-double((k - 5) * (k - 5)) / (2 * 1.5 * 1.5));
  const double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
  double total = 0;
  for (int c = 0; c < 3; ++c) {
    for (int py = 0; py < H; ++py) {
      for (int px = 0; px < W; ++px) {
        double mx = 0, my = 0, exx = 0, eyy = 0, exy = 0;
        for (int dy = -5; dy <= 5; ++dy) {
          for (int dx = -5; dx <= 5; ++dx) {
            const int qx = px + dx, qy = py + dy;
            if (qx < 0 || qx >= W || qy < 0 || qy >= H) continue;  // padded zeros add nothing
            const double wt = g[dx + 5] * g[dy + 5] / (gsum * gsum);
            const double a = x[(size_t(qy) * W + qx) * 3 + c], b = y[(size_t(qy) * W + qx) * 3 + c];
            mx += wt * a;
            my += wt * b;
            exx += wt * a * a;
            eyy += wt * b * b;
            exy += wt * a * b;
          }
        }
        const double sxx = exx - mx * mx, syy = eyy - my * my, sxy = exy - mx * my;
        total += ((2 * mx * my + C1) * (2 * sxy + C2)) / ((mx * mx + my * my + C1) * (sxx + syy + C2));
      }
    }
  }
  return total / (3.0 * W * H);
}

struct SizeCase {
  int W, H;
};

// Worst errors of one SIMD table against the float reference on one size.
struct Worst {
  double l1 = 0, ssim = 0, grad = 0;
};

void check_table(const gs::simd::KernelTable* kt, int W, int H, uint64_t seed, Worst* worst) {
  const std::string isa = kt->isa;
  CAPTURE(isa); CAPTURE(W); CAPTURE(H); CAPTURE(seed);
  std::mt19937_64 rng(seed);
  std::vector<float> image, target;
  random_pair(rng, W, H, 0.1, &image, &target);
  const LossParams p = gs::simd::make_loss_params();
  const size_t n = image.size(), ns = gs::simd::loss_scratch_floats(W, H);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Scratch starts as NaN: a kernel that reads scratch it did not write shows up in the outputs.
  std::vector<float> s_ref(ns, nan), s_out(ns + 16, nan), v_ref(n), v_out(n + 16, kCanary);
  for (size_t k = ns; k < ns + 16; ++k) s_out[k] = kCanary;
  double l1_ref = 0, ssim_ref = 0, l1 = 0, ssim = 0, l1_b = 0, ssim_b = 0;
  gs::simd::loss_bwd_ref<float>(&p, W, H, image.data(), target.data(), 1.0, s_ref.data(), v_ref.data(), &l1_ref,
                                &ssim_ref);
  kt->loss_fwd(&p, W, H, image.data(), target.data(), s_out.data(), &l1, &ssim);
  kt->loss_bwd(&p, W, H, image.data(), target.data(), 1.0, s_out.data(), v_out.data(), &l1_b, &ssim_b);
  for (size_t k = 0; k < 16; ++k) {
    REQUIRE(v_out[n + k] == kCanary);
    REQUIRE(s_out[ns + k] == kCanary);
  }
  // Forward: per-row float partial sums against the reference's per-value double sums (measured
  // worst 7e-8 relative).
  const double e_l1 = std::fabs(l1 - l1_ref) / std::max(l1_ref, 1e-30);
  const double e_ssim = std::fabs(ssim - ssim_ref) / std::fabs(ssim_ref);
  CHECK(e_l1 <= 1e-5);
  CHECK(e_ssim <= 1e-5);
  CHECK(std::fabs(l1_b - l1) <= 1e-6 * l1_ref);
  CHECK(std::fabs(ssim_b - ssim) <= 1e-6 * std::fabs(ssim_ref));
  // Gradient: relative to the largest reference value (values are sums of terms of both signs, so
  // a per-value relative error is meaningless where they cancel). Measured: 0 for sse2 and avx512
  // (bit-identical: same operation order, xsimd::fma there is a multiply and an add) and 2.9e-7
  // for avx2, neon64 and neon (fused multiply-adds); the budget is ~70x that.
  double vmax = 0;
  for (size_t e = 0; e < n; ++e) vmax = std::max(vmax, double(std::fabs(v_ref[e])));
  double e_grad = 0;
  for (size_t e = 0; e < n; ++e) {
    REQUIRE(std::isfinite(v_out[e]));
    e_grad = std::max(e_grad, std::fabs(double(v_out[e]) - double(v_ref[e])) / vmax);
  }
  CHECK(e_grad <= 2e-5);
  worst->l1 = std::max(worst->l1, e_l1);
  worst->ssim = std::max(worst->ssim, e_ssim);
  worst->grad = std::max(worst->grad, e_grad);
}

}  // namespace

TEST_CASE("loss reference gradient matches 4-point finite differences") {
  // Sizes: beyond the 11x11 window (interior and every border distance), smaller than it, and 1x1.
  fd_check(16, 12, 11, gs::simd::kLossLambda, 2);
  fd_check(5, 3, 12, gs::simd::kLossLambda, 1);
  fd_check(1, 1, 13, gs::simd::kLossLambda, 1);
  fd_check(12, 12, 14, 1.0, 2);  // SSIM term alone, so the L1 term cannot mask an error in it
}

TEST_CASE("loss reference: identical images give SSIM 1 and L1 0 and a zero gradient") {
  std::mt19937_64 rng(21);
  std::vector<double> image, target;
  random_pair(rng, 13, 9, 0.0, &image, &target);
  const LossParams p = gs::simd::make_loss_params();
  std::vector<double> scratch(gs::simd::loss_scratch_floats(13, 9)), v(image.size());
  double l1 = -1, ssim = -1;
  gs::simd::loss_fwd_ref<double>(&p, 13, 9, target.data(), target.data(), scratch.data(), &l1, &ssim);
  CHECK(l1 == 0.0);
  CHECK(std::fabs(ssim - 1.0) <= 1e-14);
  // SSIM has its maximum at image == target and the L1 subgradient there is 0.
  gs::simd::loss_bwd_ref<double>(&p, 13, 9, target.data(), target.data(), 1.0, scratch.data(), v.data(), nullptr,
                                 nullptr);
  double vmax = 0;
  for (double g : v) vmax = std::max(vmax, std::fabs(g));
  CHECK(vmax <= 1e-12);
}

TEST_CASE("loss reference SSIM equals a brute-force 2D zero-padded SSIM") {
  const LossParams p = gs::simd::make_loss_params();
  for (SizeCase s : {SizeCase{1, 1}, SizeCase{5, 3}, SizeCase{11, 11}, SizeCase{12, 13}, SizeCase{30, 17}}) {
    CAPTURE(s.W); CAPTURE(s.H);
    std::mt19937_64 rng(uint64_t(100 + s.W * 7 + s.H));
    std::vector<double> image, target;
    random_pair(rng, s.W, s.H, 0.1, &image, &target);
    std::vector<double> scratch(gs::simd::loss_scratch_floats(s.W, s.H));
    double l1 = 0, ssim = 0;
    gs::simd::loss_fwd_ref<double>(&p, s.W, s.H, image.data(), target.data(), scratch.data(), &l1, &ssim);
    const double brute = ssim_brute_force(s.W, s.H, image, target);
    // Same sums in a different order: agreement to double rounding, amplified by at most ~1/C2.
    CHECK(std::fabs(ssim - brute) <= 1e-12);
    double l1_direct = 0;
    for (size_t e = 0; e < image.size(); ++e) l1_direct += std::fabs(image[e] - target[e]);
    CHECK(std::fabs(l1 - l1_direct / double(image.size())) <= 1e-15);
    // The float reference follows the double one to float rounding (cancellation in
    // E[x^2] - mu^2 next to C2 = 9e-4 amplifies it to ~1e-6).
    std::vector<float> fi(image.begin(), image.end()), ft(target.begin(), target.end());
    std::vector<float> fs(scratch.size());
    double fl1 = 0, fssim = 0;
    gs::simd::loss_fwd_ref<float>(&p, s.W, s.H, fi.data(), ft.data(), fs.data(), &fl1, &fssim);
    CHECK(std::fabs(fssim - ssim) <= 1e-5);
    CHECK(std::fabs(fl1 - l1) <= 1e-6);
  }
}

GS_SIMD_TEST_CASE(loss_matches_ref, "loss kernels match the float reference") {
  Worst worst;
  for (SizeCase s : {SizeCase{1, 1}, SizeCase{3, 2}, SizeCase{11, 11}, SizeCase{17, 13}, SizeCase{64, 48},
                     SizeCase{393, 293}})
    check_table(kt, s.W, s.H, uint64_t(s.W * 1000 + s.H), &worst);
  MESSAGE(std::string(kt->isa) << ": worst relative error l1 " << worst.l1 << ", ssim " << worst.ssim << ", gradient (of max |v|) "
                  << worst.grad);
}

// The backward of one table is linear in the upstream cotangent.
static void check_cotangent_scaling(const gs::simd::KernelTable* kt) {
  const int W = 9, H = 7;
  std::mt19937_64 rng(5);
  std::vector<float> image, target;
  random_pair(rng, W, H, 0.1, &image, &target);
  const LossParams p = gs::simd::make_loss_params();
  std::vector<float> scratch(gs::simd::loss_scratch_floats(W, H)), v1(image.size()), v2(image.size());
  const std::string isa = kt->isa;
  CAPTURE(isa);
  kt->loss_bwd(&p, W, H, image.data(), target.data(), 1.0, scratch.data(), v1.data(), nullptr, nullptr);
  kt->loss_bwd(&p, W, H, image.data(), target.data(), -2.5, scratch.data(), v2.data(), nullptr, nullptr);
  // The scaled float constants round differently and a value's terms partly cancel, so compare
  // against the gradient's scale, not each value's.
  double vmax = 0;
  for (float g : v1) vmax = std::max(vmax, double(std::fabs(g)));
  for (size_t e = 0; e < v1.size(); ++e) CHECK(std::fabs(double(v2[e]) + 2.5 * double(v1[e])) <= 1e-5 * 2.5 * vmax);
}

TEST_CASE("loss kernels scale the gradient by the upstream cotangent / ref") {
  check_cotangent_scaling(&gs::simd::ref_kernel_table());
}

GS_SIMD_TEST_CASE(loss_cotangent_scaling, "loss kernels scale the gradient by the upstream cotangent") {
  check_cotangent_scaling(kt);
}

// loss_bwd_rows: bands of rows (any split, each band with its own scratch) give loss_bwd's
// gradient bit for bit, and the per-row sums added in row order give its means: bit for bit in
// the SIMD kernels (they sum per row too), to rounding in the reference (one running sum).
static void check_row_bands(const gs::simd::KernelTable* kt, bool exact_sums) {
  const std::string isa = kt->isa;
  CAPTURE(isa);
  const LossParams p = gs::simd::make_loss_params();
  for (SizeCase s : {SizeCase{1, 1}, SizeCase{17, 13}, SizeCase{64, 48}}) {
    const int W = s.W, H = s.H;
    CAPTURE(W);
    CAPTURE(H);
    std::mt19937_64 rng(uint64_t(W * 7 + H));
    std::vector<float> image, target;
    random_pair(rng, W, H, 0.1, &image, &target);
    std::vector<float> scratch(gs::simd::loss_scratch_floats(W, H)), whole(image.size());
    double l1 = 0, ssim = 0;
    kt->loss_bwd(&p, W, H, image.data(), target.data(), 1.0, scratch.data(), whole.data(), &l1, &ssim);
    for (int bands : {1, 2, 3, 7, H}) {
      if (bands > H) continue;
      CAPTURE(bands);
      std::vector<float> banded(image.size() + 1, kCanary);
      std::vector<double> row_l1(size_t(H) + 1, -1.0), row_ssim(size_t(H) + 1, -1.0);
      // Bands run last to first with a fresh scratch each, so no band leans on what another left.
      for (int b = bands - 1; b >= 0; --b) {
        std::vector<float> own(scratch.size(), std::numeric_limits<float>::quiet_NaN());
        kt->loss_bwd_rows(&p, W, H, H * b / bands, H * (b + 1) / bands, image.data(), target.data(), 1.0, own.data(),
                          banded.data(), row_l1.data(), row_ssim.data());
      }
      CHECK(banded.back() == kCanary);
      CHECK(row_l1.back() == -1.0);
      CHECK(row_ssim.back() == -1.0);
      size_t differ = 0;
      for (size_t e = 0; e < whole.size(); ++e) differ += banded[e] != whole[e];
      CHECK(differ == 0);
      double sum_l1 = 0, sum_ssim = 0;
      for (int r = 0; r < H; ++r) sum_l1 += row_l1[size_t(r)], sum_ssim += row_ssim[size_t(r)];
      const double count = 3.0 * W * H;
      if (exact_sums) {
        CHECK(sum_l1 / count == l1);
        CHECK(sum_ssim / count == ssim);
      } else {
        CHECK(std::fabs(sum_l1 / count - l1) <= 1e-12);
        CHECK(std::fabs(sum_ssim / count - ssim) <= 1e-12);
      }
    }
  }
}

TEST_CASE("loss kernels in bands of rows match the whole-image backward / ref") {
  check_row_bands(&gs::simd::ref_kernel_table(), /*exact_sums=*/false);
}

GS_SIMD_TEST_CASE(loss_row_bands, "loss kernels in bands of rows match the whole-image backward") {
  check_row_bands(kt, /*exact_sums=*/true);
}
