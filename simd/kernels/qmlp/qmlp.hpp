// SPDX-License-Identifier: MIT
// xsimd int8 decoder MLP, templated on the architecture: per row, int32 accumulators for a block of
// output columns are updated input by input (acc += x[i] * W^T[i, block]), so whole registers of
// outputs advance together; requantisation is the shared scalar code of gs/simd/qmlp.h. Integer
// sums are exact in any order, so results are bit-identical with simd/ref/qmlp_ref.cpp.
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"

#include "gs/simd/qmlp.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

template <class Arch>
struct QMlpKernels {
  using B = xsimd::batch<int32_t, Arch>;
  static constexpr int N = int(B::size);
  static_assert(kQMlpPad % N == 0, "padded widths must hold whole registers");

  // acc[0..width) = bias + sum_i x[i] w[i, 0..width) (w rows `stride` apart).
  template <class X>
  static void layer(const X* x, int32_t n_in, const int32_t* w, int32_t stride, const int32_t* bias, int32_t width,
                    int32_t* acc) {
    for (int32_t c = 0; c < width; c += N) B::load_unaligned(bias + c).store_unaligned(acc + c);
    for (int32_t i = 0; i < n_in; ++i) {
      const int32_t xi = int32_t(x[i]);
      if (xi == 0) continue;  // exact: adds nothing (ReLU zeros are common)
      const B xb(xi);
      const int32_t* wr = w + size_t(i) * size_t(stride);
      for (int32_t c = 0; c < width; c += N) (B::load_unaligned(acc + c) + xb * B::load_unaligned(wr + c)).store_unaligned(acc + c);
    }
  }

  static void fwd(const QMlpParams* p, int32_t batch, const int8_t* x, int8_t* hidden, int16_t* y) {
    alignas(64) int32_t acc[kQMlpMaxWidth];
    for (int32_t b = 0; b < batch; ++b) {
      int8_t* hr = hidden + size_t(b) * size_t(p->hidden);
      layer(x + size_t(b) * size_t(p->in), p->in, p->w1t, p->hidden_pad, p->b1, p->hidden_pad, acc);
      qmlp_requant_hidden(p, acc, hr);
      layer(hr, p->hidden, p->w2t, p->out_pad, p->b2, p->out_pad, acc);
      qmlp_requant_out(p, acc, y + size_t(b) * size_t(p->out));
    }
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
