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

#include <cstddef>
#include <cstdint>
#include <cstring>
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

// The constants of the blend loop. GCC re-creates broadcast constants inside the loop from a
// general register (a shuffle-port instruction each, every iteration); an empty asm statement
// that "changes" them makes that impossible, so they stay in registers.
template <class A>
struct QBlendConsts {
  using B = xsimd::batch<int16_t, A>;
  B poly[5], alpha_max, stop, v_min;
  QBlendConsts() {
    for (int k = 0; k < 5; ++k) poly[k] = B(kQExpPoly[k]);
    alpha_max = B(int16_t(kQAlphaMax));
    stop = B(int16_t(kQTransmittanceStop));
    v_min = B(int16_t(-32767));
    for (B* b : {&poly[0], &poly[1], &poly[2], &poly[3], &poly[4], &alpha_max, &stop, &v_min}) keep_in_register(*b);
  }
  static void keep_in_register(B& b) {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
    typename B::register_type r = b;
    __asm__("" : "+v"(r));
    b = B(r);
#elif defined(__GNUC__) && (defined(__aarch64__) || defined(__ARM_NEON))
    typename B::register_type r = b;
    __asm__("" : "+w"(r));
    b = B(r);
#else
    (void)b;
#endif
  }
};

// alpha = min(o h(y / 8)^8, 0.99) per lane (q_alpha in gs/simd/qsplat.h).
template <class A>
inline xsimd::batch<int16_t, A> q_alpha(const xsimd::batch<int16_t, A>& y, const xsimd::batch<int16_t, A>& opacity,
                                        const QBlendConsts<A>& k) {
  using B = xsimd::batch<int16_t, A>;
  const B z = xsimd::sadd(y, y);
  B h = k.poly[4];
  for (int i = 3; i >= 0; --i) h = xsimd::sadd(k.poly[i], q_mulhrs(h, z));
  B e = q_mulhrs(h, h);
  e = q_mulhrs(e, e);
  e = q_mulhrs(e, e);
  return xsimd::min(q_mulhrs(e, opacity), k.alpha_max);
}

// Tile rows per register: two on AVX-512 (32 int16 lanes), else one (16 lanes) or half of one (8).
// With two, the rows are interleaved: lane 2 i + h is column i of the register's row h, so that a
// pair of per-row values stored next to each other is one 32-bit broadcast.
template <class A>
constexpr int q_rows_per_register() {
  return int(xsimd::batch<int16_t, A>::size) >= 2 * kTileSize ? int(xsimd::batch<int16_t, A>::size) / kTileSize : 1;
}

// Two-row registers (AVX-512 only). Interleaved step rows: lane 2 i = lo[i], lane 2 i + 1 = hi[i].
template <class A>
inline xsimd::batch<int16_t, A> q_rows_interleave(const int16_t* lo, const int16_t* hi) {
  using B = xsimd::batch<int16_t, A>;
#if defined(__AVX512BW__)
  if constexpr (B::size == 32) {
    const __m512i l = _mm512_castsi256_si512(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(lo)));
    const __m512i h = _mm512_castsi256_si512(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(hi)));
    const __m512i idx = _mm512_set_epi16(47, 15, 46, 14, 45, 13, 44, 12, 43, 11, 42, 10, 41, 9, 40, 8, 39, 7, 38, 6, 37, 5,
                                         36, 4, 35, 3, 34, 2, 33, 1, 32, 0);
    return B(_mm512_permutex2var_epi16(l, idx, h));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: two rows per register only on AVX-512");
    (void)hi;
    return B::load_unaligned(lo);
  }
}
// Lane bits of the rows set in `rows` (bit h: the register's row h), interleaved.
constexpr uint32_t q_rows_lane_bits(uint32_t rows) {
  return (rows & 1 ? 0x55555555u : 0u) | (rows & 2 ? 0xAAAAAAAAu : 0u);
}
template <class A>
inline xsimd::batch_bool<int16_t, A> q_rows_mask(uint32_t lane_bits) {
  using M = xsimd::batch_bool<int16_t, A>;
#if defined(__AVX512BW__)
  if constexpr (xsimd::batch<int16_t, A>::size == 32) {
    return M(typename M::register_type(lane_bits));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: two rows per register only on AVX-512");
    return M(lane_bits != 0);
  }
}
// int64 lanes (already in int16 range) to int16, stored (AVX-512 vpmovqw).
template <class A>
inline void q_store_narrow16(const xsimd::batch<int64_t, A>& v, int16_t* out) {
#if defined(__AVX512BW__)
  if constexpr (xsimd::batch<int64_t, A>::size == 8) {
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm512_cvtepi64_epi16(v));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: vector row setup only on AVX-512");
    (void)out;
  }
}
// a b for int64 lanes whose values fit int32 (AVX-512 vpmuldq: one uop, where vpmullq is three).
template <class A>
inline xsimd::batch<int64_t, A> q_mul_int32(const xsimd::batch<int64_t, A>& a, const xsimd::batch<int64_t, A>& b) {
#if defined(__AVX512BW__)
  if constexpr (xsimd::batch<int64_t, A>::size == 8) {
    return xsimd::batch<int64_t, A>(_mm512_mul_epi32(a, b));
  } else
#endif
  {
    return a * b;
  }
}
template <class A>
inline uint32_t q_mask_bits(const xsimd::batch_bool<int64_t, A>& m) {
#if defined(__AVX512BW__)
  if constexpr (xsimd::batch<int64_t, A>::size == 8) {
    return uint32_t(__mmask8(m));
  } else
#endif
  {
    static_assert(sizeof(A) == 0, "qraster: vector row setup only on AVX-512");
    return 0;
  }
}

