// SPDX-License-Identifier: MIT
// Reference tile rasteriser: front-to-back alpha blending of depth-sorted splats (3DGS forward) and
// its backward, which walks each pixel's contributors back to front and recovers the transmittance
// by division, so no per-pixel lists are stored (only final T and the last contributor).
#include <algorithm>
#include <cmath>

#include "gs/simd/ref.h"

namespace gs::simd {
namespace {

template <class T>
void tile_bounds(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y, int32_t* x0, int32_t* y0, int32_t* x1,
                 int32_t* y1) {
  *x0 = tile_x * kTileSize;
  *y0 = tile_y * kTileSize;
  *x1 = std::min(*x0 + kTileSize, p->width);
  *y1 = std::min(*y0 + kTileSize, p->height);
}

}  // namespace

template <class T>
void raster_fwd_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y, const T* splats, int32_t count,
                         T* out_rgb, T* out_T, int32_t* out_last, T* out_depth) {
  int32_t x0, y0, x1, y1;
  tile_bounds(p, tile_x, tile_y, &x0, &y0, &x1, &y1);
  for (int32_t y = y0; y < y1; ++y) {
    for (int32_t x = x0; x < x1; ++x) {
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      T rgb[3] = {0, 0, 0}, depth = 0, trans = 1;
      int32_t last = 0;
      for (int32_t i = 0; i < count; ++i) {
        const T* s = splats + size_t(i) * kSplatStride;
        SplatEval<T> e;
        if (!eval_splat_ref(s, px, py, &e)) continue;
        const T next_T = trans * (T(1) - e.alpha);
        if (next_T < T(kTransmittanceMin)) break;
        const T w = e.alpha * trans;
        for (int c = 0; c < 3; ++c) rgb[c] += s[kSplatR + c] * w;
        depth += s[kSplatDepth] * w;
        trans = next_T;
        last = i + 1;
      }
      const size_t pix = size_t(y) * p->width + x;
      for (int c = 0; c < 3; ++c) out_rgb[3 * pix + c] = rgb[c] + trans * p->background[c];
      out_T[pix] = trans;
      out_last[pix] = last;
      if (out_depth) out_depth[pix] = depth;
    }
  }
}

template <class T>
void raster_bwd_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y, const T* splats, int32_t count,
                         const T* final_T, const int32_t* last, const T* v_rgb, T* v_splats) {
  std::fill(v_splats, v_splats + size_t(count) * kSplatStride, T(0));
  int32_t x0, y0, x1, y1;
  tile_bounds(p, tile_x, tile_y, &x0, &y0, &x1, &y1);
  for (int32_t y = y0; y < y1; ++y) {
    for (int32_t x = x0; x < x1; ++x) {
      const size_t pix = size_t(y) * p->width + x;
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      const T* v_pix = v_rgb + 3 * pix;
      const T T_final = final_T[pix];
      const T v_bg = p->background[0] * v_pix[0] + p->background[1] * v_pix[1] + p->background[2] * v_pix[2];
      T trans = T_final;
      T behind[3] = {0, 0, 0};  // colour blended behind the current splat, as seen from just behind it
      T next_alpha = 0, next_rgb[3] = {0, 0, 0};
      for (int32_t i = last[pix] - 1; i >= 0; --i) {
        const T* s = splats + size_t(i) * kSplatStride;
        SplatEval<T> e;
        if (!eval_splat_ref(s, px, py, &e)) continue;
        trans /= (T(1) - e.alpha);  // transmittance in front of splat i
        T* g = v_splats + size_t(i) * kSplatStride;
        const T w = e.alpha * trans;
        for (int c = 0; c < 3; ++c) g[kSplatR + c] += w * v_pix[c];
        for (int c = 0; c < 3; ++c) behind[c] = next_alpha * next_rgb[c] + (T(1) - next_alpha) * behind[c];
        T v_alpha = 0;
        for (int c = 0; c < 3; ++c) v_alpha += (s[kSplatR + c] - behind[c]) * v_pix[c];
        v_alpha = v_alpha * trans - T_final / (T(1) - e.alpha) * v_bg;
        next_alpha = e.alpha;
        for (int c = 0; c < 3; ++c) next_rgb[c] = s[kSplatR + c];
        if (e.clamped) continue;
        g[kSplatOpacity] += e.G * v_alpha;
        const T v_power = s[kSplatOpacity] * e.G * v_alpha;
        // power = -0.5 (a dx^2 + c dy^2) - b dx dy, d = mean2d - pixel centre
        g[kSplatMx] += v_power * -(s[kSplatA] * e.dx + s[kSplatB] * e.dy);
        g[kSplatMy] += v_power * -(s[kSplatC] * e.dy + s[kSplatB] * e.dx);
        g[kSplatA] += v_power * T(-0.5) * e.dx * e.dx;
        g[kSplatB] += v_power * -e.dx * e.dy;
        g[kSplatC] += v_power * T(-0.5) * e.dy * e.dy;
      }
    }
  }
}

