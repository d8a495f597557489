// SPDX-License-Identifier: MIT
// xsimd decoder MLP (forward, backward) and Adam step, templated on the architecture.
//
// Every MLP product is a small matrix product C (+)= A Bm with lanes along the contiguous columns
// of Bm and C, and A read one scalar at a time and broadcast (no horizontal adds):
//   forward   hidden = relu(x W1^T + b1)      A = x [B, I],       Bm = W1^T [I, H]
//             y      = act2(hidden W2^T + b2) A = hidden [B, H],  Bm = W2^T [H, O]
//   backward  g      = v_y act2'(y)           (elementwise, [R, O] per chunk of R rows)
//             v_h    = (g W2) masked by hidden > 0       Bm = W2 [O, H]
//             v_W2  += g^T hidden              A = g^T (strided), Bm = hidden rows
//             v_W1^T += x^T v_h                A = x^T (strided), Bm = v_h rows
//             v_x    = v_h W1                  Bm = W1 [H, I]
// v_W1 is accumulated transposed ([I, Hp] on the stack, from v_W1^T at the call's start, written
// back at its end), so its products run with lanes along H, a whole number of vectors, instead of
// along I (hbgs: 52, padded to 64 on 16 lanes: a fifth of the lanes idle); every element still
// sums the same products in the same order, so the result is the same float.
// A register tile holds kMR rows x kNV vectors of C; per reduction step it loads kNV vectors of Bm
// and broadcasts kMR scalars of A, so the accumulators stay in registers for the whole reduction.
// Operands read as Bm must have a row length that is a multiple of the lane count: the transposed
// weights are built once per call in a stack buffer, zero-padded to whole vectors; W1, W2 and
// hidden are used in place when their row length already is, and otherwise copied (zero-padded)
// per call (weights) or per chunk of rows (hidden); x is only ever broadcast, so never copied. The
// weight gradients are reductions over the batch: each chunk of R rows is reduced in registers
// (K = R) and added to v_W1^T / v_W2 once per chunk; v_b1 / v_b2 are summed in a stack buffer and added once per call. C rows whose length
// is not a multiple of the lanes end with a partial store, so nothing is written past an output
// and, as Bm rows are whole vectors, nothing is read past an input.
// Shapes too large for the kScratch stack floats fall back to the row-at-a-time kernels (lanes
// along the reduction dimension, one horizontal add per dot product). Adam runs lanes along the
// parameters.
//
// Semantics are those of mlp_ref.cpp (the spec); results differ by float accumulation order
// (float sums over lanes, chunks and the hidden/output units instead of a double accumulator) and
// FMA contraction.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"
#include "../madd.hpp"

#include "gs/simd/mlp.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

template <class Arch>
struct MlpKernels {
  using B = xsimd::batch<float, Arch>;
  static constexpr size_t N = B::size;
  static_assert(N <= 16, "stack lane buffers hold at most 16 floats");
  // Register tile: 12 accumulators + 2 Bm vectors + 1 broadcast fit the 16 vector registers of
  // sse2/avx2/neon. Measured at batch 3300 on the hbgs shapes (avx512 and avx2), 6x2 beat 4x2 by
  // ~10% in the backward; 8x2 and 4x4 were no better on avx512, nor was 6x4 there (one tile for
  // the 49- or 52-column outputs: forward 0.96-1.08x, backward 0.99-1.02x by shape, bench_mlp).
  static constexpr size_t kMR = 6;          // C rows per register tile
  static constexpr size_t kNV = 2;          // C vectors per register tile
  static constexpr size_t kScratch = 8192;  // stack floats (32 KiB) for padded weights and chunks
  static constexpr size_t kMaxChunk = 60;   // rows per chunk (a multiple of kMR)
  static constexpr size_t kMinChunk = 12;   // backward chunks below this use the row-at-a-time path