// int32 lanes (already in int16 range) to int16, stored: 16 lanes (AVX-512 vpmovdw) or 8 (AVX2).
template <class A>
inline void q_store_narrow16(const xsimd::batch<int32_t, A>& v, int16_t* out) {
  constexpr size_t n = xsimd::batch<int32_t, A>::size;
#if defined(__AVX512BW__)
  if constexpr (n == 16) {
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm512_cvtepi32_epi16(v));
    return;
  }
#endif
#if defined(__AVX2__)
  if constexpr (n == 8) {
    const __m256i r = v;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm_packs_epi32(_mm256_castsi256_si128(r), _mm256_extracti128_si256(r, 1)));
    return;
  }
#endif
  alignas(64) int32_t tmp[n];
  v.store_aligned(tmp);
  for (size_t i = 0; i < n; ++i) out[i] = int16_t(tmp[i]);
}
// Bit i set where lane i of m is true.
template <class A>
inline uint32_t q_mask_bits(const xsimd::batch_bool<int32_t, A>& m) {
  constexpr size_t n = xsimd::batch<int32_t, A>::size;
#if defined(__AVX512BW__)
  if constexpr (n == 16) return uint32_t(__mmask16(m));
#endif
#if defined(__AVX2__)
  if constexpr (n == 8) return uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(__m256i(m))));
#endif
  alignas(64) int32_t tmp[n];
  xsimd::select(m, xsimd::batch<int32_t, A>(1), xsimd::batch<int32_t, A>(0)).store_aligned(tmp);
  uint32_t bits = 0;
  for (size_t i = 0; i < n; ++i) bits |= uint32_t(tmp[i]) << i;
  return bits;
}

template <class Arch>
struct QRasterKernels {
  using B = xsimd::batch<int16_t, Arch>;
  using M = xsimd::batch_bool<int16_t, Arch>;
  using B32 = xsimd::batch<int32_t, Arch>;
  static constexpr int L = int(B::size);
  static constexpr int R = q_rows_per_register<Arch>();  // tile rows per register (1 or 2)
  static constexpr int kGroups = kTileSize / R;             // registers rows of a tile
  static constexpr int kChunk = 128;  // splats per chunk
  static_assert(kTileSize % L == 0 || L == R * kTileSize, "a register holds part of a tile row or whole rows");
  static constexpr int kPixels = kTileSize * kTileSize;
  // How a splat's row values are computed: in int32 lanes on AVX2 and AVX-512 for splats whose
  // row centres are near the tile (nearly all), else in int64 lanes on AVX-512 (int64 multiply,
  // shift and min/max) and one row at a time elsewhere.
  static constexpr bool kRows32 = L >= kTileSize;
  static constexpr bool kRows64 = R == 2;

