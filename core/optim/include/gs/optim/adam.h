// SPDX-License-Identifier: MIT
// The optimiser: Adam and its learning-rate schedules, one implementation for every caller
// (the trainer's parameter groups and training poses, registration's Adam solver).
//
// Adam is PyTorch's torch.optim.Adam (no weight decay, no amsgrad), written once in
// simd::adam_step_ref (gs/simd/mlp.h): the SIMD kernel table's adam_step runs it on float arrays,
// and twist_adam_step runs the reference itself in double on a pose's 6-vector, so parameters and
// poses take the same formula, betas and epsilon rule.
//   m = b1 m + (1 - b1) g,  v = b2 v + (1 - b2) g^2,
//   step = lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps),  t the 1-based step.
// Epsilon rule: eps is added after the square root of the bias-corrected v, and is kAdamEps
// (1e-15, 3DGS's value) everywhere unless a caller's options say otherwise (TrainOptions::adam_eps).
//
// Densification (anchor growing and pruning under the budgets) is the other half of the reference
// optimiser; it lives with the trainer's state in model/trainer_anchors.cpp (it needs the model).
#pragma once

#include <cstddef>
#include <cstdint>

#include "gs/simd/mlp.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::optim {

inline constexpr double kAdamBeta1 = 0.9;
inline constexpr double kAdamBeta2 = 0.999;
// 3DGS's Adam epsilon. Registration used 1e-12 before; one value for every pose and parameter,
// and the smaller one, because pose-twist and Gaussian gradients can be far below 1e-8.
inline constexpr double kAdamEps = 1e-15;

// The per-step constants of Adam at 1-based step t with rate lr.
inline simd::AdamParams adam_params(double lr, int64_t step, double eps = kAdamEps) {
  return simd::AdamParams{lr, kAdamBeta1, kAdamBeta2, eps, step};
}

// One Adam step over n floats in place with the kernel table's adam_step, split over the pool in
// fixed 16384-element chunks (results do not depend on the thread count). pool may be nullptr.
void adam_step(const simd::KernelTable& kernels, platform::ThreadPool* pool, const simd::AdamParams& p, size_t n,
               float* param,        // [n]
               const float* grad,   // [n]
               float* m, float* v);  // [n] moments

// One Adam step over each of `count` arrays (array i: n[i] floats with constants p[i]), as
// adam_step on each, but in one pass over the pool: the fixed chunks of every array are claimed
// together, so small arrays do not run alone and the threads meet once. Same results as adam_step.
struct AdamArray {
  simd::AdamParams p;
  size_t n = 0;
  float* param = nullptr;
  const float* grad = nullptr;
  float *m = nullptr, *v = nullptr;
};
void adam_step_arrays(const simd::KernelTable& kernels, platform::ThreadPool* pool, const AdamArray* arrays,
                      size_t count);

// One Adam step on a 6-DoF twist (rho[3], phi[3]) in double: updates the moments m, v [6] from the
// gradient g [6] and writes the increment xi [6] (to be applied to the pose, e.g. by
// pose::apply_left_twist), with rate lr_translation for rho and lr_rotation for phi.
void twist_adam_step(const double g[6], double lr_translation, double lr_rotation, int64_t step, double eps,
                     double m[6], double v[6], double xi[6]);

}  // namespace gs::optim
