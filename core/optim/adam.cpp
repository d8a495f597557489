// SPDX-License-Identifier: MIT
// Adam for float parameter arrays (the kernel table) and pose twists (the reference in double);
// see gs/optim/adam.h.
#include "gs/optim/adam.h"

#include <algorithm>

#include "gs/platform/thread_pool.h"
#include "gs/simd/kernel_table.h"

namespace gs::optim {

namespace {
constexpr size_t kChunk = 16384;  // fixed: a chunk's SIMD tail does not depend on the thread count
}  // namespace

void adam_step(const simd::KernelTable& kernels, platform::ThreadPool* pool, const simd::AdamParams& p, size_t n,
               float* param, const float* grad, float* m, float* v) {
  const size_t chunk = kChunk;
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

void adam_step_arrays(const simd::KernelTable& kernels, platform::ThreadPool* pool, const AdamArray* arrays,
                      size_t count) {
  // Items are (array, chunk) pairs numbered array by array; an item finds its array by a linear
  // search (a handful of arrays).
  size_t items = 0;
  for (size_t a = 0; a < count; ++a) items += (arrays[a].n + kChunk - 1) / kChunk;
  auto body = [&](size_t b, size_t e, int) {
    size_t a = 0, first = 0;  // array of item b and the number of its first chunk
    for (size_t item = b; item < e; ++item) {
      while (item >= first + (arrays[a].n + kChunk - 1) / kChunk) first += (arrays[a++].n + kChunk - 1) / kChunk;
      const AdamArray& x = arrays[a];
      const size_t lo = (item - first) * kChunk, hi = std::min(x.n, lo + kChunk);
      kernels.adam_step(&x.p, hi - lo, x.param + lo, x.grad + lo, x.m + lo, x.v + lo);
    }
  };
  if (pool && items > 1)
    pool->parallel_for(items, 1, body);
  else
    body(0, items, 0);
}

void twist_adam_step(const double g[6], double lr_translation, double lr_rotation, int64_t step, double eps,
                     double m[6], double v[6], double xi[6]) {
  std::fill(xi, xi + 6, 0.0);  // the reference subtracts the step from the "parameter"
  const simd::AdamParams tr = adam_params(lr_translation, step, eps), rot = adam_params(lr_rotation, step, eps);
  simd::adam_step_ref<double>(&tr, 3, xi, g, m, v);
  simd::adam_step_ref<double>(&rot, 3, xi + 3, g + 3, m + 3, v + 3);
}

}  // namespace gs::optim