  // Index of pixel (ly, lx) in the tile's state arrays: row-major, or row pairs interleaved (R = 2).
  static constexpr int state_index(int ly, int lx) {
    return R == 2 ? (ly / 2) * 2 * kTileSize + 2 * lx + (ly & 1) : ly * kTileSize + lx;
  }

  // What the blend loop reads of one splat: its column-step table, the row values of q_splat_row
  // for each row of its support box (v at the nearest column j, w^2, and 15 - j, the step-table
  // offset that aligns column 0), and its constants, each stored twice in an int32 so that
  // broadcasting it is a 32-bit broadcast load.
  struct ChunkSplat {
    alignas(64) int16_t step[32];  // step[d + 15]: q_column_step over d columns, d in [-15, 15]; step[31] = 0
    alignas(4) int16_t v_j[kTileSize], y_w[kTileSize], off[kTileSize];
    int32_t ylim2, opacity2, rgb2[3], depth2, index2;  // ylim, opacity, colour, depth, chunk index + 1
  };
  static_assert(offsetof(QSplat, depth) == offsetof(QSplat, ylim) + 5 * sizeof(int32_t), "QSplat field order");
  static_assert(offsetof(ChunkSplat, depth2) == offsetof(ChunkSplat, ylim2) + 5 * sizeof(int32_t), "ChunkSplat field order");
  // A splat in the bucket of a register row: its index in the chunk, and (R = 2) the lanes of the
  // register's rows it reaches.
  struct Entry {
    uint32_t lanes;
    uint32_t splat;
  };

  static void fwd(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                  float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    if (out_depth) blend<true>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
    else blend<false>(p, tile_x, tile_y, splats, count, out_rgb, out_T, out_last, out_depth);
  }

  static int32_t twice(int32_t v) { return int32_t(uint32_t(uint16_t(v)) * 0x10001u); }
  static B broadcast2(int32_t v2) { return xsimd::bitwise_cast<B>(B32(v2)); }
  static int32_t pair(const int16_t* v) {  // v[0], v[1] as one int32 (for a 32-bit broadcast)
    int32_t x;
    std::memcpy(&x, v, sizeof(x));
    return x;
  }

  // Chunk setup of one splat: its constants, column-step table and row values (q_splat_row's, for
  // the rows of its support box at least); returns the rows of the box (bit ly) that reach
  // y <= ylim somewhere.
  static uint32_t setup_splat(const QSplat& s, int32_t k, int32_t x0, int32_t y0, int32_t by0, int32_t by1,
                              ChunkSplat* c) {
    // q_column_step(s, d) = sat16((d s + 2^10) >> 11): |d s| <= 15 2^25 fits int32.
    for (int d = 0; d < 32; ++d) {
      const int32_t v = ((d - 15) * s.s + 1024) >> 11;
      c->step[d] = int16_t(v < -32767 ? -32767 : (v > 32767 ? 32767 : v));
    }
    c->step[31] = 0;
    // ylim, opacity, rgb, depth are consecutive in both records (one vector op for the six).
    int32_t v6[6];
    std::memcpy(v6, &s.ylim, sizeof(v6));
    for (int i = 0; i < 6; ++i) v6[i] = twice(v6[i]);
    std::memcpy(&c->ylim2, v6, sizeof(v6));
    c->index2 = twice(k + 1);

    const int64_t col0 = int64_t(x0) * 256 + 128;
    const int64_t dy0 = int64_t(s.my) - (int64_t(y0) * 256 + 128);  // dy of the tile's row 0
    uint32_t ok = 0;
    bool have_rows = false;
    if constexpr (kRows32) have_rows = rows_int32(s, col0, dy0, c, &ok);
    if (!have_rows) {
      if constexpr (kRows64) ok = rows_int64(s, col0, dy0, c);
      else ok = rows_scalar(s, col0, dy0, by0, by1, c);
    }
    return ok & ((2u << by1) - 1) & ~((1u << by0) - 1);
  }

