// SPDX-License-Identifier: MIT
// Adam for float parameter arrays (the kernel table) and pose twists (the reference in double);
// see gs/optim/adam.h.
#include "gs/optim/adam.h"

#include <algorithm>

#include "gs/platform/thread_pool.h"
#include "gs/simd/kernel_table.h"

namespace gs::optim {

void adam_step(const simd::KernelTable& kernels, platform::ThreadPool* pool, const simd::AdamParams& p, size_t n,
               float* param, const float* grad, float* m, float* v) {
  const size_t chunk = 16384;
  auto body = [&](size_t b, size_t e, int) {
    for (size_t c = b; c < e; ++c) {
      const size_t lo = c * chunk, hi = std::min(n, lo + chunk);
      kernels.adam_step(&p, hi - lo, param + lo, grad + lo, m + lo, v + lo);
    }
  };
  const size_t chunks = (n + chunk - 1) / chunk;
  if (pool && chunks > 1)
    pool->parallel_for(chunks, 1, body);
  else
    body(0, chunks, 0);
}

void twist_adam_step(const double g[6], double lr_translation, double lr_rotation, int64_t step, double eps,
                     double m[6], double v[6], double xi[6]) {
  std::fill(xi, xi + 6, 0.0);  // the reference subtracts the step from the "parameter"
  const simd::AdamParams tr = adam_params(lr_translation, step, eps), rot = adam_params(lr_rotation, step, eps);
  simd::adam_step_ref<double>(&tr, 3, xi, g, m, v);
  simd::adam_step_ref<double>(&rot, 3, xi + 3, g + 3, m + 3, v + 3);
}

}  // namespace gs::optim
