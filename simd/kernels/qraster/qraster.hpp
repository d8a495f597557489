// SPDX-License-Identifier: MIT
// xsimd fixed-point forward tile rasteriser, templated on the architecture: int16 lanes over the
// pixels of a tile row (16 lanes on AVX2 and AVX-512, where a tile row is one register; 8 on SSE2
// and NEON). Integer arithmetic only, so it is bit-exact with simd/ref/qraster_ref.cpp (the spec;
// formats in gs/simd/qsplat.h). Structure as the float forward (raster.hpp): splats in chunks,
// bucketed by the rows of their support box; per row, each splat's row values (its nearest column
// and v there, w^2) are computed once in scalar code, then every lane of the row is v_j minus a
// per-splat column-step table, squared, compared and blended. A lane takes part where its y <= ylim
// (the support box only picks the tile's rows), so the lane width never changes a result.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <cstdint>
#include <type_traits>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"

#include "gs/simd/qsplat.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__AVX2__)
#include <immintrin.h>
#endif
#if defined(__ARM_NEON) || defined(__ARM_NEON__)
#include <arm_neon.h>
#endif

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

// (a b + 2^14) >> 15 per int16 lane: pmulhrsw on AVX2, vqrdmulh on NEON, and an exact SSE2 form.
template <class A>
inline xsimd::batch<int16_t, A> q_mulhrs(const xsimd::batch<int16_t, A>& a, const xsimd::batch<int16_t, A>& b) {
  using B = xsimd::batch<int16_t, A>;
  using R = typename B::register_type;
#if defined(__AVX2__)
  if constexpr (sizeof(R) == 32) {  // __m256i
    return B(R(_mm256_mulhrs_epi16(R(a), R(b))));
  } else
#endif
#if defined(__SSE2__)
  if constexpr (sizeof(R) == 16) {  // __m128i
    // p = hi 2^16 + lo (lo unsigned); (p + 2^14) >> 15 = 2 hi + ((lo + 2^14) >> 15), the last term
    // computed as ((lo >> 1) + 2^13) >> 14 in unsigned 16 bits (exact: 2^14 is even).
    const __m128i hi = _mm_mulhi_epi16(R(a), R(b)), lo = _mm_mullo_epi16(R(a), R(b));
    const __m128i carry = _mm_srli_epi16(_mm_add_epi16(_mm_srli_epi16(lo, 1), _mm_set1_epi16(8192)), 14);
    return B(R(_mm_add_epi16(_mm_add_epi16(hi, hi), carry)));
  } else
#endif
#if defined(__ARM_NEON) || defined(__ARM_NEON__)
  if constexpr (sizeof(R) == 16) {  // int16x8_t
    return B(R(vqrdmulhq_s16(R(a), R(b))));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: no int16 mulhrs for this architecture");
    return a;
  }
}

template <class A>
inline xsimd::batch<int16_t, A> q_alpha(const xsimd::batch<int16_t, A>& y, int16_t opacity) {
  using B = xsimd::batch<int16_t, A>;
  const B z = xsimd::sadd(y, y);
  B h(kQExpPoly[4]);
  for (int k = 3; k >= 0; --k) h = xsimd::sadd(B(kQExpPoly[k]), q_mulhrs(h, z));
  B e = q_mulhrs(h, h);
  e = q_mulhrs(e, e);
  e = q_mulhrs(e, e);
  return xsimd::min(q_mulhrs(e, B(opacity)), B(int16_t(kQAlphaMax)));
}

template <class Arch>
struct QRasterKernels {
  using B = xsimd::batch<int16_t, Arch>;
  using M = xsimd::batch_bool<int16_t, Arch>;
  static constexpr int L = int(B::size);
  static constexpr int kChunk = 128;  // splats per chunk (row buckets index it with uint8_t)
  static_assert(kTileSize % L == 0, "tile rows must hold a whole number of batches");
  static constexpr int kPixels = kTileSize * kTileSize;

  struct ChunkSplat {
    const QSplat* s;
    int16_t index1;     // chunk-relative index + 1
    alignas(32) int16_t step[32];  // step[d + 15]: v step over d columns, d in [-15, 15]
  };

  static void fwd(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                  float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    if (out_depth) blend<true>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
    else blend<false>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
  }

