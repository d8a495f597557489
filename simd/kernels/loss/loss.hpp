// SPDX-License-Identifier: MIT
// xsimd photometric loss (L1 + SSIM, forward and backward), templated on the architecture. Lanes
// run along the interleaved image row (3 W values): the vertical 11-tap pass reads 11 image rows at
// the same offsets, and the horizontal pass is 11 unaligned loads 3 values apart from a scratch row
// whose zero padding stands in for the image border, so neither pass branches per value. A row
// tail shorter than a batch is loaded zero-filled and stored partially, so inputs are never read
// and outputs never written past their end.
//
// Semantics and operation order are those of loss_ref.cpp (the spec), including the elementwise
// ssim_elem / ssim_elem_vjp shared through loss.h; results differ only by FMA contraction and by
// the per-row float partial sums of the two means.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"
#include "../madd.hpp"

#include "gs/simd/loss.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

template <class Arch>
struct LossKernels {
  using B = xsimd::batch<float, Arch>;
  static constexpr int N = int(B::size);
  static_assert(N <= 16 && kLossRowPad % N == 0, "scratch rows are padded for at most 16 lanes");

  static void fwd(const LossParams* p, int32_t width, int32_t height, const float* image, const float* target,
                  float* scratch, double* out_l1, double* out_ssim) {
    const Ctx c(p, width, scratch);
    float* v[kMoments];
    for (int q = 0; q < kMoments; ++q) v[q] = c.row(q);
    double sum_l1 = 0, sum_ssim = 0;
    for (int32_t r = 0; r < height; ++r) {
      moments_vertical(c, height, image, target, r, v);
      B acc_ssim(0.0f), acc_l1(0.0f);
      for (size_t i = 0; i < c.n; i += N) {
        const size_t cnt = scalar::min(size_t(N), c.n - i);
        B m[kMoments];
        for (int q = 0; q < kMoments; ++q) m[q] = blur_horizontal(c, v[q] + i);
        const B s = ssim_elem(m[0], m[1], m[2], m[3], m[4], c.c1, c.c2);
        const size_t e = size_t(r) * c.n + i;
        const B d = load_n(image + e, cnt) - load_n(target + e, cnt);  // 0 in the padded lanes
        acc_ssim += cnt == size_t(N) ? s : xsimd::select(lane_below(cnt), s, B(0.0f));
        acc_l1 += xsimd::abs(d);
      }
      sum_ssim += double(xsimd::hadd(acc_ssim));
      sum_l1 += double(xsimd::hadd(acc_l1));
    }
    const double count = double(c.n) * double(height);
    *out_l1 = sum_l1 / count;
    *out_ssim = sum_ssim / count;
  }

  static void bwd(const LossParams* p, int32_t width, int32_t height, const float* image, const float* target,
                  double v_loss, float* scratch, float* v_image, double* out_l1, double* out_ssim) {
    const double count = double(3 * size_t(width)) * double(height);
    double sum_l1 = 0, sum_ssim = 0;
    bwd_band(p, width, height, 0, height, image, target, v_loss, scratch, v_image,
             [&](int32_t, double l1) { sum_l1 += l1; }, [&](int32_t, double ssim) { sum_ssim += ssim; });
    if (out_l1) *out_l1 = sum_l1 / count;
    if (out_ssim) *out_ssim = sum_ssim / count;
  }

  // Rows [row_begin, row_end) of bwd (see loss.h): v_image of those rows, and each row's partial
  // sums of |d| and of the SSIM map (the terms bwd adds in row order) into row_l1 / row_ssim.
  static void bwd_rows(const LossParams* p, int32_t width, int32_t height, int32_t row_begin, int32_t row_end,
                       const float* image, const float* target, double v_loss, float* scratch, float* v_image,
                       double* row_l1, double* row_ssim) {
    bwd_band(p, width, height, row_begin, row_end, image, target, v_loss, scratch, v_image,
             [&](int32_t r, double l1) { row_l1[r] = l1; }, [&](int32_t r, double ssim) { row_ssim[r] = ssim; });
  }

