// SPDX-License-Identifier: MIT
// Reference fixed-point tile rasteriser (the spec of qraster_fwd_tile, gs/simd/qsplat.h): pixel by
// pixel, splat by splat, with the shared integer helpers; and the float-to-integer record
// conversion the renderer runs once per Gaussian.
#include <algorithm>
#include <cmath>

#include "gs/simd/qsplat.h"
#include "gs/simd/ref.h"

namespace gs::simd {
namespace {

// std::lround(v) (halves away from zero) for |v| < 2^52, inline: the conversion runs once per
// Gaussian per frame and the libm call was a fifth of its time. v - trunc(v) is exact there.
int64_t q_round_half_away(double v) {
  const int64_t t = int64_t(v);  // toward zero
  const double frac = v - double(t);
  return t + int64_t(frac >= 0.5) - int64_t(frac <= -0.5);  // branch-free: frac is random
}
// q_round_clamp(std::ceil(v), 0, hi) for an integer hi < 2^52, inline.
int32_t q_ceil_clamp(double v, double hi) {
  if (!(v > 0)) return 0;  // ceil(v) <= 0 (or NaN): clamped to 0
  if (v > hi) return int32_t(hi);
  const int64_t t = int64_t(v);  // toward zero
  return int32_t(t + int64_t(double(t) < v));
}

// lo, hi within +-2^31.
int32_t q_round_clamp(double v, double lo, double hi) {
  if (!(v >= lo)) return int32_t(lo);  // NaN too
  if (v > hi) return int32_t(hi);
  return int32_t(q_round_half_away(v));
}

}  // namespace

int32_t q15_from_unit(float v) { return q_round_clamp(double(v) * kQOne, 0, kQOne); }

void qsplat_from_record(const float* rec, float depth_scale, QSplat* out) {
  const double a = rec[kSplatA], b = rec[kSplatB], c = rec[kSplatC], o = rec[kSplatOpacity];
  QSplat q{};
  q.mx = q_round_clamp(double(rec[kSplatMx]) * 256.0, -2147483647.0, 2147483647.0);
  q.my = q_round_clamp(double(rec[kSplatMy]) * 256.0, -2147483647.0, 2147483647.0);
  const double det = a * c - b * b;
  const bool usable = a > 0 && det > 0 && o * 255.0 >= 1.0 && rec[kSplatExtX] >= 0 && rec[kSplatExtX] < 1e6f &&
                      rec[kSplatExtY] < 1e6f;
  if (usable) {
    q.kappa = q_round_clamp(b / a * 65536.0, -1073741824.0, 1073741824.0);
    q.s = q_round_clamp(std::sqrt(a / 2) * 16777216.0, 0, 33554432.0);
    q.r = q_round_clamp(std::sqrt(std::max(0.0, (c - b * b / a) / 2)) * 16777216.0, 0, 33554432.0);
    q.ylim = q_round_clamp(std::log(255.0 * std::min(o, 1.0)) * 2048.0, 0, 32767.0);
    q.ext_x = q_ceil_clamp(double(rec[kSplatExtX]) * 256.0, 268435456.0);
    q.ext_y = q_ceil_clamp(double(rec[kSplatExtY]) * 256.0, 268435456.0);
  } else {
    q.ylim = -1;  // never reaches alpha 1/255 (or not positive definite: the fixed path skips it)
    q.ext_x = q.ext_y = -1;
  }
  q.opacity = q_round_clamp(o * kQOne, 0, kQOne);
  for (int k = 0; k < 3; ++k) q.rgb[k] = q15_from_unit(rec[kSplatR + k]);
  q.depth = depth_scale > 0 ? q_round_clamp(double(rec[kSplatDepth]) / depth_scale * kQOne, 0, kQOne) : 0;
  *out = q;
}

void qraster_fwd_tile_ref(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                          float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
  const int32_t x0 = tile_x * kTileSize, y0 = tile_y * kTileSize;
  const int32_t tw = std::min(kTileSize, p->width - x0), th = std::min(kTileSize, p->height - y0);
  for (int32_t ly = 0; ly < th; ++ly) {
    const int32_t py_q8 = (y0 + ly) * 256 + 128;
    for (int32_t lx = 0; lx < tw; ++lx) {
      int16_t T = kQOne, acc[4] = {0, 0, 0, 0};
      int32_t last = 0;
      for (int32_t i = 0; i < count; ++i) {
        const QSplat& s = splats[i];
        int32_t bx0, by0, bx1, by1;
        if (!q_support_box(s, x0, y0, tw, th, &bx0, &by0, &bx1, &by1)) continue;
        if (ly < by0 || ly > by1) continue;  // rows of the support box; columns decide by y alone
        QRow row;
        if (!q_splat_row(s, x0, py_q8, &row)) continue;
        int16_t v = q_subs(row.v_j, q_column_step(s, lx - row.j));
        if (v < -32767) v = -32767;
        const int16_t y = q_adds(q_mulhrs(v, v), row.y_w);
        if (y > s.ylim) continue;
        const int16_t alpha = q_alpha(y, int16_t(s.opacity));
        const int16_t next = int16_t(T - q_mulhrs(T, alpha));
        if (next < kQTransmittanceStop) break;
        const int16_t w = q_mulhrs(alpha, T);
        for (int k = 0; k < 3; ++k) acc[k] = q_adds(acc[k], q_mulhrs(w, int16_t(s.rgb[k])));
        acc[3] = q_adds(acc[3], q_mulhrs(w, int16_t(s.depth)));
        T = next;
        last = i + 1;
      }
      const size_t pix = size_t(y0 + ly) * size_t(p->width) + size_t(x0 + lx);
      qraster_write_pixel(p, T, acc, last, pix, out_rgb, out_T, out_last, out_depth);
    }
  }
}

}  // namespace gs::simd
