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

// (a b + 2^14) >> 15 per int16 lane: pmulhrsw on AVX2 and AVX-512, vqrdmulh on NEON, and an exact SSE2 form.
template <class A>
inline xsimd::batch<int16_t, A> q_mulhrs(const xsimd::batch<int16_t, A>& a, const xsimd::batch<int16_t, A>& b) {
  using B = xsimd::batch<int16_t, A>;
  using R = typename B::register_type;
#if defined(__AVX512BW__)
  if constexpr (sizeof(R) == 64) {  // __m512i
    return B(R(_mm512_mulhrs_epi16(R(a), R(b))));
  } else
#endif
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
inline xsimd::batch<int16_t, A> q_alpha(const xsimd::batch<int16_t, A>& y, const xsimd::batch<int16_t, A>& opacity) {
  using B = xsimd::batch<int16_t, A>;
  const B z = xsimd::sadd(y, y);
  B h(kQExpPoly[4]);
  for (int k = 3; k >= 0; --k) h = xsimd::sadd(B(kQExpPoly[k]), q_mulhrs(h, z));
  B e = q_mulhrs(h, h);
  e = q_mulhrs(e, e);
  e = q_mulhrs(e, e);
  return xsimd::min(q_mulhrs(e, opacity), B(int16_t(kQAlphaMax)));
}

// Tile rows per register: two on AVX-512 (32 int16 lanes), else one (16 lanes) or half of one (8).
template <class A>
constexpr int q_rows_per_register() {
  return int(xsimd::batch<int16_t, A>::size) >= 2 * kTileSize ? int(xsimd::batch<int16_t, A>::size) / kTileSize : 1;
}

// A batch of two tile rows (R = 2): lanes [0, 16) hold lo, lanes [16, 32) hold hi.
template <class A>
inline xsimd::batch<int16_t, A> q_rows_broadcast(int16_t lo, int16_t hi) {
  using B = xsimd::batch<int16_t, A>;
#if defined(__AVX512BW__)
  if constexpr (B::size == 32) {
    return B(_mm512_mask_set1_epi16(_mm512_set1_epi16(lo), __mmask32(0xFFFF0000u), hi));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: two rows per register only on AVX-512");
    (void)hi;
    return B(lo);
  }
}
// 16 int16 from lo then 16 from hi (unaligned), as one two-row batch.
template <class A>
inline xsimd::batch<int16_t, A> q_rows_load(const int16_t* lo, const int16_t* hi) {
  using B = xsimd::batch<int16_t, A>;
#if defined(__AVX512BW__)
  if constexpr (B::size == 32) {
    const __m256i l = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(lo));
    const __m256i h = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(hi));
    return B(_mm512_inserti64x4(_mm512_castsi256_si512(l), h, 1));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: two rows per register only on AVX-512");
    (void)hi;
    return B::load_unaligned(lo);
  }
}
// Lanes of the rows set in `rows` (bit h: the register's row h).
template <class A>
inline xsimd::batch_bool<int16_t, A> q_rows_mask(uint32_t rows) {
  using M = xsimd::batch_bool<int16_t, A>;
#if defined(__AVX512BW__)
  if constexpr (xsimd::batch<int16_t, A>::size == 32) {
    return M(typename M::register_type((rows & 1 ? 0x0000FFFFu : 0u) | (rows & 2 ? 0xFFFF0000u : 0u)));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: two rows per register only on AVX-512");
    return M(rows != 0);
  }
}

template <class Arch>
struct QRasterKernels {
  using B = xsimd::batch<int16_t, Arch>;
  using M = xsimd::batch_bool<int16_t, Arch>;
  using B32 = xsimd::batch<int32_t, Arch>;
  static constexpr int L = int(B::size);
  static constexpr int R = q_rows_per_register<Arch>();  // tile rows per register (1 or 2)
  static constexpr int kGroups = kTileSize / R;             // register rows of a tile
  static constexpr int kChunk = 128;  // splats per chunk (bucket entries index it with uint8_t)
  static_assert(kTileSize % L == 0 || L == R * kTileSize, "a register holds part of a tile row or whole rows");
  static constexpr int kPixels = kTileSize * kTileSize;