 private:
  // The backward over image rows [r0, r1): the cotangent rows r0 - 5 .. r1 + 4 (inside the image)
  // are computed, those of [r0, r1) reported through add_ssim(row, partial sum); add_l1(row, sum)
  // for each row of [r0, r1). Both in increasing row order.
  template <class AddL1, class AddSsim>
  static void bwd_band(const LossParams* p, int32_t width, int32_t height, int32_t r0, int32_t r1, const float* image,
                       const float* target, double v_loss, float* scratch, float* v_image, AddL1&& add_l1,
                       AddSsim&& add_ssim) {
    const Ctx c(p, width, scratch);
    const double count = double(c.n) * double(height);
    const B v_map(float(-p->lambda * v_loss / count));
    const B v_abs(float((1 - p->lambda) * v_loss / count));
    float* v[kMoments];
    for (int q = 0; q < kMoments; ++q) v[q] = c.row(q);
    constexpr int kRing = kMoments, kVg = kRing + 3 * kSsimTaps;
    auto ring = [&](int32_t k, int g) { return c.row(kRing + 3 * (k % kSsimTaps) + g); };
    float* vg[3] = {c.row(kVg), c.row(kVg + 1), c.row(kVg + 2)};
    int32_t next = scalar::max(0, r0 - kSsimRadius);  // next cotangent row (rows r - 5 .. r + 5 live in the ring)
    for (int32_t r = r0; r < r1; ++r) {
      for (; next < height && next <= r + kSsimRadius; ++next) {
        moments_vertical(c, height, image, target, next, v);
        B acc_ssim(0.0f);
        float* g0 = ring(next, 0);
        float* g1 = ring(next, 1);
        float* g2 = ring(next, 2);
        for (size_t i = 0; i < c.n; i += N) {
          const size_t cnt = scalar::min(size_t(N), c.n - i);
          B m[kMoments];
          for (int q = 0; q < kMoments; ++q) m[q] = blur_horizontal(c, v[q] + i);
          B g_mx, g_exx, g_exy;
          const B s = ssim_elem_vjp(m[0], m[1], m[2], m[3], m[4], c.c1, c.c2, v_map, &g_mx, &g_exx, &g_exy);
          // Partial stores keep the row's padding zero: the zero moments past the row end have
          // a non-zero cotangent (-v_map / C2) that must not leak into the transposed blur.
          store_n(g0 + i, g_mx, cnt);
          store_n(g1 + i, g_exx, cnt);
          store_n(g2 + i, g_exy, cnt);
          acc_ssim += cnt == size_t(N) ? s : xsimd::select(lane_below(cnt), s, B(0.0f));
        }
        if (next >= r0 && next < r1) add_ssim(next, double(xsimd::hadd(acc_ssim)));
      }
      // Transposed blur, vertical pass: scratch rows are readable (and zero) past the row end.
      // Row pointers are resolved once per row (nullptr = outside the image).
      for (int g = 0; g < 3; ++g) {
        const float* centre = ring(r, g);
        const float* up[kSsimTaps];
        const float* down[kSsimTaps];
        for (int k = 1; k <= kSsimRadius; ++k) {
          up[k] = r - k >= 0 ? ring(r - k, g) : nullptr;
          down[k] = r + k < height ? ring(r + k, g) : nullptr;
        }
        for (size_t i = 0; i < c.n; i += N) {
          B acc = c.w[kSsimRadius] * B::load_unaligned(centre + i);
          for (int k = 1; k <= kSsimRadius; ++k) {
            if (!up[k] && !down[k]) continue;
            const B s = up[k] && down[k] ? B::load_unaligned(up[k] + i) + B::load_unaligned(down[k] + i)
                                         : B::load_unaligned((up[k] ? up[k] : down[k]) + i);
            acc = madd(c.w[kSsimRadius + k], s, acc);
          }
          acc.store_unaligned(vg[g] + i);
        }
      }
      B acc_l1(0.0f);
      for (size_t i = 0; i < c.n; i += N) {
        const size_t cnt = scalar::min(size_t(N), c.n - i);
        const size_t e = size_t(r) * c.n + i;
        const B x = load_n(image + e, cnt), y = load_n(target + e, cnt), d = x - y;
        const B b_mx = blur_horizontal(c, vg[0] + i);
        const B b_exx = blur_horizontal(c, vg[1] + i);
        const B b_exy = blur_horizontal(c, vg[2] + i);
        const B sgn = xsimd::select(d > B(0.0f), B(1.0f), xsimd::select(d < B(0.0f), B(-1.0f), B(0.0f)));
        store_n(v_image + e, v_abs * sgn + (b_mx + (x + x) * b_exx + y * b_exy), cnt);
        acc_l1 += xsimd::abs(d);
      }
      add_l1(r, double(xsimd::hadd(acc_l1)));
    }
  }

