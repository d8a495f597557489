// SPDX-License-Identifier: MIT
// Kernel ABI of the training photometric loss L = (1 - lambda) L1 + lambda (1 - SSIM) (ALGORITHM.md
// Part A item 6) on [H, W, 3] interleaved float images in [0, 1]: constants, the scratch plan and
// the scalar reference kernels (the spec of the xsimd variants in simd/kernels/loss/).
//
// SSIM follows 3DGS's ssim(): per channel, an 11x11 Gaussian window (sigma 1.5, sum 1) applied as a
// zero-padded 'same' convolution, so near the border the padded zeros count in the window sums
// (the window is not renormalised); C1 = 0.01^2, C2 = 0.03^2; SSIM is the mean of the map over all
// 3 H W values. The 2D window is the outer product of the 1D one, so every blur is two 1D passes.
//
// Sizes: width, height >= 1 (the means divide by 3 W H). Threading: one call per image; the
// kernels keep no state, so concurrent calls need only separate scratch.
// Memory: kernels never allocate; the caller passes loss_scratch_floats(W, H) elements of T. The
// plan is rolling (a few padded rows), so scratch is O(W), not O(W H).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "gs/simd/isa.h"

namespace gs::simd {

constexpr int kSsimRadius = 5;                    // window half-width, px
constexpr int kSsimTaps = 2 * kSsimRadius + 1;    // 11
constexpr double kSsimSigma = 1.5;                // px
constexpr double kLossLambda = 0.2;               // SSIM weight
constexpr double kSsimC1 = 0.01 * 0.01;           // (K1 L)^2 with dynamic range L = 1
constexpr double kSsimC2 = 0.03 * 0.03;           // (K2 L)^2

// Per-run constants. Kept in double so the double reference (finite-difference checks) sees the
// exact window; float kernels round them once per call.
struct LossParams {
  double lambda;              // weight of (1 - SSIM)
  double c1, c2;              // SSIM stabilisers
  double window[kSsimTaps];   // 1D Gaussian, sums to 1; window[kSsimRadius] is the centre tap
};

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

inline LossParams make_loss_params(double lambda = kLossLambda) {
  LossParams p;
  p.lambda = lambda;
  p.c1 = kSsimC1;
  p.c2 = kSsimC2;
  double sum = 0;
  for (int k = 0; k < kSsimTaps; ++k) {
    const double d = double(k - kSsimRadius);
    p.window[k] = scalar::exp(-d * d / (2 * kSsimSigma * kSsimSigma));
    sum += p.window[k];
  }
  for (int k = 0; k < kSsimTaps; ++k) p.window[k] /= sum;
  return p;
}

// The scalar loss from the two means the forward returns.
inline double loss_value(const LossParams* p, double l1, double ssim) {
  return (1 - p->lambda) * l1 + p->lambda * (1 - ssim);
}

}  // inline namespace GS_SIMD_ISA_NS

// Scratch plan. Every scratch row holds one image row of 3 W interleaved values at offset
// kLossRowPad, with at least kLossRowPad zeros on both sides: the horizontal pass (taps 3 floats
// apart on the interleaved row, reaching 3 kSsimRadius = 15 floats) then reads the zero padding
// instead of branching, and a 16-lane batch never leaves the row. Rows: 5 (blurred moments of
// one row) + 3 x kSsimTaps (ring of SSIM-map cotangents) + 3 (their vertical blur) = 41.
constexpr int kLossRowPad = 16;    // floats; >= 3 kSsimRadius and a multiple of 16 (lane alignment)
constexpr int kLossScratchRows = 5 + 3 * kSsimTaps + 3;

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

inline size_t loss_row_stride(int32_t width) {
  const size_t n = 3 * size_t(width);
  return kLossRowPad + (n + 15) / 16 * 16 + kLossRowPad + 16;
}

// Scratch elements (of the kernel's T) needed by loss_fwd* and loss_bwd* for a W x H image.
inline size_t loss_scratch_floats(int32_t width, int32_t height) {
  (void)height;  // the plan is rolling over rows
  return size_t(kLossScratchRows) * loss_row_stride(width);
}

