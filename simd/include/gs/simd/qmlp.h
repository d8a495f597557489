// SPDX-License-Identifier: MIT
// Kernel ABI of the int8 decoder MLP (the on-device decode path): a 2-layer MLP with int8 inputs and
// weights, int32 accumulation, per-output-channel requantisation (gs/simd/fxp.h), ReLU then int8
// hidden activations (0..127), and int16 outputs before the final activation. The reference
// (simd/ref/qmlp_ref.cpp) is the spec; integer sums are exact, so every variant is bit-exact.
//   hidden[b, h] = clamp(rq(b1[h] + sum_i x[b, i] W1[h, i], m1[h], s1[h]), 0, 127)
//   y[b, o]      = sat16(rq(b2[o] + sum_h hidden[b, h] W2[o, h], m2[o], s2[o]))
// with rq = fxp::multiply_by_quantized_multiplier. Weights are stored transposed and widened to
// int32 ([I, Hp], [H, Op], Hp and Op rounded up to kQMlpPad with zero columns) so the SIMD variants
// add whole rows of outputs at once; their values are int8.
#pragma once

#include <cstdint>

#include "gs/simd/fxp.h"
#include "gs/simd/isa.h"

namespace gs::simd {

constexpr int32_t kQMlpPad = 16;       // output columns are padded to a multiple of this
constexpr int32_t kQMlpMaxWidth = 1024;  // hidden and output widths the kernels accept

struct QMlpParams {
  int32_t in, hidden, out;          // I, H, O (each 1..kQMlpMaxWidth)
  int32_t hidden_pad, out_pad;      // H, O rounded up to kQMlpPad
  const int32_t* w1t;               // [I, hidden_pad] int8 values, W1 transposed
  const int32_t* b1;                // [hidden_pad] in accumulator units
  const int32_t* m1;                // [H] Q31 multipliers
  const int32_t* s1;                // [H] shifts
  const int32_t* w2t;               // [H, out_pad]
  const int32_t* b2;                // [out_pad]
  const int32_t* m2;                // [O]
  const int32_t* s2;                // [O]
};

inline int32_t qmlp_pad(int32_t n) { return (n + kQMlpPad - 1) / kQMlpPad * kQMlpPad; }

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

// The requantisation of one row's accumulators (shared by every variant: scalar, exact).
inline void qmlp_requant_hidden(const QMlpParams* p, const int32_t* acc, int8_t* hidden) {
  for (int32_t h = 0; h < p->hidden; ++h) {
    const int32_t v = fxp::multiply_by_quantized_multiplier(acc[h], p->m1[h], p->s1[h]);
    hidden[h] = int8_t(v < 0 ? 0 : (v > 127 ? 127 : v));
  }
}
inline void qmlp_requant_out(const QMlpParams* p, const int32_t* acc, int16_t* y) {
  for (int32_t o = 0; o < p->out; ++o) y[o] = fxp::saturate_int16(fxp::multiply_by_quantized_multiplier(acc[o], p->m2[o], p->s2[o]));
}

}  // inline namespace GS_SIMD_ISA_NS

// Reference: x [batch, I] int8, hidden [batch, H] int8 (written), y [batch, O] int16.
void qmlp_fwd_ref(const QMlpParams* p, int32_t batch, const int8_t* x, int8_t* hidden, int16_t* y);

}  // namespace gs::simd
