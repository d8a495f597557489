// SPDX-License-Identifier: MIT
// Kernel ABI of the fixed-point forward rasteriser (the on-device render path): the integer splat
// record, the per-frame parameters, and the integer arithmetic every variant shares. The kernels
// (ref: simd/ref/qraster_ref.cpp, the spec; xsimd: simd/kernels/qraster/) read only integers, so
// every variant is bit-exact with the reference.
//
// Geometry. The power -0.5 (a dx^2 + 2 b dx dy + c dy^2) of a splat is written as a sum of two
// squares, -(v^2 + w^2), with v = s (cx_row - px), s = sqrt(a / 2), cx_row = mx + (b / a)(my - py)
// (the row's centre) and w = r (my - py), r = sqrt((c - b^2 / a) / 2). Both squares are >= 0, so
// saturating int16 arithmetic never cancels: a lane far from the splat saturates to "far" (alpha
// 0), never to a wrong value. y = v^2 + w^2 is compared with ln(255 o) (alpha >= 1/255, the float
// kernels' rule) and alpha = o exp(-y) = o h(y / 8)^8 with h a degree-4 polynomial of exp(-z) on
// [0, 0.72] (|error| < 8e-5), evaluated in Q15; alpha's error is below 4e-4 (0.1 of an 8-bit level).
// The support box (from the float record's extents) picks the tile and its rows; within a row a
// pixel takes part exactly where y <= ylim.
//
// Fixed-point formats: positions Q8 px (int32); v, w Q13 (int16, |v| < 4); y Q11 (int16, < 16);
// alpha, transmittance, colour and depth Q15 (int16, 1.0 = 32767). mulhrs(a, b) = (a b + 2^14) >> 15
// is the one multiply (x86 pmulhrsw, NEON vqrdmulh); its operands are never both -32768.
// Blending: T' = T - mulhrs(T, alpha); stop before T' < 4 (1.2e-4, the float kernel's 1e-4);
// alpha <= 32439 (0.99); colour += mulhrs(mulhrs(alpha, T), c).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "gs/simd/isa.h"
#include "gs/simd/splat.h"

