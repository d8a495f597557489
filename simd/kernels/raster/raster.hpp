// SPDX-License-Identifier: MIT
// xsimd tile rasteriser (forward and backward), templated on the architecture. Lanes run over the
// pixels of a tile row (16 px = 16/N batches); per-pixel state lives in tile-local arrays that stay
// in L1. Each splat is first clipped to the box outside which its alpha is provably below 1/255
// (|d_x| <= sqrt(2 ln(255 o) cov_xx), plus a 1 px margin for rounding), so small splats touch only a
// few batches. Semantics are those of raster_ref.cpp, which is the spec; only this file's exp
// (xsimd's polynomial) differs from std::exp by a few ULP.
//
// Included only by the per-ISA translation units in ../variants/, which instantiate the kernels for
// one Arch each; never include it from code compiled with baseline flags.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/splat.h"

namespace gs::simd::kernels {

constexpr int kTilePixels = kTileSize * kTileSize;

struct TileGeometry {
  int32_t x0, y0, w, h;  // first pixel, size in pixels (w, h <= kTileSize at the image border)
};

inline TileGeometry tile_geometry(int32_t width, int32_t height, int32_t tile_x, int32_t tile_y) {
  TileGeometry g;
  g.x0 = tile_x * kTileSize;
  g.y0 = tile_y * kTileSize;
  g.w = std::min(kTileSize, width - g.x0);
  g.h = std::min(kTileSize, height - g.y0);
  return g;
}

// Inclusive tile-local pixel box [bx0, bx1] x [by0, by1] where the splat can reach alpha >= 1/255.
// Returns false if it reaches no pixel of the tile.
inline bool splat_support_box(const float* s, const TileGeometry& g, int32_t* bx0, int32_t* by0, int32_t* bx1,
                              int32_t* by1) {
  const float opacity = s[kSplatOpacity];
  if (!(opacity * 255.0f >= 1.0f)) return false;  // alpha = o G <= o < 1/255 everywhere
  const float a = s[kSplatA], b = s[kSplatB], c = s[kSplatC];
  const float det = a * c - b * b;
  float ex = float(kTileSize), ey = float(kTileSize);  // non-PD conic: no bound, use the whole tile
  if (det > 0.0f && a > 0.0f) {
    const float two_tau = 2.0f * std::log(255.0f * opacity);
    ex = std::sqrt(two_tau * c / det) + 1.0f;
    ey = std::sqrt(two_tau * a / det) + 1.0f;
  }
  // Pixel centre of local column i is x0 + i + 0.5.
  const float lx = s[kSplatMx] - float(g.x0) - 0.5f, ly = s[kSplatMy] - float(g.y0) - 0.5f;
  const float fx0 = std::max(lx - ex, -1.0f), fx1 = std::min(lx + ex, float(kTileSize));
  const float fy0 = std::max(ly - ey, -1.0f), fy1 = std::min(ly + ey, float(kTileSize));
  if (!(fx0 <= fx1) || !(fy0 <= fy1)) return false;
  *bx0 = std::max(0, int32_t(std::floor(fx0)));
  *bx1 = std::min(g.w - 1, int32_t(std::ceil(fx1)));
  *by0 = std::max(0, int32_t(std::floor(fy0)));
  *by1 = std::min(g.h - 1, int32_t(std::ceil(fy1)));
  return *bx0 <= *bx1 && *by0 <= *by1;
}

template <class Arch>
struct RasterKernels {
  using B = xsimd::batch<float, Arch>;
  using M = xsimd::batch_bool<float, Arch>;
  static constexpr int N = int(B::size);
  static_assert(kTileSize % N == 0, "tile rows must hold a whole number of batches");

  // Lane offsets 0.5, 1.5, ... for pixel centres.
  static B lane_centres() {
    alignas(64) float v[N];
    for (int i = 0; i < N; ++i) v[i] = float(i) + 0.5f;
    return B::load_aligned(v);
  }

  // power, G and alpha of one splat over one batch of pixels, as in raster_ref's eval_splat.
  struct Eval {
    B dx, dy, G, alpha;
    M contributes, clamped;
  };
  static Eval eval(const float* s, B px, B py) {
    Eval e;
    e.dx = B(s[kSplatMx]) - px;
    e.dy = B(s[kSplatMy]) - py;
    const B power = B(-0.5f) * (B(s[kSplatA]) * e.dx * e.dx + B(s[kSplatC]) * e.dy * e.dy) - B(s[kSplatB]) * e.dx * e.dy;
    e.G = xsimd::exp(power);
    const B raw = B(s[kSplatOpacity]) * e.G;
    e.clamped = raw > B(kAlphaMax);
    e.alpha = xsimd::select(e.clamped, B(kAlphaMax), raw);
    e.contributes = (power <= B(0.0f)) & (e.alpha >= B(kAlphaMin));
    return e;
  }