  // The row values of all 16 rows in int32 lanes, for a splat whose row centres lie within 128 px
  // of the tile's column 0 (false otherwise, and nothing written). Each int64 product of
  // q_splat_row is split so that every partial product fits int32 and the floors are exact:
  //   r dy + 2^18 = A - 256 r ly, A = r dy0 + 2^18 = qA 2^19 + mA, r = rh 2^11 + rl:
  //     w = qA - rh ly + floor((mA - 256 rl ly) / 2^19) (|qA| clamped to 2^20: saturated either way);
  //   kappa dy = K - 256 kappa ly, K = qK 2^16 + mK, kappa = kh 2^8 + kl:
  //     rel = mx - col0 + qK - kh ly + floor((mK - 256 kl ly) / 2^16);
  //   s X + 2^18 with X = rel - 256 j (|X| < 2^16), s = sh 2^11 + sl, P = sh X = ph 2^8 + pl:
  //     v_j = ph + floor((pl 2^11 + sl X + 2^18) / 2^19).
  static bool rows_int32(const QSplat& s, int64_t col0, int64_t dy0, ChunkSplat* c, uint32_t* ok) {
    const int64_t kappa_dy0 = int64_t(s.kappa) * dy0;
    const int64_t rel0 = int64_t(s.mx) - col0 + q_floor_shift(kappa_dy0, 16);
    const int64_t rel15 = int64_t(s.mx) - col0 + q_floor_shift(kappa_dy0 - int64_t(s.kappa) * 256 * (kTileSize - 1), 16);
    constexpr int64_t kNear = int64_t(1) << 15;  // rel is monotone in ly: both ends bound every row
    if (rel0 < -kNear || rel0 > kNear || rel15 < -kNear || rel15 > kNear) return false;
    using I = xsimd::batch<int32_t, Arch>;
    constexpr int L32 = int(I::size);
    alignas(64) int32_t iota[L32];
    for (int i = 0; i < L32; ++i) iota[i] = i;
    const int64_t a = int64_t(s.r) * dy0 + (int64_t(1) << 18);
    const int64_t qa = q_floor_shift(a, 19);
    const I qA(int32_t(qa < -(int64_t(1) << 20) ? -(int64_t(1) << 20) : (qa > (int64_t(1) << 20) ? (int64_t(1) << 20) : qa)));
    const I mA(int32_t(a & ((int64_t(1) << 19) - 1)));
    const I rh(s.r >> 11), rl256((s.r & 2047) << 8);
    const I C = I(int32_t(rel0)), mK = I(int32_t(kappa_dy0 & 0xFFFF));
    const I kh(s.kappa >> 8), kl256((s.kappa & 255) << 8);
    const I sh(s.s >> 11), sl(s.s & 2047);
    const I lo16(-32767), hi16(32767), ylim(s.ylim);
    uint32_t bits = 0;
    for (int32_t ly0 = 0; ly0 < kTileSize; ly0 += L32) {
      const I ly = I::load_aligned(iota) + I(ly0);
      const I w = xsimd::min(xsimd::max(qA - rh * ly + ((mA - rl256 * ly) >> 19), lo16), hi16);
      const I yw = (w * w + I(1 << 14)) >> 15;
      const I rel = C - kh * ly + ((mK - kl256 * ly) >> 16);
      const I j = xsimd::min(xsimd::max((rel + I(128)) >> 8, I(0)), I(kTileSize - 1));
      const I x = rel - (j << 8);
      const I p = sh * x;
      const I vj = xsimd::min(xsimd::max((p >> 8) + ((((p & I(255)) << 11) + sl * x + I(1 << 18)) >> 19), lo16), hi16);
      q_store_narrow16<Arch>(vj, c->v_j + ly0);
      q_store_narrow16<Arch>(yw, c->y_w + ly0);
      q_store_narrow16<Arch>(I(kTileSize - 1) - j, c->off + ly0);
      bits |= q_mask_bits<Arch>(yw <= ylim) << ly0;
    }
    *ok = bits;
    return true;
  }