  // kDepth: accumulate depth too (registration's keyframes); the image-only forward skips it.
  template <bool kDepth>
  static void blend(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                    float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    const int32_t x0 = tile_x * kTileSize, y0 = tile_y * kTileSize;
    const int32_t tw = scalar::min(kTileSize, p->width - x0), th = scalar::min(kTileSize, p->height - y0);
    alignas(64) int16_t T[kPixels], acc[4][kPixels], done[kPixels];
    int32_t last[kPixels];
    for (int i = 0; i < kPixels; ++i) {
      T[i] = int16_t(kQOne);
      acc[0][i] = acc[1][i] = acc[2][i] = acc[3][i] = 0;
      last[i] = 0;
      done[i] = (i % kTileSize < tw && i / kTileSize < th) ? 0 : -1;
    }
    ChunkSplat chunk[kChunk];
    uint8_t rows[kTileSize][kChunk];
    int32_t row_count[kTileSize];
    QRow row_vals[kChunk];
    bool row_ok[kChunk];
    bool all_done = false;
    for (int32_t c0 = 0; c0 < count && !all_done; c0 += kChunk) {
      const int32_t cn = scalar::min(kChunk, count - c0);
      for (int32_t y = 0; y < kTileSize; ++y) row_count[y] = 0;
      int32_t nb = 0;
      for (int32_t k = 0; k < cn; ++k) {
        const QSplat& s = splats[c0 + k];
        int32_t bx0, by0, bx1, by1;
        if (!q_support_box(s, x0, y0, tw, th, &bx0, &by0, &bx1, &by1)) continue;
        ChunkSplat& c = chunk[nb];
        c.s = &s;
        c.index1 = int16_t(k + 1);
        // q_column_step(s, d) for d = -15..15, by exact int64 increments instead of products.
        int64_t acc = -15 * int64_t(s.s) + 1024;
        for (int d = 0; d < 31; ++d, acc += s.s) c.step[d] = q_sat16(acc >> 11);
        c.step[31] = 0;
        for (int32_t y = by0; y <= by1; ++y) rows[y][row_count[y]++] = uint8_t(nb);
        ++nb;
      }
      if (nb == 0) continue;
      for (int32_t ly = 0; ly < th; ++ly) {
        const int32_t rn = row_count[ly];
        if (rn == 0) continue;
        const uint8_t* row = rows[ly];
        const int32_t py_q8 = (y0 + ly) * 256 + 128;
        for (int32_t j = 0; j < rn; ++j) row_ok[j] = q_splat_row(*chunk[row[j]].s, x0, py_q8, &row_vals[j]);
        for (int32_t lx0 = 0; lx0 < tw; lx0 += L) {
          const int o = ly * kTileSize + lx0;
          M is_done = B::load_aligned(done + o) != B(int16_t(0));
          if (xsimd::all(is_done)) continue;
          B t = B::load_aligned(T + o), cr = B::load_aligned(acc[0] + o), cg = B::load_aligned(acc[1] + o);
          B cb = B::load_aligned(acc[2] + o), cd = B::load_aligned(acc[3] + o), cl(int16_t(0));
          for (int32_t j = 0; j < rn; ++j) {
            if (!row_ok[j]) continue;
            const ChunkSplat& c = chunk[row[j]];
            const QSplat& s = *c.s;
            const QRow& rv = row_vals[j];
            const B step = B::load_unaligned(c.step + (lx0 - rv.j + 15));
            const B v = xsimd::max(xsimd::ssub(B(rv.v_j), step), B(int16_t(-32767)));
            const B y = xsimd::sadd(q_mulhrs(v, v), B(rv.y_w));
            const M in = (y <= B(int16_t(s.ylim))) & !is_done;
            if (!xsimd::any(in)) continue;
            const B alpha = q_alpha(y, int16_t(s.opacity));
            const B next = t - q_mulhrs(t, alpha);
            const M stop = in & (next < B(int16_t(kQTransmittanceStop)));
            const M use = in & !stop;
            const B w = xsimd::select(use, q_mulhrs(alpha, t), B(int16_t(0)));
            cr = xsimd::sadd(cr, q_mulhrs(w, B(int16_t(s.rgb[0]))));
            cg = xsimd::sadd(cg, q_mulhrs(w, B(int16_t(s.rgb[1]))));
            cb = xsimd::sadd(cb, q_mulhrs(w, B(int16_t(s.rgb[2]))));
            if (kDepth) cd = xsimd::sadd(cd, q_mulhrs(w, B(int16_t(s.depth))));
            t = xsimd::select(use, next, t);
            cl = xsimd::select(use, B(c.index1), cl);
            if (xsimd::any(stop)) {
              is_done = is_done | stop;
              if (xsimd::all(is_done)) break;
            }
          }
          t.store_aligned(T + o);
          cr.store_aligned(acc[0] + o);
          cg.store_aligned(acc[1] + o);
          cb.store_aligned(acc[2] + o);
          cd.store_aligned(acc[3] + o);
          xsimd::select(is_done, B(int16_t(-1)), B(int16_t(0))).store_aligned(done + o);
          alignas(64) int16_t l16[L];
          cl.store_aligned(l16);
          for (int i = 0; i < L; ++i)
            if (l16[i]) last[o + i] = c0 + l16[i];
        }
      }
      all_done = true;
      for (int i = 0; i < kPixels && all_done; ++i) all_done = done[i] != 0;
    }
    for (int32_t ly = 0; ly < th; ++ly)
      for (int32_t lx = 0; lx < tw; ++lx) {
        const int o = ly * kTileSize + lx;
        const int16_t a4[4] = {acc[0][o], acc[1][o], acc[2][o], acc[3][o]};
        const size_t pix = size_t(y0 + ly) * size_t(p->width) + size_t(x0 + lx);
        qraster_write_pixel(p, T[o], a4, last[o], pix, out_rgb, out_T, out_last, out_depth);
      }
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
