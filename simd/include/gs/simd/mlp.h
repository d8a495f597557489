// SPDX-License-Identifier: MIT
// Kernel ABI of the Scaffold-GS decoder MLPs and of the Adam update: shapes, parameters and the
// scalar reference kernels (the spec of the xsimd variants in simd/kernels/mlp/).
//
// MLP: y = act2(W2 relu(W1 x + b1) + b2) on a batch of B rows, all row-major float (or double for
// the finite-difference reference): x [B, I], W1 [H, I], b1 [H], W2 [O, H], b2 [O], y [B, O]. The
// forward keeps the post-ReLU hidden layer [B, H] for the backward. ReLU'(0) = 0. The backward
// ACCUMULATES (+=) the weight and bias gradients, so calls over several batches sum, and
// overwrites v_x (optional). Kernels never allocate and keep no state.
//
// Adam: PyTorch torch.optim.Adam (no weight decay, no amsgrad): m = b1 m + (1 - b1) g,
// v = b2 v + (1 - b2) g^2, param -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps),
// with t the 1-based step (eps added after the square root of the bias-corrected v).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "gs/simd/isa.h"

namespace gs::simd {

// Output activation of the second layer.
enum class MlpAct : int32_t { kNone = 0, kSigmoid = 1, kTanh = 2 };

struct MlpShape {
  int32_t in;      // I >= 1 (hbgs: feature 32 + view direction 3 + distance 1 = 36, or more)
  int32_t hidden;  // H >= 1 (hbgs: 32)
  int32_t out;     // O >= 1 (hbgs: 10, 30 or 70)
  MlpAct act2;     // activation after the second layer
};

struct AdamParams {
  double lr;
  double beta1, beta2;
  double eps;
  int64_t step;  // 1-based step number t, for the bias corrections
};

// Per-step constants shared by the reference and the SIMD variants (computed once, in double).
struct AdamConsts {
  double step_size;    // lr / (1 - beta1^t)
  double sqrt_bc2;     // sqrt(1 - beta2^t)
};

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

inline AdamConsts adam_consts(const AdamParams* p) {
  const double t = double(p->step);
  AdamConsts c;
  c.step_size = p->lr / (1 - scalar::pow(p->beta1, t));
  c.sqrt_bc2 = scalar::sqrt(1 - scalar::pow(p->beta2, t));
  return c;
}

// act2 applied to a pre-activation, and its derivative expressed through the output y.
template <class T>
inline T mlp_act2(MlpAct a, T z) {
  switch (a) {
    case MlpAct::kSigmoid: return T(1) / (T(1) + scalar::exp(-z));
    case MlpAct::kTanh: return scalar::tanh(z);
    default: return z;
  }
}
template <class T>
inline T mlp_act2_deriv(MlpAct a, T y) {
  switch (a) {
    case MlpAct::kSigmoid: return y * (T(1) - y);
    case MlpAct::kTanh: return T(1) - y * y;
    default: return T(1);
  }
}

}  // inline namespace GS_SIMD_ISA_NS

template <class T>
void mlp_fwd_ref(const MlpShape* s, int32_t batch,
                 // fwd inputs
                 const T* x,   // [B, I]
                 const T* W1,  // [H, I]
                 const T* b1,  // [H]
                 const T* W2,  // [O, H]
                 const T* b2,  // [O]
                 // fwd outputs
                 T* hidden,    // [B, H] post-ReLU (kept for the backward)
                 T* y);        // [B, O]

template <class T>
void mlp_bwd_ref(const MlpShape* s, int32_t batch,
                 // fwd inputs
                 const T* x,       // [B, I]
                 const T* W1,      // [H, I]
                 const T* b1,      // [H] (unused; kept for a uniform signature)
                 const T* W2,      // [O, H]
                 const T* b2,      // [O] (unused)
                 const T* hidden,  // [B, H] from mlp_fwd
                 const T* y,       // [B, O] from mlp_fwd
                 // grad inputs
                 const T* v_y,     // [B, O]
                 // grad outputs
                 T* v_x,           // [B, I] overwritten, or nullptr
                 T* v_W1,          // [H, I] accumulated (+=)
                 T* v_b1,          // [H] accumulated
                 T* v_W2,          // [O, H] accumulated
                 T* v_b2);         // [O] accumulated

// One Adam step over n parameters, in place.
template <class T>
void adam_step_ref(const AdamParams* p, size_t n,
                   T* param,       // [n] updated
                   const T* grad,  // [n]
                   T* m,           // [n] first moment, updated (zero before step 1)
                   T* v);          // [n] second moment, updated (zero before step 1)

}  // namespace gs::simd
