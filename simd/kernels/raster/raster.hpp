// SPDX-License-Identifier: MIT
// xsimd tile rasteriser (forward and backward), templated on the architecture. Lanes run over a
// pixel batch: in the forward two tile rows of N / 2 columns, the rows interleaved lane by lane
// (batch_index), in the backward N columns of one row. Each splat is clipped to the box outside
// which its alpha is provably below 1/255 (splat_support in splat.h, computed once per Gaussian),
// so small splats touch only a few batches.
//
// Forward: batch-major. Splats are taken in chunks of kChunk (boxes precomputed on the stack); for
// each pixel batch the state (T, colour, depth, last) stays in registers while the chunk's splats
// are blended, and a batch whose pixels have all stopped leaves the loop early. The blend step has
// no data-dependent branch: skipping a splat that no lane reaches saved an exp but cost more in
// mispredicted branches (tile replay of a snowmiku_plush training view: forward 0.73x on avx512,
// 0.83x on avx2 without them). For the same reason the chunk's splats are bucketed by the pixel
// batches (row pair and column batch) their box covers, and the inner loop blends every splat of
// its bucket with no test (buckets by row alone, with a branch per splat and column batch, took
// 1.03x on avx2 and 1.09x on sse2).
// In both passes the exponent's per-row terms of a splat are computed for all 16 rows a vector at
// a time before its pixels are visited, and the pixel offset is taken as pixel minus mean (the
// negated dx, exact), so a blend step does no scalar work and takes the splat's constants as
// broadcast memory operands: 5-7 % faster tile kernels on avx512 and avx2, bit-identical results.
// Backward: splat-major (gradients accumulate in registers per splat, one horizontal sum per
// splat). The colour behind each splat enters only through one per-pixel scalar, the cotangent-
// weighted light already blended behind it (see bwd), so a step loads and stores little state.
//
// Semantics are those of raster_ref.cpp, which is the spec. Rounding differs slightly: the
// exponent is evaluated in base 2 per row as (A' dx + B') dx + C' with coefficients pre-scaled by
// log2(e), and 2^x is a degree-6 polynomial (relative error < 3e-7), so results agree with the
// reference to a few 1e-7 relative, and threshold decisions may flip at exact ties.
//
// Included only by the per-ISA translation units in ../variants/, which instantiate the kernels for
// one Arch each; never include it from code compiled with baseline flags.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"
#include "../madd.hpp"
#include "../lane_sums.hpp"

#include "gs/simd/splat.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

constexpr int kTilePixels = kTileSize * kTileSize;

struct TileGeometry {
  int32_t x0, y0, w, h;  // first pixel, size in pixels (w, h <= kTileSize at the image border)
};

inline TileGeometry tile_geometry(int32_t width, int32_t height, int32_t tile_x, int32_t tile_y) {
  TileGeometry g;
  g.x0 = tile_x * kTileSize;
  g.y0 = tile_y * kTileSize;
  g.w = scalar::min(kTileSize, width - g.x0);
  g.h = scalar::min(kTileSize, height - g.y0);
  return g;
}

// Inclusive tile-local pixel box [bx0, bx1] x [by0, by1] where the splat can reach alpha >= 1/255,
// from the support fields of its record: the pixels whose centres lie within [ext_x, ext_y] of its
// mean (splat_support holds the rounding margin). Returns false if it reaches no pixel of the tile.
inline bool splat_support_box(const float* s, const TileGeometry& g, int32_t* bx0, int32_t* by0, int32_t* bx1,
                              int32_t* by1) {
  const float ex = s[kSplatExtX], ey = s[kSplatExtY];
  if (!(ex >= 0.0f)) return false;  // alpha < 1/255 everywhere
  // Pixel centre of local column i is x0 + i + 0.5, at offset i - lx from the mean.
  const float lx = s[kSplatMx] - float(g.x0) - 0.5f, ly = s[kSplatMy] - float(g.y0) - 0.5f;
  const float fx0 = scalar::max(lx - ex, -1.0f), fx1 = scalar::min(lx + ex, float(kTileSize));
  const float fy0 = scalar::max(ly - ey, -1.0f), fy1 = scalar::min(ly + ey, float(kTileSize));
  if (!(fx0 <= fx1) || !(fy0 <= fy1)) return false;
  *bx0 = scalar::max(0, int32_t(scalar::ceil(fx0)));
  *bx1 = scalar::min(g.w - 1, int32_t(scalar::floor(fx1)));
  *by0 = scalar::max(0, int32_t(scalar::ceil(fy0)));
  *by1 = scalar::min(g.h - 1, int32_t(scalar::floor(fy1)));
  return *bx0 <= *bx1 && *by0 <= *by1;
}