template <class T>
void raster_pose_jacobian_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y, const T* splats,
                                   const T* splat_tangents, int32_t count, T* out_jacobian) {
  int32_t x0, y0, x1, y1;
  tile_bounds(p, tile_x, tile_y, &x0, &y0, &x1, &y1);
  for (int32_t y = y0; y < y1; ++y) {
    for (int32_t x = x0; x < x1; ++x) {
      const T px = T(x) + T(0.5), py = T(y) + T(0.5);
      T trans = 1;
      T d_trans[6] = {0, 0, 0, 0, 0, 0};
      T d_rgb[3][6] = {};
      for (int32_t i = 0; i < count; ++i) {
        const T* s = splats + size_t(i) * kSplatStride;
        const T* ds = splat_tangents + size_t(i) * 30;
        SplatEval<T> e;
        if (!eval_splat_ref(s, px, py, &e)) continue;
        const T next_T = trans * (T(1) - e.alpha);
        if (next_T < T(kTransmittanceMin)) break;
        // power = -0.5 (a dx^2 + c dy^2) - b dx dy, d = mean2d - pixel centre.
        const T g_mx = -(s[kSplatA] * e.dx + s[kSplatB] * e.dy);
        const T g_my = -(s[kSplatC] * e.dy + s[kSplatB] * e.dx);
        const T g_a = T(-0.5) * e.dx * e.dx, g_b = -e.dx * e.dy, g_c = T(-0.5) * e.dy * e.dy;
        T d_alpha[6] = {0, 0, 0, 0, 0, 0};
        if (!e.clamped)
          for (int k = 0; k < 6; ++k)
            d_alpha[k] = e.alpha * (g_mx * ds[k] + g_my * ds[6 + k] + g_a * ds[12 + k] + g_b * ds[18 + k] +
                                    g_c * ds[24 + k]);
        for (int c = 0; c < 3; ++c)
          for (int k = 0; k < 6; ++k) d_rgb[c][k] += s[kSplatR + c] * (d_alpha[k] * trans + e.alpha * d_trans[k]);
        for (int k = 0; k < 6; ++k) d_trans[k] = d_trans[k] * (T(1) - e.alpha) - trans * d_alpha[k];
        trans = next_T;
      }
      T* out = out_jacobian + (size_t(y) * p->width + x) * 18;
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 6; ++k) out[c * 6 + k] = d_rgb[c][k] + p->background[c] * d_trans[k];
    }
  }
}

template void raster_fwd_tile_ref<float>(const RasterParamsT<float>*, int32_t, int32_t, const float*, int32_t, float*,
                                         float*, int32_t*, float*);
template void raster_fwd_tile_ref<double>(const RasterParamsT<double>*, int32_t, int32_t, const double*, int32_t,
                                          double*, double*, int32_t*, double*);
template void raster_bwd_tile_ref<float>(const RasterParamsT<float>*, int32_t, int32_t, const float*, int32_t,
                                         const float*, const int32_t*, const float*, float*);
template void raster_bwd_tile_ref<double>(const RasterParamsT<double>*, int32_t, int32_t, const double*, int32_t,
                                          const double*, const int32_t*, const double*, double*);

template void raster_pose_jacobian_tile_ref<float>(const RasterParamsT<float>*, int32_t, int32_t, const float*,
                                                   const float*, int32_t, float*);
template void raster_pose_jacobian_tile_ref<double>(const RasterParamsT<double>*, int32_t, int32_t, const double*,
                                                    const double*, int32_t, double*);

}  // namespace gs::simd