  // The row values of all 16 rows in int64 lanes (AVX-512: vpmullq, vpsraq, vpminsq/vpmaxsq), for
  // any splat; the rows outside the box are masked off by the caller, their offsets stay in [0, 15].
  static uint32_t rows_int64(const QSplat& s, int64_t col0, int64_t dy0, ChunkSplat* c) {
    using B64 = xsimd::batch<int64_t, Arch>;
    constexpr int L64 = int(B64::size);
    alignas(64) int64_t iota[L64];
    for (int i = 0; i < L64; ++i) iota[i] = i;
    const B64 lo16(int64_t(-32767)), hi16(int64_t(32767)), half19(int64_t(1) << 18);
    uint32_t ok = 0;
    for (int32_t ly0 = 0; ly0 < kTileSize; ly0 += L64) {
      const B64 ly = B64::load_aligned(iota) + B64(int64_t(ly0));
      // r, kappa, ly and w fit int32: r_step ly = (r ly) 256, and so on.
      const B64 r_dy = B64(int64_t(s.r) * dy0) - (q_mul_int32<Arch>(B64(int64_t(s.r)), ly) << 8);
      const B64 kappa_dy = B64(int64_t(s.kappa) * dy0) - (q_mul_int32<Arch>(B64(int64_t(s.kappa)), ly) << 8);
      const B64 w = xsimd::min(xsimd::max((r_dy + half19) >> 19, lo16), hi16);
      const B64 yw = (q_mul_int32<Arch>(w, w) + B64(int64_t(1) << 14)) >> 15;
      const B64 rel = B64(int64_t(s.mx) - col0) + (kappa_dy >> 16);
      const B64 j = xsimd::min(xsimd::max((rel + B64(int64_t(128))) >> 8, B64(int64_t(0))), B64(int64_t(kTileSize - 1)));
      const B64 vj = xsimd::min(xsimd::max((B64(int64_t(s.s)) * (rel - (j << 8)) + half19) >> 19, lo16), hi16);
      q_store_narrow16<Arch>(vj, c->v_j + ly0);
      q_store_narrow16<Arch>(yw, c->y_w + ly0);
      q_store_narrow16<Arch>(B64(int64_t(15)) - j, c->off + ly0);
      ok |= q_mask_bits<Arch>(yw <= B64(int64_t(s.ylim))) << ly0;
    }
    return ok;
  }

  // The row values of rows by0..by1, one at a time, stepped by exact int64 increments.
  static uint32_t rows_scalar(const QSplat& s, int64_t col0, int64_t dy0, int32_t by0, int32_t by1, ChunkSplat* c) {
    const int64_t r_step = int64_t(s.r) * 256, kappa_step = int64_t(s.kappa) * 256;
    int64_t r_dy = int64_t(s.r) * (dy0 - 256 * by0), kappa_dy = int64_t(s.kappa) * (dy0 - 256 * by0);
    uint32_t ok = 0;
    for (int32_t ly = by0; ly <= by1; ++ly, r_dy -= r_step, kappa_dy -= kappa_step) {
      const int16_t w = q_sat16(q_round_shift(r_dy, 19));
      const int16_t yw = gs::simd::q_mulhrs(w, w);
      const int64_t rel = int64_t(s.mx) + q_floor_shift(kappa_dy, 16) - col0;
      int64_t j = q_floor_shift(rel + 128, 8);
      j = j < 0 ? 0 : (j > kTileSize - 1 ? kTileSize - 1 : j);
      c->v_j[ly] = q_sat16(q_round_shift(int64_t(s.s) * (rel - j * 256), 19));
      c->y_w[ly] = yw;
      c->off[ly] = int16_t(15 - j);
      ok |= uint32_t(yw <= s.ylim) << ly;
    }
    return ok;
  }