// 2^x for x <= 0 (inputs below -100 give 2^-100): x = n + r with n an integer and r in [-0.5, 0.5],
// 2^r by its degree-6 Taylor polynomial, 2^n added to the exponent bits. The polynomial is evaluated
// in Estrin's form (3 dependent multiply-adds instead of Horner's 6: the blend step waits on this
// chain; 3 % faster tile kernels) at a relative error < 3e-7 (Horner's: 2.2e-7, float rounding included).
// The kernels evaluate the exponent pre-scaled by log2(e) (and the forward adds log2(opacity)), so
// exp needs no range-reduction multiplies and alpha no opacity multiply.
template <class B>
inline B exp2_nonpositive(B x) {
  using I = xsimd::batch<int32_t, typename B::arch_type>;
  x = xsimd::max(x, B(-100.0f));
  const B n = xsimd::nearbyint(x);
  const B r = x - n;
  const B r2 = r * r;
  const B r4 = r2 * r2;
  const B lo = madd(B(6.931471805599453e-1f), r, B(1.0f));
  const B mid = madd(B(5.550410866482158e-2f), r, B(2.402265069591007e-1f));
  const B hi = madd(B(1.5403530393381606e-4f), r2, madd(B(1.3333558146428443e-3f), r, B(9.618129107628477e-3f)));
  const B p = madd(hi, r4, madd(mid, r2, lo));
  const I bits = xsimd::bitwise_cast<I>(p) + (xsimd::to_int(n) << 23);
  return xsimd::bitwise_cast<B>(bits);
}

constexpr float kLog2e = 1.44269504088896341f;

template <class Arch>
struct RasterKernels {
  using B = xsimd::batch<float, Arch>;
  using M = xsimd::batch_bool<float, Arch>;
  static constexpr int N = int(B::size);
  static constexpr int kChunk = 128;  // splats per forward chunk (the buckets index it with uint8_t)
  static_assert(kTileSize % N == 0, "tile rows must hold a whole number of batches");

  // Lane offsets 0.5, 1.5, ... for pixel centres.
  static B lane_centres() {
    alignas(64) float v[N];
    for (int i = 0; i < N; ++i) v[i] = float(i) + 0.5f;
    return B::load_aligned(v);
  }

  // The forward's pixel batches: N lanes over two tile rows and N / 2 columns, the rows interleaved
  // lane by lane (lane l: row 2 q + (l & 1), column h N / 2 + l / 2), so a splat's two per-row
  // terms enter a step as one 64-bit broadcast. A splat narrower than N / 2 columns then costs one
  // step per row pair instead of one per row (16 lanes: 12 % fewer lane evaluations in a
  // snowmiku_plush training iteration; docs/MODEL.md). The per-pixel state is stored batch by batch.
  // The backward keeps batches of one row (two-row batches there change its lane sums' order: see
  // docs/MODEL.md).
  static constexpr int kBatchCols = N / 2;                       // columns per batch
  static constexpr int kColBatches = kTileSize / kBatchCols;     // batches per row pair
  static constexpr int kRowPairs = kTileSize / 2;
  static_assert(N % 2 == 0, "a batch is two rows of N / 2 columns");
  // Index of tile-local pixel (lx, ly) in batch-ordered state.
  static int batch_index(int lx, int ly) {
    return ((ly >> 1) * kColBatches + lx / kBatchCols) * N + (lx % kBatchCols) * 2 + (ly & 1);
  }
  // Lane column offsets 0.5, 0.5, 1.5, 1.5, ... (pixel centres of a batch's columns).
  static B pair_lane_centres() {
    alignas(64) float v[N];
    for (int i = 0; i < N; ++i) v[i] = float(i >> 1) + 0.5f;
    return B::load_aligned(v);
  }
  // (p[0], p[1], p[0], p[1], ...): a row pair's terms, each to the lanes of its row.
  static B pair_broadcast(const float* p) {
#if defined(__ARM_NEON) && !defined(__aarch64__)
    if constexpr (std::is_same<Arch, xsimd::neon>::value) {
      const float32x2_t v = vld1_f32(p);
      return B(vcombine_f32(v, v));
    } else
#endif
    {
      double d;
      std::memcpy(&d, p, sizeof d);
      return xsimd::bitwise_cast<B>(xsimd::batch<double, Arch>(d));
    }
  }