  static void fwd(const RasterParams* p, int32_t tile_x, int32_t tile_y, const float* splats, int32_t count,
                  float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    const TileGeometry g = tile_geometry(p->width, p->height, tile_x, tile_y);
    alignas(64) float T[kTilePixels], r[kTilePixels], gr[kTilePixels], bl[kTilePixels], dep[kTilePixels];
    alignas(64) float last[kTilePixels], done[kTilePixels];  // last as float: exact below 2^24 records
    for (int i = 0; i < kTilePixels; ++i) {
      T[i] = 1.0f; r[i] = gr[i] = bl[i] = dep[i] = 0.0f; last[i] = 0.0f;
      const int lx = i % kTileSize, ly = i / kTileSize;
      done[i] = (lx < g.w && ly < g.h) ? 0.0f : 1.0f;  // pixels outside the image never take part
    }
    int32_t active = g.w * g.h;
    const B centres = lane_centres();
    for (int32_t i = 0; i < count && active > 0; ++i) {
      const float* s = splats + size_t(i) * kSplatStride;
      int32_t bx0, by0, bx1, by1;
      if (!splat_support_box(s, g, &bx0, &by0, &bx1, &by1)) continue;
      const B idx1(float(i + 1));
      const int32_t c0 = bx0 / N * N, c1 = bx1 / N * N;
      for (int32_t ly = by0; ly <= by1; ++ly) {
        const B py(float(g.y0 + ly) + 0.5f);
        for (int32_t lx = c0; lx <= c1; lx += N) {
          const int o = ly * kTileSize + lx;
          const M is_done = B::load_aligned(done + o) != B(0.0f);
          if (xsimd::all(is_done)) continue;
          const B px = B(float(g.x0 + lx)) + centres;
          const Eval e = eval(s, px, py);
          M use = e.contributes & !is_done;
          if (!xsimd::any(use)) continue;
          const B t = B::load_aligned(T + o);
          const B next_t = t * (B(1.0f) - e.alpha);
          const M stop = use & (next_t < B(kTransmittanceMin));
          if (xsimd::any(stop)) {
            xsimd::select(stop, B(1.0f), B::load_aligned(done + o)).store_aligned(done + o);
            for (int k = 0; k < N; ++k) active -= stop.get(k) ? 1 : 0;
            use = use & !stop;
          }
          const B w = xsimd::select(use, e.alpha * t, B(0.0f));
          (B::load_aligned(r + o) + B(s[kSplatR]) * w).store_aligned(r + o);
          (B::load_aligned(gr + o) + B(s[kSplatG]) * w).store_aligned(gr + o);
          (B::load_aligned(bl + o) + B(s[kSplatBlue]) * w).store_aligned(bl + o);
          (B::load_aligned(dep + o) + B(s[kSplatDepth]) * w).store_aligned(dep + o);
          xsimd::select(use, next_t, t).store_aligned(T + o);
          xsimd::select(use, idx1, B::load_aligned(last + o)).store_aligned(last + o);
        }
      }
    }
    for (int32_t ly = 0; ly < g.h; ++ly) {
      for (int32_t lx = 0; lx < g.w; ++lx) {
        const int o = ly * kTileSize + lx;
        const size_t pix = size_t(g.y0 + ly) * p->width + (g.x0 + lx);
        out_rgb[3 * pix + 0] = r[o] + T[o] * p->background[0];
        out_rgb[3 * pix + 1] = gr[o] + T[o] * p->background[1];
        out_rgb[3 * pix + 2] = bl[o] + T[o] * p->background[2];
        out_T[pix] = T[o];
        out_last[pix] = int32_t(last[o]);
        if (out_depth) out_depth[pix] = dep[o];
      }
    }
  }

