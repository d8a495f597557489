// SPDX-License-Identifier: MIT
// xsimd decoder MLP forward that is bit-identical to mlp_fwd_ref (the on-device path's decode, so
// that poses are the same on every CPU; gs/simd/kernel_table.h mlp_fwd_exact).
//
// The reference accumulates each dot product in double, term by term in input order, then rounds
// to float and applies the activation. Here the lanes run along the batch rows, not along the dot
// product: a block of L rows (L doubles per register) is transposed into [I, L] doubles, and each
// hidden or output unit accumulates acc = acc + w * x lane-wise in the same order with separate
// multiply and add (a float times a float is exact in double, so only the adds round, as in the
// reference; the build has -ffp-contract=off and no xsimd::fma is used). The rounding to float, the
// ReLU and the output activation (libm, as in the reference) run per element. Architectures without
// double lanes (32-bit NEON) and shapes beyond the stack buffers call the reference itself.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"
#include "gs/simd/mlp.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

// Whether Arch has double lanes: 32-bit NEON has none (xsimd declares an empty register for it).
template <class Arch>
struct HasDoubleLanes : std::bool_constant<xsimd::types::has_simd_register<double, Arch>::value> {};
template <>
struct HasDoubleLanes<xsimd::neon> : std::false_type {};

template <class Arch, bool kHasDouble = HasDoubleLanes<Arch>::value>
struct MlpExactKernels {
  static void fwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, float* hidden, float* y) {
    mlp_fwd_ref<float>(s, batch, x, W1, b1, W2, b2, hidden, y);
  }
};

template <class Arch>
struct MlpExactKernels<Arch, true> {
  using D = xsimd::batch<double, Arch>;
  static constexpr size_t L = D::size;
  static constexpr size_t kScratch = 2048;  // stack doubles (16 KiB) for the transposed block

  static void fwd(const MlpShape* s, int32_t batch, const float* x, const float* W1, const float* b1,
                  const float* W2, const float* b2, float* hidden, float* y) {
    if (batch <= 0) return;
    const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
    if ((I + H) * L > kScratch) return mlp_fwd_ref<float>(s, batch, x, W1, b1, W2, b2, hidden, y);
    alignas(64) double xt[kScratch];  // [I, L] the block's inputs, then [H, L] its hidden units
    double* ht = xt + I * L;
    alignas(64) double lane[L];
    const MlpAct act2 = s->act2;
    for (size_t r0 = 0; r0 < size_t(batch); r0 += L) {
      const size_t rows = scalar::min(L, size_t(batch) - r0);
      for (size_t i = 0; i < I; ++i)
        for (size_t l = 0; l < L; ++l) xt[i * L + l] = l < rows ? double(x[(r0 + l) * I + i]) : 0.0;
      for (size_t j = 0; j < H; ++j) {
        D acc(0.0);
        const float* w = W1 + j * I;
        for (size_t i = 0; i < I; ++i) acc = acc + D(double(w[i])) * D::load_aligned(xt + i * L);
        (acc + D(double(b1[j]))).store_aligned(lane);
        for (size_t l = 0; l < L; ++l) {
          const float pre = float(lane[l]);
          const float h = pre > 0.0f ? pre : 0.0f;
          if (l < rows) hidden[(r0 + l) * H + j] = h;
          ht[j * L + l] = double(h);
        }
      }
      for (size_t o = 0; o < O; ++o) {
        D acc(0.0);
        const float* w = W2 + o * H;
        for (size_t j = 0; j < H; ++j) acc = acc + D(double(w[j])) * D::load_aligned(ht + j * L);
        (acc + D(double(b2[o]))).store_aligned(lane);
        for (size_t l = 0; l < rows; ++l) y[(r0 + l) * O + o] = mlp_act2<float>(act2, float(lane[l]));
      }
    }
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
