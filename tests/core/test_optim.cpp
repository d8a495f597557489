// SPDX-License-Identifier: MIT
// The optimiser's pool loops (gs/optim/adam.h): adam_step_arrays, every array in one pass over the
// pool, gives adam_step's results on each array bit for bit, for any thread count and array sizes
// around the fixed chunk (empty, shorter than a chunk, a chunk and a tail).
#include <doctest/doctest.h>

#include <random>
#include <vector>

#include "gs/optim/adam.h"
#include "gs/platform/thread_pool.h"
#include "gs/simd/kernel_table.h"

namespace {

struct Array {
  std::vector<float> param, grad, m, v;
};

Array random_array(std::mt19937_64& rng, size_t n) {
  std::normal_distribution<float> g(0.0f, 1.0f);
  Array a;
  for (auto* x : {&a.param, &a.grad, &a.m}) {
    x->resize(n);
    for (float& f : *x) f = g(rng);
  }
  a.v.resize(n);
  for (float& f : a.v) {
    const float s = g(rng);
    f = s * s;  // a second moment: never negative
  }
  return a;
}

}  // namespace

TEST_CASE("adam: adam_step_arrays is adam_step on each array for 1, 2 and 3 threads") {
  const gs::simd::KernelTable& kt = gs::simd::best_kernel_table();
  const size_t sizes[] = {40000, 0, 5, 16384, 16385, 3000};
  std::mt19937_64 rng(23);
  std::vector<Array> start;
  for (size_t n : sizes) start.push_back(random_array(rng, n));
  std::vector<Array> expect = start;
  for (size_t i = 0; i < expect.size(); ++i) {
    const gs::simd::AdamParams p = gs::optim::adam_params(1e-3 * double(i + 1), int64_t(7 + i));
    Array& a = expect[i];
    gs::optim::adam_step(kt, nullptr, p, a.param.size(), a.param.data(), a.grad.data(), a.m.data(), a.v.data());
  }
  for (int threads : {1, 2, 3}) {
    CAPTURE(threads);
    gs::platform::ThreadPool pool(threads);
    std::vector<Array> got = start;
    std::vector<gs::optim::AdamArray> arrays;
    for (size_t i = 0; i < got.size(); ++i) {
      Array& a = got[i];
      arrays.push_back(gs::optim::AdamArray{gs::optim::adam_params(1e-3 * double(i + 1), int64_t(7 + i)), a.param.size(),
                                            a.param.data(), a.grad.data(), a.m.data(), a.v.data()});
    }
    gs::optim::adam_step_arrays(kt, &pool, arrays.data(), arrays.size());
    for (size_t i = 0; i < got.size(); ++i) {
      CAPTURE(i);
      CHECK(got[i].param == expect[i].param);
      CHECK(got[i].m == expect[i].m);
      CHECK(got[i].v == expect[i].v);
      if (!start[i].param.empty()) CHECK(got[i].param != start[i].param);
    }
  }
}