  static void bwd(const RasterParams* p, int32_t tile_x, int32_t tile_y, const float* splats, int32_t count,
                  const float* final_T, const int32_t* last_in, const float* v_rgb, float* v_splats) {
    std::fill(v_splats, v_splats + size_t(count) * kSplatStride, 0.0f);
    const TileGeometry g = tile_geometry(p->width, p->height, tile_x, tile_y);
    // Per-pixel state, walking back to front: transmittance in front of the current splat, colour
    // blended behind it, the previous (nearer-to-back) splat's alpha and colour.
    alignas(64) float T[kTilePixels], T_fin[kTilePixels], last[kTilePixels], v_bg[kTilePixels];
    alignas(64) float vr[kTilePixels], vg[kTilePixels], vb[kTilePixels];
    alignas(64) float br[kTilePixels], bg_[kTilePixels], bb[kTilePixels];
    alignas(64) float na[kTilePixels], nr[kTilePixels], ng[kTilePixels], nb[kTilePixels];
    int32_t max_last = 0;
    for (int i = 0; i < kTilePixels; ++i) {
      const int lx = i % kTileSize, ly = i / kTileSize;
      const bool inside = lx < g.w && ly < g.h;
      const size_t pix = inside ? size_t(g.y0 + ly) * p->width + (g.x0 + lx) : 0;
      T[i] = T_fin[i] = inside ? final_T[pix] : 1.0f;
      last[i] = inside ? float(last_in[pix]) : 0.0f;  // outside pixels: no contributor, never active
      max_last = std::max(max_last, inside ? last_in[pix] : 0);
      vr[i] = inside ? v_rgb[3 * pix] : 0.0f;
      vg[i] = inside ? v_rgb[3 * pix + 1] : 0.0f;
      vb[i] = inside ? v_rgb[3 * pix + 2] : 0.0f;
      v_bg[i] = p->background[0] * vr[i] + p->background[1] * vg[i] + p->background[2] * vb[i];
      br[i] = bg_[i] = bb[i] = na[i] = nr[i] = ng[i] = nb[i] = 0.0f;
    }
    const B centres = lane_centres();
    for (int32_t i = std::min(max_last, count) - 1; i >= 0; --i) {
      const float* s = splats + size_t(i) * kSplatStride;
      int32_t bx0, by0, bx1, by1;
      if (!splat_support_box(s, g, &bx0, &by0, &bx1, &by1)) continue;
      const B idx = B(float(i));
      const B cr(s[kSplatR]), cg(s[kSplatG]), cb(s[kSplatBlue]), op(s[kSplatOpacity]);
      const B ca(s[kSplatA]), cbb(s[kSplatB]), cc(s[kSplatC]);
      B acc_r(0.0f), acc_g(0.0f), acc_b(0.0f), acc_op(0.0f), acc_mx(0.0f), acc_my(0.0f), acc_a(0.0f), acc_b2(0.0f),
          acc_c(0.0f);
      const int32_t c0 = bx0 / N * N, c1 = bx1 / N * N;
      for (int32_t ly = by0; ly <= by1; ++ly) {
        const B py(float(g.y0 + ly) + 0.5f);
        for (int32_t lx = c0; lx <= c1; lx += N) {
          const int o = ly * kTileSize + lx;
          const M active = idx < B::load_aligned(last + o);
          if (!xsimd::any(active)) continue;
          const B px = B(float(g.x0 + lx)) + centres;
          const Eval e = eval(s, px, py);
          const M use = e.contributes & active;
          if (!xsimd::any(use)) continue;
          const B one_minus = B(1.0f) - e.alpha;
          const B t = xsimd::select(use, B::load_aligned(T + o) / one_minus, B::load_aligned(T + o));
          t.store_aligned(T + o);
          const B pvr = B::load_aligned(vr + o), pvg = B::load_aligned(vg + o), pvb = B::load_aligned(vb + o);
          const B w = xsimd::select(use, e.alpha * t, B(0.0f));
          acc_r += w * pvr;
          acc_g += w * pvg;
          acc_b += w * pvb;
          const B nalpha = B::load_aligned(na + o);
          const B one_minus_next = B(1.0f) - nalpha;
          const B behind_r = xsimd::select(use, nalpha * B::load_aligned(nr + o) + one_minus_next * B::load_aligned(br + o), B::load_aligned(br + o));
          const B behind_g = xsimd::select(use, nalpha * B::load_aligned(ng + o) + one_minus_next * B::load_aligned(bg_ + o), B::load_aligned(bg_ + o));
          const B behind_b = xsimd::select(use, nalpha * B::load_aligned(nb + o) + one_minus_next * B::load_aligned(bb + o), B::load_aligned(bb + o));
          behind_r.store_aligned(br + o);
          behind_g.store_aligned(bg_ + o);
          behind_b.store_aligned(bb + o);
          B v_alpha = (cr - behind_r) * pvr + (cg - behind_g) * pvg + (cb - behind_b) * pvb;
          v_alpha = v_alpha * t - B::load_aligned(T_fin + o) / one_minus * B::load_aligned(v_bg + o);
          xsimd::select(use, e.alpha, nalpha).store_aligned(na + o);
          xsimd::select(use, cr, B::load_aligned(nr + o)).store_aligned(nr + o);
          xsimd::select(use, cg, B::load_aligned(ng + o)).store_aligned(ng + o);
          xsimd::select(use, cb, B::load_aligned(nb + o)).store_aligned(nb + o);
          const M grad = use & !e.clamped;
          const B v_op = xsimd::select(grad, e.G * v_alpha, B(0.0f));
          acc_op += v_op;
          const B v_power = op * v_op;
          acc_mx += v_power * -(ca * e.dx + cbb * e.dy);
          acc_my += v_power * -(cc * e.dy + cbb * e.dx);
          acc_a += v_power * B(-0.5f) * e.dx * e.dx;
          acc_b2 += v_power * -e.dx * e.dy;
          acc_c += v_power * B(-0.5f) * e.dy * e.dy;
        }
      }
      float* gs = v_splats + size_t(i) * kSplatStride;
      gs[kSplatR] = xsimd::hadd(acc_r);
      gs[kSplatG] = xsimd::hadd(acc_g);
      gs[kSplatBlue] = xsimd::hadd(acc_b);
      gs[kSplatOpacity] = xsimd::hadd(acc_op);
      gs[kSplatMx] = xsimd::hadd(acc_mx);
      gs[kSplatMy] = xsimd::hadd(acc_my);
      gs[kSplatA] = xsimd::hadd(acc_a);
      gs[kSplatB] = xsimd::hadd(acc_b2);
      gs[kSplatC] = xsimd::hadd(acc_c);
    }
  }
};

}  // namespace gs::simd::kernels