  // Pixel-centre y of each row of the tile that starts at pixel row y0.
  static void tile_row_centres(int32_t y0, float* out) {
    for (int ly = 0; ly < kTileSize; ++ly) out[ly] = float(y0 + ly) + 0.5f;
  }

  // The exponent's per-row terms of splat record s for all 16 tile rows, a vector of rows at a
  // time (see ChunkRows): b = -(neg_b dy) and c = half_c dy dy with dy = my - row centre, in base 2;
  // dy itself too when dy_out is not null (the backward's moments need it).
  static void row_terms(const float* s, const float* row_centres, float* b, float* c, float* dy_out) {
    const B b_negated(kLog2e * s[kSplatB]), half_c(-0.5f * kLog2e * s[kSplatC]), my(s[kSplatMy]);
    for (int y = 0; y < kTileSize; y += N) {
      const B dy = my - B::load_aligned(row_centres + y);
      if (dy_out) dy.store_aligned(dy_out + y);
      (b_negated * dy).store_aligned(b + y);
      (half_c * dy * dy).store_aligned(c + y);
    }
  }

  // A splat as the forward's inner loop wants it: the exponent's x coefficient pre-scaled (by -1/2
  // and by log2(e), so the exponent is in base 2) and the opacity as its base-2 log added to the
  // exponent. Its per-row terms are in ChunkRows.
  struct ChunkSplat {
    float mx, half_a, log2_opacity, index1;
    float rgbd[4];
  };
  // The exponent's terms that depend only on the splat and the tile row, for all 16 rows: with
  // dy = my - pixel_y and the pixel offset taken as px - mx (the negated dx, so the inner loop
  // subtracts the broadcast mean from the pixel centres in one instruction), power =
  // (half_a (px - mx) + b) (px - mx) + c with b = -(neg_b dy) and c = half_c dy dy, the same
  // floats as (half_a dx + neg_b dy) dx + half_c dy dy (negation is exact). Computed once per splat
  // a vector of rows at a time instead of once per splat, row and batch in the inner loop.
  struct ChunkRows {
    alignas(64) float b[kTileSize];
    alignas(64) float c[kTileSize];
  };