namespace gs::simd {

// Integer splat record, one per Gaussian-tile intersection, front to back. 13 int32 = the float
// record's 52 bytes, so the renderer's per-intersection buffer holds either.
struct QSplat {
  int32_t mx, my;     // Q8 px: centre (image coordinates, pixel centres at +0.5)
  int32_t kappa;      // Q16: b / a (the row centre moves by kappa px per px of dy), |kappa| <= 2^14
  int32_t s, r;       // Q24: sqrt(a / 2), sqrt((c - b^2/a) / 2), each in [0, 2^25]
  int32_t ylim;       // Q11: ln(255 o); the splat contributes where y <= ylim (negative: never)
  int32_t opacity;    // Q15
  int32_t rgb[3];     // Q15, clamped to [0, 1]
  int32_t depth;      // Q15 of RasterParams depth_scale
  int32_t ext_x, ext_y;  // Q8 px: half-extents of the support box (negative: never contributes)
};
static_assert(sizeof(QSplat) == kSplatStride * sizeof(float), "a QSplat fills a float record's slot");

// Per-frame constants of the fixed-point tile kernel.
struct QRasterParams {
  int32_t width, height;     // image size, px
  int32_t background[3];     // Q15
  float depth_scale;         // depth of 32767 (the output is depth_q15 * depth_scale / 32767)
};

constexpr int32_t kQOne = 32767;               // 1.0 in Q15
constexpr int32_t kQAlphaMax = 32439;          // 0.99
constexpr int32_t kQTransmittanceStop = 4;     // stop before T < 4 / 32767 (1.2e-4)
// exp(-z), z in [0, 0.72] (Q15 in, Q15 out): c0 + z (c1 + z (c2 + z (c3 + z c4))).
constexpr int16_t kQExpPoly[5] = {32767, -32763, 16324, -5222, 959};

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

inline int16_t q_sat16(int64_t v) { return int16_t(v < -32767 ? -32767 : (v > 32767 ? 32767 : v)); }
inline int32_t q_sat32(int64_t v) { return int32_t(v < INT32_MIN ? INT32_MIN : (v > INT32_MAX ? INT32_MAX : v)); }
// (a b + 2^14) >> 15, as int16 (wrapping, like pmulhrsw; operands never both -32768).
inline int16_t q_mulhrs(int16_t a, int16_t b) { return int16_t((int32_t(a) * int32_t(b) + (1 << 14)) >> 15); }
inline int16_t q_adds(int16_t a, int16_t b) {
  const int32_t v = int32_t(a) + int32_t(b);
  return int16_t(v < -32768 ? -32768 : (v > 32767 ? 32767 : v));
}
inline int16_t q_subs(int16_t a, int16_t b) {
  const int32_t v = int32_t(a) - int32_t(b);
  return int16_t(v < -32768 ? -32768 : (v > 32767 ? 32767 : v));
}
// floor(a / 2^k) for signed a (arithmetic shift is floor on every target hbgs supports).
inline int64_t q_floor_shift(int64_t a, int k) { return a >> k; }
inline int64_t q_round_shift(int64_t a, int k) { return (a + (int64_t(1) << (k - 1))) >> k; }

// alpha (Q15) of a lane at y (Q11, y <= ylim): o h(y / 8)^8.
inline int16_t q_alpha(int16_t y, int16_t opacity) {
  const int16_t z = q_adds(y, y);  // Q11 -> Q15 of y / 8 (y <= ln 255 < 5.55, so z < 0.7)
  int16_t h = kQExpPoly[4];
  for (int k = 3; k >= 0; --k) h = q_adds(kQExpPoly[k], q_mulhrs(h, z));
  int16_t e = q_mulhrs(h, h);
  e = q_mulhrs(e, e);
  e = q_mulhrs(e, e);
  const int16_t a = q_mulhrs(e, opacity);
  return a < kQAlphaMax ? a : int16_t(kQAlphaMax);
}

// One splat on one tile row: what every lane of the row needs. Row centre relative to the
// tile's column 0 pixel centre, the column j nearest it (clamped to the tile), v at that column,
// and the row's w^2.
struct QRow {
  int32_t j;     // 0..15
  int16_t v_j;   // Q13
  int16_t y_w;   // Q11: w^2
};
// false: no lane of this row can reach y <= ylim.
inline bool q_splat_row(const QSplat& s, int32_t x0, int32_t py_q8, QRow* out) {
  const int64_t dy = int64_t(s.my) - py_q8;                                        // Q8
  const int16_t w = q_sat16(q_round_shift(int64_t(s.r) * dy, 19));                // Q24 Q8 -> Q13
  const int16_t y_w = q_mulhrs(w, w);                                              // Q11
  if (y_w > s.ylim) return false;
  const int64_t cx = int64_t(s.mx) + q_floor_shift(int64_t(s.kappa) * dy, 16);     // Q8
  const int64_t rel = cx - (int64_t(x0) * 256 + 128);                              // from column 0's centre
  int64_t j = q_floor_shift(rel + 128, 8);
  j = j < 0 ? 0 : (j > kTileSize - 1 ? kTileSize - 1 : j);
  out->j = int32_t(j);
  out->v_j = q_sat16(q_round_shift(int64_t(s.s) * (rel - j * 256), 19));          // Q24 Q8 -> Q13
  out->y_w = y_w;
  return true;
}
// v step between columns d apart (Q13 of d s), d in [-15, 15].
inline int16_t q_column_step(const QSplat& s, int32_t d) { return q_sat16(q_round_shift(int64_t(d) * s.s, 11)); }

// Inclusive tile-local columns / rows [x0, x1] x [y0, y1] of the support box; false when empty.
inline bool q_support_box(const QSplat& s, int32_t tile_px0, int32_t tile_py0, int32_t tw, int32_t th, int32_t* bx0,
                          int32_t* by0, int32_t* bx1, int32_t* by1) {
  if (s.ext_x < 0 || s.ylim < 0) return false;
  const int64_t lx = int64_t(s.mx) - (int64_t(tile_px0) * 256 + 128), ly = int64_t(s.my) - (int64_t(tile_py0) * 256 + 128);
  const int64_t fx0 = lx - s.ext_x, fx1 = lx + s.ext_x, fy0 = ly - s.ext_y, fy1 = ly + s.ext_y;
  const int64_t c0 = q_floor_shift(fx0, 8), c1 = -q_floor_shift(-fx1, 8);  // floor, ceil
  const int64_t r0 = q_floor_shift(fy0, 8), r1 = -q_floor_shift(-fy1, 8);
  *bx0 = int32_t(c0 < 0 ? 0 : (c0 > tw ? tw : c0));
  *bx1 = int32_t(c1 > tw - 1 ? tw - 1 : (c1 < -1 ? -1 : c1));
  *by0 = int32_t(r0 < 0 ? 0 : (r0 > th ? th : r0));
  *by1 = int32_t(r1 > th - 1 ? th - 1 : (r1 < -1 ? -1 : r1));
  return *bx0 <= *bx1 && *by0 <= *by1;
}

// A pixel's outputs from its integer state: colour acc + T background, T, last, depth (floats for
// the renderer's callers; the same scalar code in every variant).
inline void qraster_write_pixel(const QRasterParams* p, int16_t T, const int16_t* acc, int32_t last, size_t pix,
                                float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
  constexpr float kInv = 1.0f / float(kQOne);
  for (int k = 0; k < 3; ++k) out_rgb[3 * pix + size_t(k)] = float(int32_t(acc[k]) + q_mulhrs(T, int16_t(p->background[k]))) * kInv;
  out_T[pix] = float(T) * kInv;
  out_last[pix] = last;
  if (out_depth) out_depth[pix] = float(acc[3]) * (p->depth_scale * kInv);
}

}  // inline namespace GS_SIMD_ISA_NS

// Reference fixed-point forward of one tile (the spec). splats: [count] front to back. Outputs as
// raster_fwd_tile's: out_rgb [H, W, 3] (acc + T background), out_T, out_last, out_depth (may be null).
void qraster_fwd_tile_ref(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                          float* out_rgb, float* out_T, int32_t* out_last, float* out_depth);

// Float record (splat.h layout, with its support fields) to the integer record. Deterministic
// float arithmetic, outside the kernels; depth_scale as in QRasterParams.
void qsplat_from_record(const float* record, float depth_scale, QSplat* out);
// Q15 of a colour in [0, 1] (clamped), for backgrounds.
int32_t q15_from_unit(float v);

}  // namespace gs::simd