// SSIM of one window from its blurred moments mx = B(x), my = B(y), exx = B(x^2), eyy = B(y^2),
// exy = B(x y). V is a scalar or an xsimd batch, so the reference and the SIMD kernels share the
// exact formula and operation order.
template <class V>
inline V ssim_elem(const V& mx, const V& my, const V& exx, const V& eyy, const V& exy, const V& c1, const V& c2) {
  const V mxx = mx * mx, myy = my * my, mxy = mx * my;
  const V a1 = (mxy + mxy) + c1;
  const V a2 = (exy - mxy) + (exy - mxy) + c2;
  const V b1 = (mxx + myy) + c1;
  const V b2 = (exx - mxx) + (eyy - myy) + c2;
  return (a1 * a2) / (b1 * b2);
}

// ssim_elem and its cotangents: with S = a1 a2 / (b1 b2), a1 = 2 mx my + C1,
// a2 = 2 (exy - mx my) + C2, b1 = mx^2 + my^2 + C1, b2 = exx - mx^2 + eyy - my^2 + C2:
//   dS/dexy = 2 a1 / (b1 b2),  dS/dexx = -S / b2,
//   dS/dmx = 2 my (a2 - a1) / (b1 b2) - 2 mx S (1/b1 - 1/b2).
// Writes v_s times those; returns S. (my, eyy belong to the fixed target: no cotangent.)
template <class V>
inline V ssim_elem_vjp(const V& mx, const V& my, const V& exx, const V& eyy, const V& exy, const V& c1, const V& c2,
                       const V& v_s, V* v_mx, V* v_exx, V* v_exy) {
  const V mxx = mx * mx, myy = my * my, mxy = mx * my;
  const V a1 = (mxy + mxy) + c1;
  const V a2 = (exy - mxy) + (exy - mxy) + c2;
  const V b1 = (mxx + myy) + c1;
  const V b2 = (exx - mxx) + (eyy - myy) + c2;
  const V den = b1 * b2;
  const V s = (a1 * a2) / den;
  const V inv_den = V(1) / den, inv_b1 = V(1) / b1, inv_b2 = V(1) / b2;
  const V vs2 = v_s + v_s;
  *v_exy = vs2 * a1 * inv_den;
  *v_exx = -v_s * s * inv_b2;
  *v_mx = vs2 * (my * (a2 - a1) * inv_den - mx * s * (inv_b1 - inv_b2));
  return s;
}

}  // inline namespace GS_SIMD_ISA_NS

// Forward: out_l1 = mean |image - target|, out_ssim = mean SSIM map, both over 3 W H values.
// Combine with loss_value().
template <class T>
void loss_fwd_ref(const LossParams* p, int32_t width, int32_t height,
                  // fwd inputs
                  const T* image,   // [H, W, 3] rendered
                  const T* target,  // [H, W, 3] ground truth (fixed)
                  T* scratch,       // [loss_scratch_floats(W, H)]
                  // fwd outputs
                  double* out_l1,     // [1]
                  double* out_ssim);  // [1]

// Backward: v_image = v_loss dL/dimage (overwritten), recomputing the forward; the L1 subgradient
// at image == target is 0. out_l1 / out_ssim get the forward values if not null (they come free).
template <class T>
void loss_bwd_ref(const LossParams* p, int32_t width, int32_t height,
                  // fwd inputs
                  const T* image,   // [H, W, 3]
                  const T* target,  // [H, W, 3]
                  // grad inputs
                  double v_loss,    // dObjective / dL (1 for the loss itself)
                  T* scratch,       // [loss_scratch_floats(W, H)]
                  // grad outputs
                  T* v_image,        // [H, W, 3]
                  // fwd outputs (optional)
                  double* out_l1,    // [1] or nullptr
                  double* out_ssim);  // [1] or nullptr

// The backward for image rows [row_begin, row_end) only, so bands of rows can run in parallel
// (each with its own scratch): writes those rows of v_image, exactly as loss_bwd_ref, and each
// row's sums of |image - target| and of the SSIM map into row_l1[r], row_ssim[r] ([height]).
// Summing row_l1 / row_ssim over all rows in order and dividing by 3 W H gives the means (in
// the SIMD kernels bit-identical to their loss_bwd; here the per-row partials round differently
// from loss_bwd_ref's single running sum). The band reads the image rows up to 10 beyond it.
template <class T>
void loss_bwd_rows_ref(const LossParams* p, int32_t width, int32_t height, int32_t row_begin, int32_t row_end,
                       const T* image, const T* target, double v_loss, T* scratch, T* v_image, double* row_l1,
                       double* row_ssim);

}  // namespace gs::simd