  static void fwd(const RasterParams* p, int32_t tile_x, int32_t tile_y, const float* splats, int32_t count,
                  float* out_rgb, float* out_T, int32_t* out_last, float* out_depth) {
    const TileGeometry g = tile_geometry(p->width, p->height, tile_x, tile_y);
    // Per-pixel state in batch order (batch_index).
    alignas(64) float T[kTilePixels], r[kTilePixels], gr[kTilePixels], bl[kTilePixels], dep[kTilePixels];
    alignas(64) float last[kTilePixels], done[kTilePixels];  // last as float: exact below 2^24 records
    for (int ly = 0; ly < kTileSize; ++ly)
      for (int lx = 0; lx < kTileSize; ++lx) {
        const int i = batch_index(lx, ly);
        T[i] = 1.0f; r[i] = gr[i] = bl[i] = dep[i] = 0.0f; last[i] = 0.0f;
        done[i] = (lx < g.w && ly < g.h) ? 0.0f : 1.0f;  // pixels outside the image never take part
      }
    const B centres = pair_lane_centres();
    // One chunk of splats, packed for the inner loop, and bucketed by the pixel batches (row pair,
    // column batch) their box covers: the inner loop blends every splat of its bucket.
    alignas(64) float row_centres[kTileSize];
    tile_row_centres(g.y0, row_centres);
    ChunkSplat chunk[kChunk];
    ChunkRows chunk_rows[kChunk];
    uint8_t buckets[kRowPairs][kColBatches][kChunk];
    int32_t bucket_count[kRowPairs][kColBatches];
    const int32_t pairs = (g.h + 1) / 2, col_batches = (g.w + kBatchCols - 1) / kBatchCols;
    bool all_done = false;
    for (int32_t c0 = 0; c0 < count && !all_done; c0 += kChunk) {
      const int32_t cn = scalar::min(kChunk, count - c0);
      scalar::fill(&bucket_count[0][0], &bucket_count[0][0] + kRowPairs * kColBatches, 0);
      int32_t nb = 0;
      for (int32_t k = 0; k < cn; ++k) {
        const float* s = splats + size_t(c0 + k) * kSplatStride;
        int32_t bx0, by0, bx1, by1;
        if (!splat_support_box(s, g, &bx0, &by0, &bx1, &by1)) continue;
        ChunkSplat& c = chunk[nb];
        c.mx = s[kSplatMx];
        c.half_a = -0.5f * kLog2e * s[kSplatA];
        c.log2_opacity = scalar::log2(s[kSplatOpacity]);
        row_terms(s, row_centres, chunk_rows[nb].b, chunk_rows[nb].c, nullptr);
        c.rgbd[0] = s[kSplatR]; c.rgbd[1] = s[kSplatG]; c.rgbd[2] = s[kSplatBlue]; c.rgbd[3] = s[kSplatDepth];
        c.index1 = float(c0 + k + 1);
        for (int32_t q = by0 / 2; q <= by1 / 2; ++q)
          for (int32_t b = bx0 / kBatchCols; b <= bx1 / kBatchCols; ++b) buckets[q][b][bucket_count[q][b]++] = uint8_t(nb);
        ++nb;
      }
      if (nb == 0) continue;
      for (int32_t q = 0; q < pairs; ++q) {
        for (int32_t h = 0; h < col_batches; ++h) {
          const uint8_t* bucket = buckets[q][h];
          const int32_t bucket_n = bucket_count[q][h];
          if (bucket_n == 0) continue;
          const int o = (q * kColBatches + h) * N;
          M is_done = B::load_aligned(done + o) != B(0.0f);
          if (xsimd::all(is_done)) continue;
          B t = B::load_aligned(T + o), cr = B::load_aligned(r + o), cg = B::load_aligned(gr + o);
          B cb = B::load_aligned(bl + o), cd = B::load_aligned(dep + o), cl = B::load_aligned(last + o);
          const B px = B(float(g.x0 + h * kBatchCols)) + centres;
          const int row = 2 * q;
          for (int32_t j = 0; j < bucket_n; ++j) {
            const ChunkSplat& c = chunk[bucket[j]];
            const ChunkRows& rows = chunk_rows[bucket[j]];
            const B dx_negated = px - B(c.mx);
            const B power = madd(madd(B(c.half_a), dx_negated, pair_broadcast(rows.b + row)), dx_negated,
                                 pair_broadcast(rows.c + row));
            const B raw = exp2_nonpositive(power + B(c.log2_opacity));
            const B alpha = xsimd::min(raw, B(kAlphaMax));
            const M contributes = (power <= B(0.0f)) & (alpha >= B(kAlphaMin)) & !is_done;
            const B next_t = t * (B(1.0f) - alpha);
            const M stop = contributes & (next_t < B(kTransmittanceMin));
            const M use = contributes & !stop;
            const B w = xsimd::select(use, alpha * t, B(0.0f));
            cr = madd(B(c.rgbd[0]), w, cr);
            cg = madd(B(c.rgbd[1]), w, cg);
            cb = madd(B(c.rgbd[2]), w, cb);
            cd = madd(B(c.rgbd[3]), w, cd);
            t = xsimd::select(use, next_t, t);
            cl = xsimd::select(use, B(c.index1), cl);
            // A lane stopping is a rare, unpredictable event: fold it in without a branch and test
            // for a finished batch every 8 splats (a pattern the predictor learns).
            is_done = is_done | stop;
            if ((j & 7) == 7 && xsimd::all(is_done)) break;
          }
          t.store_aligned(T + o); cr.store_aligned(r + o); cg.store_aligned(gr + o); cb.store_aligned(bl + o);
          cd.store_aligned(dep + o); cl.store_aligned(last + o);
          xsimd::select(is_done, B(1.0f), B(0.0f)).store_aligned(done + o);
        }
      }
      all_done = true;
      for (int i = 0; i < kTilePixels && all_done; ++i) all_done = done[i] != 0.0f;
    }
    for (int32_t ly = 0; ly < g.h; ++ly) {
      for (int32_t lx = 0; lx < g.w; ++lx) {
        const int o = batch_index(lx, ly);
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
    scalar::fill(v_splats, v_splats + size_t(count) * kSplatStride, 0.0f);
    const TileGeometry g = tile_geometry(p->width, p->height, tile_x, tile_y);
    // Per-pixel state, walking back to front. With v the pixel's cotangent, T_i the transmittance in
    // front of splat i and c_i its colour, the light blended behind splat j, weighted by v, is
    //   behind_j = sum_{i > j} (c_i . v) alpha_i T_i + T_final (background . v),
    // and d(pixel . v) / d alpha_j = (c_j . v) T_j - behind_j / (1 - alpha_j) (the reference's
    // colour-behind form, raster_ref.cpp, multiplied out). behind starts at the background term
    // and each splat adds its own term once its gradient is taken: one scalar of state per pixel.
    alignas(64) float T[kTilePixels], last[kTilePixels], behind_v[kTilePixels];
    alignas(64) float vr[kTilePixels], vg[kTilePixels], vb[kTilePixels];
    int32_t max_last = 0;
    for (int i = 0; i < kTilePixels; ++i) {
      const int lx = i % kTileSize, ly = i / kTileSize;
      const bool inside = lx < g.w && ly < g.h;
      const size_t pix = inside ? size_t(g.y0 + ly) * p->width + (g.x0 + lx) : 0;
      T[i] = inside ? final_T[pix] : 1.0f;
      last[i] = inside ? float(last_in[pix]) : 0.0f;  // outside pixels: no contributor, never active
      max_last = scalar::max(max_last, inside ? last_in[pix] : 0);
      vr[i] = inside ? v_rgb[3 * pix] : 0.0f;
      vg[i] = inside ? v_rgb[3 * pix + 1] : 0.0f;
      vb[i] = inside ? v_rgb[3 * pix + 2] : 0.0f;
      behind_v[i] = T[i] * (p->background[0] * vr[i] + p->background[1] * vg[i] + p->background[2] * vb[i]);
    }
    // Pixel-centre x of each column batch, y of each tile row.
    constexpr int kBatches = kTileSize / N;
    B batch_centres[kBatches];
    for (int b = 0; b < kBatches; ++b) batch_centres[b] = B(float(g.x0 + b * N)) + lane_centres();
    alignas(64) float row_centres[kTileSize];
    tile_row_centres(g.y0, row_centres);
    // Each splat's 9 accumulators are summed across lanes N splats at a time (xsimd::haddp: one
    // transposing reduction instead of 9 horizontal sums per splat).
    alignas(64) float pending[kSums][N * N];
    int32_t pending_index[N];
    int pending_count = 0;
    for (int32_t i = scalar::min(max_last, count) - 1; i >= 0; --i) {
      const float* s = splats + size_t(i) * kSplatStride;
      int32_t bx0, by0, bx1, by1;
      if (!splat_support_box(s, g, &bx0, &by0, &bx1, &by1)) continue;
      const B threshold(kLog2e * (-0.5f * s[kSplatTwoTau] - 1e-3f));
      const B idx = B(float(i));
      const B cr(s[kSplatR]), cg(s[kSplatG]), cb(s[kSplatBlue]), op(s[kSplatOpacity]);
      const B half_a2(-0.5f * kLog2e * s[kSplatA]);  // base-2 exponent coefficients
      // The exponent's per-row terms (as in fwd, with the pixel offset taken as pixel minus mean).
      alignas(64) float row_dy[kTileSize], row_b2[kTileSize], row_c2[kTileSize];
      row_terms(s, row_centres, row_b2, row_c2, row_dy);
      B acc_r(0.0f), acc_g(0.0f), acc_b(0.0f), acc_op(0.0f);
      // Moments of v_power over the pixels, in the negated dx: sum -dx, dy, dx^2, -dx dy, dy^2.
      B sum_dx(0.0f), sum_dy(0.0f), sum_dxdx(0.0f), sum_dxdy(0.0f), sum_dydy(0.0f);
      const B mx(s[kSplatMx]);
      const int32_t c0 = bx0 / N * N, c1 = bx1 / N * N;
      for (int32_t ly = by0; ly <= by1; ++ly) {
        const B dy(row_dy[ly]), row_b(row_b2[ly]), row_c(row_c2[ly]);
        for (int32_t lx = c0; lx <= c1; lx += N) {
          const int o = ly * kTileSize + lx;
          const M active = idx < B::load_aligned(last + o);
          if (!xsimd::any(active)) continue;
          const B dx_negated = batch_centres[lx / N] - mx;  // pixel minus mean
          const B power = madd(madd(half_a2, dx_negated, row_b), dx_negated, row_c);  // base 2
          if (!xsimd::any(power >= threshold)) continue;
          const B G = exp2_nonpositive(power);
          const B raw = op * G;
          const M clamped = raw > B(kAlphaMax);
          const B alpha = xsimd::select(clamped, B(kAlphaMax), raw);
          const M use = (power <= B(0.0f)) & (alpha >= B(kAlphaMin)) & active;
          const B inv_one_minus = B(1.0f) / (B(1.0f) - alpha);  // one division serves both uses below
          const B t_old = B::load_aligned(T + o);
          const B t = xsimd::select(use, t_old * inv_one_minus, t_old);
          t.store_aligned(T + o);
          const B pvr = B::load_aligned(vr + o), pvg = B::load_aligned(vg + o), pvb = B::load_aligned(vb + o);
          const B w = xsimd::select(use, alpha * t, B(0.0f));
          acc_r = madd(w, pvr, acc_r);
          acc_g = madd(w, pvg, acc_g);
          acc_b = madd(w, pvb, acc_b);
          const B cv = madd(cr, pvr, madd(cg, pvg, cb * pvb));  // this splat's colour . v
          const B behind = B::load_aligned(behind_v + o);
          const B v_alpha = cv * t - behind * inv_one_minus;
          madd(cv, w, behind).store_aligned(behind_v + o);  // w = 0 where the splat is not used
          const B v_op = xsimd::select(use & !clamped, G * v_alpha, B(0.0f));
          acc_op += v_op;
          // The conic and mean gradients are linear in these moments of v_power over the pixels
          // (the conic is constant per splat), so the step only accumulates the moments.
          const B v_power = op * v_op;
          const B vp_dx = v_power * dx_negated, vp_dy = v_power * dy;
          sum_dx += vp_dx;
          sum_dy += vp_dy;
          sum_dxdx = madd(vp_dx, dx_negated, sum_dxdx);
          sum_dxdy = madd(vp_dx, dy, sum_dxdy);
          sum_dydy = madd(vp_dy, dy, sum_dydy);
        }
      }
      const int slot = pending_count * N;
      acc_r.store_aligned(pending[0] + slot);
      acc_g.store_aligned(pending[1] + slot);
      acc_b.store_aligned(pending[2] + slot);
      acc_op.store_aligned(pending[3] + slot);
      sum_dx.store_aligned(pending[4] + slot);
      sum_dy.store_aligned(pending[5] + slot);
      sum_dxdx.store_aligned(pending[6] + slot);
      sum_dxdy.store_aligned(pending[7] + slot);
      sum_dydy.store_aligned(pending[8] + slot);
      pending_index[pending_count++] = i;
      if (pending_count == N) {
        flush(splats, pending, pending_index, pending_count, v_splats);
        pending_count = 0;
      }
    }
    if (pending_count > 0) flush(splats, pending, pending_index, pending_count, v_splats);
  }

  static constexpr int kSums = 9;  // per splat: r, g, b, opacity, then the moments dx, dy, dxdx, dxdy, dydy

  // Writes the gradients of the n (<= N) pending splats: lane sums of their accumulators, and the
  // mean and conic gradients from the moments.
  static void flush(const float* splats, float (*pending)[N * N], const int32_t* index, int n, float* v_splats) {
    alignas(64) float sums[kSums][N];
    for (int f = 0; f < kSums; ++f) {
      B rows[N];
      for (int k = 0; k < N; ++k) rows[k] = k < n ? B::load_aligned(pending[f] + k * N) : B(0.0f);
      lane_sums(rows).store_aligned(sums[f]);
    }
    for (int k = 0; k < n; ++k) {
      const float* s = splats + size_t(index[k]) * kSplatStride;
      float* gs = v_splats + size_t(index[k]) * kSplatStride;
      gs[kSplatR] = sums[0][k];
      gs[kSplatG] = sums[1][k];
      gs[kSplatBlue] = sums[2][k];
      gs[kSplatOpacity] = sums[3][k];
      // power = -(a dx^2 + 2 b dx dy + c dy^2) / 2 with dx = mean_x - pixel_x: d power / d mean_x =
      // -(a dx + b dy), d power / d a = -dx^2 / 2, d / d b = -dx dy, d / d c = -dy^2 / 2.
      // sums[4] and sums[7] were taken in the negated dx (bwd).
      const float m_dx = -sums[4][k], m_dy = sums[5][k];
      gs[kSplatMx] = -(s[kSplatA] * m_dx + s[kSplatB] * m_dy);
      gs[kSplatMy] = -(s[kSplatC] * m_dy + s[kSplatB] * m_dx);
      gs[kSplatA] = -0.5f * sums[6][k];
      gs[kSplatB] = sums[7][k];
      gs[kSplatC] = -0.5f * sums[8][k];
    }
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