  // kDepth: accumulate depth too (registration's keyframes); the image-only forward skips it.
  template <bool kDepth>
  static void blend(const QRasterParams* p, int32_t tile_x, int32_t tile_y, const QSplat* splats, int32_t count,
                    float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    const int32_t x0 = tile_x * kTileSize, y0 = tile_y * kTileSize;
    const int32_t tw = scalar::min(kTileSize, p->width - x0), th = scalar::min(kTileSize, p->height - y0);
    alignas(64) int16_t T[kPixels], acc[4][kPixels], done[kPixels];
    int32_t last[kPixels];
    for (int ly = 0; ly < kTileSize; ++ly)
      for (int lx = 0; lx < kTileSize; ++lx) {
        const int i = state_index(ly, lx);
        T[i] = int16_t(kQOne);
        acc[0][i] = acc[1][i] = acc[2][i] = acc[3][i] = 0;
        last[i] = 0;
        done[i] = (lx < tw && ly < th) ? 0 : -1;
      }
    ChunkSplat chunk[kChunk];
    Entry buckets[kGroups][kChunk];
    int32_t bucket_count[kGroups];
    const int32_t groups = (th + R - 1) / R;
    const QBlendConsts<Arch> consts;
    bool all_done = false;
    for (int32_t c0 = 0; c0 < count && !all_done; c0 += kChunk) {
      const int32_t cn = scalar::min(kChunk, count - c0);
      for (int32_t g = 0; g < kGroups; ++g) bucket_count[g] = 0;
      int32_t nb = 0;
      for (int32_t k = 0; k < cn; ++k) {
        const QSplat& s = splats[c0 + k];
        int32_t bx0, by0, bx1, by1;
        if (!q_support_box(s, x0, y0, tw, th, &bx0, &by0, &bx1, &by1)) continue;
        const uint32_t ok = setup_splat(s, k, x0, y0, by0, by1, &chunk[nb]);
        if (!ok) continue;
        // Every bucket gets the entry written at its end, and keeps it where the splat reaches
        // one of its rows: a fixed loop without data-dependent branches (which rows a splat
        // reaches varies from splat to splat).
        for (int32_t g = 0; g < kGroups; ++g) {
          const uint32_t rows = (ok >> (g * R)) & ((1u << R) - 1);
          buckets[g][bucket_count[g]] = Entry{q_rows_lane_bits(rows), uint32_t(nb)};
          bucket_count[g] += rows != 0;
        }
        ++nb;
      }
      if (nb == 0) continue;
      for (int32_t g = 0; g < groups; ++g) {
        const int32_t en = bucket_count[g];
        if (en == 0) continue;
        const Entry* entries = buckets[g];
        const int32_t ly = g * R;  // the register's first row
        for (int32_t lx0 = 0; lx0 < (R == 1 ? tw : L); lx0 += L) {
          const int o = g * R * kTileSize + lx0;
          M is_done = B::load_aligned(done + o) != B(int16_t(0));
          if (xsimd::all(is_done)) continue;
          M not_done = !is_done;
          B t = B::load_aligned(T + o), cr = B::load_aligned(acc[0] + o), cg = B::load_aligned(acc[1] + o);
          B cb = B::load_aligned(acc[2] + o), cd = B::load_aligned(acc[3] + o), cl(int16_t(0));
          for (int32_t n = 0; n < en; ++n) {
            const Entry e = entries[n];
            const ChunkSplat& c = chunk[e.splat];
            B step, vj, yw;
            M live = not_done;
            if constexpr (R == 1) {
              step = B::load_unaligned(c.step + (c.off[ly] + lx0));
              vj = B(c.v_j[ly]);
              yw = B(c.y_w[ly]);
            } else {
              step = q_rows_interleave<Arch>(c.step + c.off[ly], c.step + c.off[ly + 1]);
              vj = broadcast2(pair(c.v_j + ly));
              yw = broadcast2(pair(c.y_w + ly));
              live = live & q_rows_mask<Arch>(e.lanes);
            }
            const B v = xsimd::max(xsimd::ssub(vj, step), consts.v_min);
            const B y = xsimd::sadd(q_mulhrs(v, v), yw);
            const M in = (y <= broadcast2(c.ylim2)) & live;
            if (!xsimd::any(in)) continue;
            const B alpha = q_alpha(y, broadcast2(c.opacity2), consts);
            const B alpha_t = q_mulhrs(alpha, t);  // = q_mulhrs(t, alpha)
            const B next = t - alpha_t;
            const M stop = in & (next < consts.stop);
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
              not_done = !is_done;
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
        const int o = state_index(ly, lx);
        const int16_t a4[4] = {acc[0][o], acc[1][o], acc[2][o], acc[3][o]};
        const size_t pix = size_t(y0 + ly) * size_t(p->width) + size_t(x0 + lx);
        qraster_write_pixel(p, T[o], a4, last[o], pix, out_rgb, out_T, out_last, out_depth);
      }
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