  static constexpr int kMoments = 5;  // B(x), B(y), B(x^2), B(y^2), B(x y)

  struct Ctx {
    B w[kSsimTaps];  // window taps, broadcast
    B c1, c2;
    size_t n, stride;
    float* scratch;
    Ctx(const LossParams* p, int32_t width, float* s)
        : c1(float(p->c1)), c2(float(p->c2)), n(3 * size_t(width)), stride(loss_row_stride(width)), scratch(s) {
      for (int k = 0; k < kSsimTaps; ++k) w[k] = B(float(p->window[k]));
      // Zero every row's padding once; the kernels only ever store inside [0, n) of a row.
      for (int k = 0; k < kLossScratchRows; ++k) {
        float* base = scratch + size_t(k) * stride;
        scalar::fill(base, base + kLossRowPad, 0.0f);
        scalar::fill(base + kLossRowPad + n, base + stride, 0.0f);
      }
    }
    float* row(int k) const { return scratch + size_t(k) * stride + kLossRowPad; }
  };

  static xsimd::batch_bool<float, Arch> lane_below(size_t cnt) {
    alignas(64) static const float iota[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
    return B::load_aligned(iota) < B(float(cnt));
  }

  // Loads cnt <= N values, zero-filling the other lanes (no read past p + cnt).
  static B load_n(const float* p, size_t cnt) {
    if (cnt == size_t(N)) return B::load_unaligned(p);
    alignas(64) float t[N] = {};
    for (size_t l = 0; l < cnt; ++l) t[l] = p[l];
    return B::load_aligned(t);
  }

  static void store_n(float* p, const B& v, size_t cnt) {
    if (cnt == size_t(N)) return v.store_unaligned(p);
    alignas(64) float t[N];
    v.store_aligned(t);
    for (size_t l = 0; l < cnt; ++l) p[l] = t[l];
  }

  // Vertical pass of the five moments of image row r into the scratch rows v (as the reference:
  // symmetric row pairs added before weighting, missing rows skipped).
  static void moments_vertical(const Ctx& c, int32_t height, const float* x, const float* y, int32_t r,
                               float* const* v) {
    for (size_t i = 0; i < c.n; i += N) {
      const size_t cnt = scalar::min(size_t(N), c.n - i);
      const B xc = load_n(x + size_t(r) * c.n + i, cnt), yc = load_n(y + size_t(r) * c.n + i, cnt);
      const B wc = c.w[kSsimRadius];
      B acc[kMoments] = {wc * xc, wc * yc, wc * (xc * xc), wc * (yc * yc), wc * (xc * yc)};
      for (int k = 1; k <= kSsimRadius; ++k) {
        const bool top = r - k >= 0, bot = r + k < height;
        if (!top && !bot) continue;
        // Rows r - k and r + k added first (or the one inside the image), as the reference.
        const float* xa = x + size_t(top ? r - k : r + k) * c.n + i;
        const float* ya = y + size_t(top ? r - k : r + k) * c.n + i;
        const B xa_v = load_n(xa, cnt), ya_v = load_n(ya, cnt);
        B s[kMoments] = {xa_v, ya_v, xa_v * xa_v, ya_v * ya_v, xa_v * ya_v};
        if (top && bot) {
          const B xb = load_n(x + size_t(r + k) * c.n + i, cnt), yb = load_n(y + size_t(r + k) * c.n + i, cnt);
          s[0] = s[0] + xb;
          s[1] = s[1] + yb;
          s[2] = s[2] + xb * xb;
          s[3] = s[3] + yb * yb;
          s[4] = s[4] + xb * yb;
        }
        for (int q = 0; q < kMoments; ++q) acc[q] = madd(c.w[kSsimRadius + k], s[q], acc[q]);
      }
      for (int q = 0; q < kMoments; ++q) store_n(v[q] + i, acc[q], cnt);
    }
  }

  // Horizontal pass at v[0 .. N) of a zero-padded scratch row (taps 3 values apart).
  static B blur_horizontal(const Ctx& c, const float* v) {
    B acc = c.w[kSsimRadius] * B::load_unaligned(v);
    for (int k = 1; k <= kSsimRadius; ++k)
      acc = madd(c.w[kSsimRadius + k], B::load_unaligned(v - 3 * k) + B::load_unaligned(v + 3 * k), acc);
    return acc;
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