  // What the blend loop reads of one splat. The per-splat constants are stored twice in an int32
  // so that broadcasting them is a 32-bit broadcast load (no shuffle).
  struct ChunkSplat {
    alignas(64) int16_t step[32];  // step[d + 15]: q_column_step over d columns, d in [-15, 15]; step[31] = 0
    int32_t ylim2, opacity2, rgb2[3], depth2, index2;  // ylim, opacity, colour, depth, chunk index + 1
  };
  // One splat on one register's rows (R of them), in the bucket of that register row: the row
  // values of q_splat_row and the step-table offset 15 - j that aligns column 0 with it.
  struct Entry {
    int16_t v_j[R], y_w[R], off[R];
    uint8_t splat;  // index in the chunk
    uint8_t rows;   // bit h: row h of the register is reached (R = 2; always 1 for R = 1)
  };

  static void fwd(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                  float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    if (out_depth) blend<true>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
    else blend<false>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
  }

  static int32_t twice(int32_t v) { return int32_t(uint32_t(uint16_t(v)) * 0x10001u); }
  static B broadcast2(int32_t v2) { return xsimd::bitwise_cast<B>(B32(v2)); }

  // Chunk setup of one splat: its constants, its column-step table and the row values of every
  // row of its support box, appended to the buckets of the registers that hold those rows. The row
  // values are q_splat_row's, stepped row to row by exact int64 increments (dy falls by 256 per row).
  static void add_splat(const QSplat& s, int32_t k, int32_t x0, int32_t y0, int32_t by0, int32_t by1, ChunkSplat* c,
                        Entry (*buckets)[kChunk], int32_t* bucket_count, int32_t nb) {
    // q_column_step(s, d) = sat16((d s + 2^10) >> 11): |d s| <= 15 2^25 fits int32.
    for (int d = 0; d < 32; ++d) {
      const int32_t v = ((d - 15) * s.s + 1024) >> 11;
      c->step[d] = int16_t(v < -32767 ? -32767 : (v > 32767 ? 32767 : v));
    }
    c->step[31] = 0;
    c->ylim2 = twice(s.ylim);
    c->opacity2 = twice(s.opacity);
    for (int k3 = 0; k3 < 3; ++k3) c->rgb2[k3] = twice(s.rgb[k3]);
    c->depth2 = twice(s.depth);
    c->index2 = twice(k + 1);

    const int64_t dy0 = int64_t(s.my) - (int64_t(y0 + by0) * 256 + 128);
    int64_t r_dy = int64_t(s.r) * dy0, kappa_dy = int64_t(s.kappa) * dy0;
    const int64_t r_step = int64_t(s.r) * 256, kappa_step = int64_t(s.kappa) * 256;
    const int64_t col0 = int64_t(x0) * 256 + 128;
    int16_t v_j[kTileSize], y_w[kTileSize], off[kTileSize];
    uint32_t ok = 0;  // bit ly: row ly reaches y <= ylim somewhere
    for (int32_t ly = by0; ly <= by1; ++ly, r_dy -= r_step, kappa_dy -= kappa_step) {
      const int16_t w = q_sat16(q_round_shift(r_dy, 19));
      const int16_t yw = gs::simd::q_mulhrs(w, w);
      const int64_t rel = int64_t(s.mx) + q_floor_shift(kappa_dy, 16) - col0;
      int64_t j = q_floor_shift(rel + 128, 8);
      j = j < 0 ? 0 : (j > kTileSize - 1 ? kTileSize - 1 : j);
      v_j[ly] = q_sat16(q_round_shift(int64_t(s.s) * (rel - j * 256), 19));
      y_w[ly] = yw;
      off[ly] = int16_t(15 - j);
      ok |= uint32_t(yw <= s.ylim) << ly;
    }
    for (int32_t g = by0 / R; g <= by1 / R; ++g) {
      const uint32_t rows = (ok >> (g * R)) & ((1u << R) - 1);
      if (!rows) continue;
      Entry& e = buckets[g][bucket_count[g]++];
      for (int h = 0; h < R; ++h) {
        const int32_t ly = g * R + h;
        const bool in = (rows >> h) & 1;
        e.v_j[h] = in ? v_j[ly] : int16_t(0);
        e.y_w[h] = in ? y_w[ly] : int16_t(0);
        e.off[h] = in ? off[ly] : int16_t(0);
      }
      e.splat = uint8_t(nb);
      e.rows = uint8_t(rows);
    }
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
    Entry buckets[kGroups][kChunk];
    int32_t bucket_count[kGroups];
    const int32_t groups = (th + R - 1) / R;
    bool all_done = false;
    for (int32_t c0 = 0; c0 < count && !all_done; c0 += kChunk) {
      const int32_t cn = scalar::min(kChunk, count - c0);
      for (int32_t g = 0; g < kGroups; ++g) bucket_count[g] = 0;
      int32_t nb = 0;
      for (int32_t k = 0; k < cn; ++k) {
        const QSplat& s = splats[c0 + k];
        int32_t bx0, by0, bx1, by1;
        if (!q_support_box(s, x0, y0, tw, th, &bx0, &by0, &bx1, &by1)) continue;
        add_splat(s, k, x0, y0, by0, by1, &chunk[nb], buckets, bucket_count, nb);
        ++nb;
      }
      if (nb == 0) continue;
      for (int32_t g = 0; g < groups; ++g) {
        const int32_t en = bucket_count[g];
        if (en == 0) continue;
        const Entry* entries = buckets[g];
        for (int32_t lx0 = 0; lx0 < (R == 1 ? tw : L); lx0 += L) {
          const int o = g * R * kTileSize + lx0;
          M is_done = B::load_aligned(done + o) != B(int16_t(0));
          if (xsimd::all(is_done)) continue;
          B t = B::load_aligned(T + o), cr = B::load_aligned(acc[0] + o), cg = B::load_aligned(acc[1] + o);
          B cb = B::load_aligned(acc[2] + o), cd = B::load_aligned(acc[3] + o), cl(int16_t(0));
          for (int32_t n = 0; n < en; ++n) {
            const Entry& e = entries[n];
            const ChunkSplat& c = chunk[e.splat];
            B step, vj, yw;
            M live = !is_done;
            if constexpr (R == 1) {
              step = B::load_unaligned(c.step + (e.off[0] + lx0));
              vj = B(e.v_j[0]);
              yw = B(e.y_w[0]);
            } else {
              step = q_rows_load<Arch>(c.step + e.off[0], c.step + e.off[1]);
              vj = q_rows_broadcast<Arch>(e.v_j[0], e.v_j[1]);
              yw = q_rows_broadcast<Arch>(e.y_w[0], e.y_w[1]);
              live = live & q_rows_mask<Arch>(e.rows);
            }
            const B v = xsimd::max(xsimd::ssub(vj, step), B(int16_t(-32767)));
            const B y = xsimd::sadd(q_mulhrs(v, v), yw);
            const M in = (y <= broadcast2(c.ylim2)) & live;
            if (!xsimd::any(in)) continue;
            const B alpha = q_alpha(y, broadcast2(c.opacity2));
            const B alpha_t = q_mulhrs(alpha, t);  // = q_mulhrs(t, alpha)
            const B next = t - alpha_t;
            const M stop = in & (next < B(int16_t(kQTransmittanceStop)));
            const M use = in & !stop;
            const B w = xsimd::select(use, alpha_t, B(int16_t(0)));
            cr = xsimd::sadd(cr, q_mulhrs(w, broadcast2(c.rgb2[0])));
            cg = xsimd::sadd(cg, q_mulhrs(w, broadcast2(c.rgb2[1])));
            cb = xsimd::sadd(cb, q_mulhrs(w, broadcast2(c.rgb2[2])));
            if (kDepth) cd = xsimd::sadd(cd, q_mulhrs(w, broadcast2(c.depth2)));
            t = xsimd::select(use, next, t);
            cl = xsimd::select(use, broadcast2(c.index2), cl);
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
