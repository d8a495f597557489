// SPDX-License-Identifier: MIT
// xsimd decoder MLP (forward, backward) and Adam step, templated on the architecture.
//
// Layout choice: the weights are row-major ([H, I], [O, H]), so the forward runs lanes along the
// contiguous reduction dimension: each hidden unit is a dot product of a W1 row with the x row
// (lanes along I), each output a dot product of a W2 row with the hidden row (lanes along H),
// reduced with one horizontal add. The backward runs lanes along the hidden dimension: for a
// block of N hidden units it walks the outputs once, updating the v_W2 row block, v_b2 and the
// hidden cotangent in registers (no scratch), masks it with the ReLU, and then each unit of the
// block updates its v_W1 row and the v_x row with lanes along I. Vectorising over batch rows would
// need x transposed (gathers, or scratch), which the plain-pointer ABI does not give us.
// Tails shorter than a batch are loaded zero-filled and stored partially, so nothing is read or
// written past the end of an array. Adam runs lanes along the parameters.
//
// Semantics are those of mlp_ref.cpp (the spec); results differ by float accumulation order
// (lane partial sums instead of a double accumulator) and FMA contraction.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/mlp.h"

namespace gs::simd::kernels {

template <class Arch>
struct MlpKernels {
  using B = xsimd::batch<float, Arch>;
  static constexpr size_t N = B::size;
  static_assert(N <= 16, "stack lane buffers hold at most 16 floats");

  static void fwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
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

  static void bwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, const float* hidden, const float* y, const float* v_y,
                  float* v_x, float* v_W1, float* v_b1, float* v_W2, float* v_b2) {
    (void)b1;
    (void)b2;
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    for (size_t r = 0; r < size_t(batch); ++r) {
      const float* xr = x + r * I;
      const float* hr = hidden + r * H;
      float* v_xr = v_x ? v_x + r * I : nullptr;
      if (v_xr) std::fill(v_xr, v_xr + I, 0.0f);
      for (size_t c = 0; c < H; c += N) {
        const size_t cnt = std::min(N, H - c);
        const B h = load_n(hr + c, cnt);
        B v_h(0.0f);
        for (size_t o = 0; o < O; ++o) {
          const float g = v_y[r * O + o] * mlp_act2_deriv<float>(s->act2, y[r * O + o]);
          if (c == 0) v_b2[o] += g;
          const B gb(g);
          v_h = xsimd::fma(gb, load_n(W2 + o * H + c, cnt), v_h);
          float* vw2 = v_W2 + o * H + c;
          store_n(vw2, xsimd::fma(gb, h, load_n(vw2, cnt)), cnt);
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

  static void adam(const AdamParams* p, size_t n, float* param, const float* grad, float* m, float* v) {
    const AdamConsts k = adam_consts(p);
    const float b1 = float(p->beta1), b2 = float(p->beta2);
    const B vb1(b1), vb2(b2), vc1(1.0f - b1), vc2(1.0f - b2), eps(float(p->eps));
    const B step_size(float(k.step_size)), sqrt_bc2(float(k.sqrt_bc2));
    for (size_t i = 0; i < n; i += N) {
      const size_t cnt = std::min(N, n - i);
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
  static float dot(const float* a, const float* b, size_t n) {
    B acc(0.0f);
    size_t i = 0;
    for (; i + N <= n; i += N) acc = xsimd::fma(B::load_unaligned(a + i), B::load_unaligned(b + i), acc);
    if (i < n) acc = xsimd::fma(load_n(a + i, n - i), load_n(b + i, n - i), acc);
    return xsimd::hadd(acc);
  }

  // out[0..n) += a * in[0..n)
  static void axpy(float a, const float* in, float* out, size_t n) {
    const B ab(a);
    size_t i = 0;
    for (; i + N <= n; i += N)
      xsimd::fma(ab, B::load_unaligned(in + i), B::load_unaligned(out + i)).store_unaligned(out + i);
    if (i < n) store_n(out + i, xsimd::fma(ab, load_n(in + i, n - i), load_n(out + i, n - i)), n - i);
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

}  // namespace gs::simd::kernels