  static void fwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, float* hidden, float* y) {
    if (batch <= 0) return;
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    const size_t Hp = pad(H), Op = pad(O);
    if (I * Hp + H * Op > kScratch) return fwd_rows(s, batch, x, W1, b1, W2, b2, hidden, y);
    alignas(64) float buf[kScratch];
    float* W1T = buf;            // [I, Hp]
    float* W2T = buf + I * Hp;   // [H, Op]
    transpose_pad(W1, H, I, W1T, Hp);
    transpose_pad(W2, O, H, W2T, Op);
    const Act2 act{s->act2};
    // Chunks keep a block of hidden rows in L1 between the two layers.
    for (size_t r0 = 0; r0 < size_t(batch); r0 += kMaxChunk) {
      const size_t rows = scalar::min(kMaxChunk, size_t(batch) - r0);
      float* h = hidden + r0 * H;
      gemm(Gemm{rows, H, I, x + r0 * I, I, 1, W1T, Hp, b1, 0, h, H}, Relu{});
      gemm(Gemm{rows, O, H, h, H, 1, W2T, Op, b2, 0, y + r0 * O, O}, act);
    }
  }

  static void bwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, const float* hidden, const float* y, const float* v_y,
                  float* v_x, float* v_W1, float* v_b1, float* v_W2, float* v_b2) {
    if (batch <= 0) return;
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    const size_t Ip = pad(I), Hp = pad(H), Op = pad(O);
    const bool copy_w1 = Ip != I, copy_h = Hp != H;  // rows read as Bm must be whole vectors
    const size_t fixed = (copy_w1 ? H * Ip : 0) + (copy_h ? O * Hp : 0) + I * Hp + Hp + Op;
    const size_t per_row = Op + Hp + (copy_h ? Hp : 0);
    const size_t R = fixed < kScratch ? scalar::min(kMaxChunk, (kScratch - fixed) / per_row) / kMR * kMR : 0;
    if (R < kMinChunk)
      return bwd_rows(s, batch, x, W1, b1, W2, b2, hidden, y, v_y, v_x, v_W1, v_b1, v_W2, v_b2);
    alignas(64) float buf[kScratch];
    float* p = buf;
    auto take = [&p](size_t n) {
      float* q = p;
      p += n;
      return q;
    };
    const float* W1v = W1;  // [H, Ip]
    const float* W2v = W2;  // [O, Hp]
    if (copy_w1) {
      float* t = take(H * Ip);
      copy_pad(W1, H, I, t, Ip);
      W1v = t;
    }
    if (copy_h) {
      float* t = take(O * Hp);
      copy_pad(W2, O, H, t, Hp);
      W2v = t;
    }
    float* v_W1T = take(I * Hp);  // [I, Hp] v_W1 transposed, accumulated over the chunks
    transpose_pad(v_W1, H, I, v_W1T, Hp);
    float* sum_b1 = take(Hp);  // v_b1 / v_b2 partial sums of this call
    float* sum_b2 = take(Op);
    float* g = take(R * Op);   // [R, Op] cotangent of the output pre-activation (0 in the padding)
    float* vh = take(R * Hp);  // [R, Hp] cotangent of the hidden pre-activation
    float* hp = copy_h ? take(R * Hp) : nullptr;
    scalar::fill(sum_b1, sum_b1 + Hp + Op, 0.0f);
    const MlpAct a2 = s->act2;
    for (size_t r0 = 0; r0 < size_t(batch); r0 += R) {
      const size_t rows = scalar::min(R, size_t(batch) - r0);
      for (size_t r = 0; r < rows; ++r) {
        const float* vyr = v_y + (r0 + r) * O;
        const float* yr = y + (r0 + r) * O;
        for (size_t c = 0; c < Op; c += N) {
          const size_t cnt = scalar::min(N, O - c);
          const B gv = load_n(vyr + c, cnt) * act2_deriv(a2, load_n(yr + c, cnt));  // 0 in the padding
          gv.store_aligned(g + r * Op + c);
          (B::load_aligned(sum_b2 + c) + gv).store_aligned(sum_b2 + c);
        }
      }
      const float* hv = hidden + r0 * H;  // [rows, Hp]
      if (copy_h) {
        copy_pad(hv, rows, H, hp, Hp);
        hv = hp;
      }
      gemm(Gemm{rows, Hp, O, g, Op, 1, W2v, Hp, nullptr, 0, vh, Hp}, Id{});
      for (size_t r = 0; r < rows; ++r)
        for (size_t c = 0; c < Hp; c += N) {
          float* v = vh + r * Hp + c;
          const B m = xsimd::select(B::load_unaligned(hv + r * Hp + c) > B(0.0f), B::load_aligned(v), B(0.0f));
          m.store_aligned(v);
          (B::load_aligned(sum_b1 + c) + m).store_aligned(sum_b1 + c);
        }
      gemm(Gemm{O, H, rows, g, 1, Op, hv, Hp, v_W2, H, v_W2, H}, Id{});
      gemm(Gemm{I, H, rows, x + r0 * I, 1, I, vh, Hp, v_W1T, Hp, v_W1T, Hp}, Id{});
      if (v_x) gemm(Gemm{rows, I, H, vh, Hp, 1, W1v, Ip, nullptr, 0, v_x + r0 * I, I}, Id{});
    }
    for (size_t j = 0; j < H; ++j)
      for (size_t i = 0; i < I; ++i) v_W1[j * I + i] = v_W1T[i * Hp + j];
    for (size_t j = 0; j < H; ++j) v_b1[j] += sum_b1[j];
    for (size_t o = 0; o < O; ++o) v_b2[o] += sum_b2[o];
  }

  static void adam(const AdamParams* p, size_t n, float* param, const float* grad, float* m, float* v) {
    const AdamConsts k = adam_consts(p);
    const float b1 = float(p->beta1), b2 = float(p->beta2);
    const B vb1(b1), vb2(b2), vc1(1.0f - b1), vc2(1.0f - b2), eps(float(p->eps));
    const B step_size(float(k.step_size)), sqrt_bc2(float(k.sqrt_bc2));
    for (size_t i = 0; i < n; i += N) {
      const size_t cnt = scalar::min(N, n - i);
      const B g = load_n(grad + i, cnt);
      const B mn = vb1 * load_n(m + i, cnt) + vc1 * g;
      const B vn = vb2 * load_n(v + i, cnt) + vc2 * (g * g);
      const B denom = xsimd::sqrt(vn) / sqrt_bc2 + eps;
      store_n(m + i, mn, cnt);
      store_n(v + i, vn, cnt);
      store_n(param + i, load_n(param + i, cnt) - step_size * (mn / denom), cnt);
    }
  }

 private:
  static size_t pad(size_t n) { return (n + N - 1) / N * N; }

  // C[m, c] = epi(init[m, c] + sum_k A[m ars + k acs] Bm[k ldb + c]) for m < M, c < cols; init
  // is read at init + m irs (irs = 0: one bias row for every m; init = C, irs = ldc: accumulate)
  // or is 0 when null. Bm rows are read as whole vectors up to pad(cols).
  struct Gemm {
    size_t M, cols, K;
    const float* A;
    size_t ars, acs;
    const float* Bm;
    size_t ldb;
    const float* init;
    size_t irs;
    float* C;
    size_t ldc;
  };
  struct Id {
    B operator()(const B& v) const { return v; }
  };
  struct Relu {  // same predicate as the reference (pre > 0), so NaN maps to 0 like it
    B operator()(const B& v) const { return xsimd::select(v > B(0.0f), v, B(0.0f)); }
  };
  struct Act2 {  // mlp_act2, lane-wise
    MlpAct a;
    B operator()(const B& z) const {
      switch (a) {
        case MlpAct::kSigmoid: return B(1.0f) / (B(1.0f) + xsimd::exp(-z));
        case MlpAct::kTanh: return xsimd::tanh(z);
        default: return z;
      }
    }
  };
  static B act2_deriv(MlpAct a, const B& y) {  // mlp_act2_deriv, lane-wise
    switch (a) {
      case MlpAct::kSigmoid: return y * (B(1.0f) - y);
      case MlpAct::kTanh: return B(1.0f) - y * y;
      default: return B(1.0f);
    }
  }

  template <class Epi>
  static void gemm(const Gemm& g, const Epi& epi) {
    for (size_t c0 = 0; c0 < g.cols; c0 += kNV * N) {
      const size_t nv = scalar::min(kNV, (g.cols - c0 + N - 1) / N);
      const size_t last = scalar::min(N, g.cols - c0 - (nv - 1) * N);  // lanes of the tile's last vector
      for (size_t m0 = 0; m0 < g.M; m0 += kMR)
        tile_dispatch<kMR, kNV>(scalar::min(kMR, g.M - m0), nv, g, m0, c0, last, epi);
    }
  }

  template <size_t MR, size_t NV, class Epi>
  static void tile_dispatch(size_t mr, size_t nv, const Gemm& g, size_t m0, size_t c0, size_t last, const Epi& epi) {
    if constexpr (MR > 1) {
      if (mr < MR) return tile_dispatch<MR - 1, NV>(mr, nv, g, m0, c0, last, epi);
    }
    if constexpr (NV > 1) {
      if (nv < NV) return tile_dispatch<MR, NV - 1>(mr, nv, g, m0, c0, last, epi);
    }
    tile<MR, NV>(g, m0, c0, last, epi);
  }

  template <size_t MR, size_t NV, class Epi>
  static void tile(const Gemm& g, size_t m0, size_t c0, size_t last, const Epi& epi) {
    B acc[MR][NV];
    for (size_t m = 0; m < MR; ++m)
      for (size_t v = 0; v < NV; ++v)
        acc[m][v] = g.init ? load_n(g.init + (m0 + m) * g.irs + c0 + v * N, v + 1 == NV ? last : N) : B(0.0f);
    const float* a = g.A + m0 * g.ars;
    const float* bp = g.Bm + c0;
    for (size_t k = 0; k < g.K; ++k, a += g.acs, bp += g.ldb) {
      B b[NV];
      for (size_t v = 0; v < NV; ++v) b[v] = B::load_unaligned(bp + v * N);
      for (size_t m = 0; m < MR; ++m) {
        const B am(a[m * g.ars]);
        for (size_t v = 0; v < NV; ++v) acc[m][v] = madd(am, b[v], acc[m][v]);
      }
    }
    for (size_t m = 0; m < MR; ++m)
      for (size_t v = 0; v < NV; ++v)
        store_n(g.C + (m0 + m) * g.ldc + c0 + v * N, epi(acc[m][v]), v + 1 == NV ? last : N);
  }

  // dst[i, j] = src[j, i] for a rows x cols src (row-major), dst rows ld >= rows long, zero-padded.
  static void transpose_pad(const float* src, size_t rows, size_t cols, float* dst, size_t ld) {
    for (size_t i = 0; i < cols; ++i) {
      float* d = dst + i * ld;
      for (size_t j = 0; j < rows; ++j) d[j] = src[j * cols + i];
      scalar::fill(d + rows, d + ld, 0.0f);
    }
  }

  // dst rows of ld >= cols floats: a copy of the rows x cols src, zero-padded.
  static void copy_pad(const float* src, size_t rows, size_t cols, float* dst, size_t ld) {
    for (size_t r = 0; r < rows; ++r) {
      scalar::copy(src + r * cols, src + (r + 1) * cols, dst + r * ld);
      scalar::fill(dst + r * ld + cols, dst + (r + 1) * ld, 0.0f);
    }
  }

  // Row-at-a-time kernels (lanes along the reduction dimension): the fallback for shapes whose
  // padded weights or chunks do not fit kScratch.
  static void fwd_rows(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, float* hidden, float* y) {
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    for (size_t r = 0; r < size_t(batch); ++r) {
      const float* xr = x + r * I;
      float* hr = hidden + r * H;
      for (size_t j = 0; j < H; ++j) {
        const float pre = dot(W1 + j * I, xr, I) + b1[j];
        hr[j] = pre > 0.0f ? pre : 0.0f;
      }
      for (size_t o = 0; o < O; ++o) y[r * O + o] = mlp_act2<float>(s->act2, dot(W2 + o * H, hr, H) + b2[o]);
    }
  }

  static void bwd_rows(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, const float* hidden, const float* y, const float* v_y,
                  float* v_x, float* v_W1, float* v_b1, float* v_W2, float* v_b2) {
    (void)b1;
    (void)b2;
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    for (size_t r = 0; r < size_t(batch); ++r) {
      const float* xr = x + r * I;
      const float* hr = hidden + r * H;
      float* v_xr = v_x ? v_x + r * I : nullptr;
      if (v_xr) scalar::fill(v_xr, v_xr + I, 0.0f);
      for (size_t c = 0; c < H; c += N) {
        const size_t cnt = scalar::min(N, H - c);
        const B h = load_n(hr + c, cnt);
        B v_h(0.0f);
        for (size_t o = 0; o < O; ++o) {
          const float g = v_y[r * O + o] * mlp_act2_deriv<float>(s->act2, y[r * O + o]);
          if (c == 0) v_b2[o] += g;
          const B gb(g);
          v_h = madd(gb, load_n(W2 + o * H + c, cnt), v_h);
          float* vw2 = v_W2 + o * H + c;
          store_n(vw2, madd(gb, h, load_n(vw2, cnt)), cnt);
        }
        const B g1 = xsimd::select(h > B(0.0f), v_h, B(0.0f));
        store_n(v_b1 + c, load_n(v_b1 + c, cnt) + g1, cnt);
        alignas(64) float gl[16];
        g1.store_aligned(gl);
        for (size_t l = 0; l < cnt; ++l) {
          const size_t j = c + l;
          axpy(gl[l], xr, v_W1 + j * I, I);
          if (v_xr) axpy(gl[l], W1 + j * I, v_xr, I);
        }
      }
    }
  }

  static float dot(const float* a, const float* b, size_t n) {
    B acc(0.0f);
    size_t i = 0;
    for (; i + N <= n; i += N) acc = madd(B::load_unaligned(a + i), B::load_unaligned(b + i), acc);
    if (i < n) acc = madd(load_n(a + i, n - i), load_n(b + i, n - i), acc);
    return xsimd::hadd(acc);
  }

  // out[0..n) += a * in[0..n)
  static void axpy(float a, const float* in, float* out, size_t n) {
    const B ab(a);
    size_t i = 0;
    for (; i + N <= n; i += N)
      madd(ab, B::load_unaligned(in + i), B::load_unaligned(out + i)).store_unaligned(out + i);
    if (i < n) store_n(out + i, madd(ab, load_n(in + i, n - i), load_n(out + i, n - i)), n - i);
  }

  // Loads cnt <= N values, zero-filling the other lanes (no read past p + cnt).
  static B load_n(const float* p, size_t cnt) {
    if (cnt == N) return B::load_unaligned(p);
    alignas(64) float t[16] = {};
    for (size_t l = 0; l < cnt; ++l) t[l] = p[l];
    return B::load_aligned(t);
  }

  static void store_n(float* p, const B& v, size_t cnt) {
    if (cnt == N) return v.store_unaligned(p);
    alignas(64) float t[16];
    v.store_aligned(t);
    for (size_t l = 0; l < cnt; ++l) p[l] = t[l];
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
