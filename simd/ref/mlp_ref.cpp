// SPDX-License-Identifier: MIT
// Reference decoder MLP (forward, backward) and Adam step, the spec of simd/kernels/mlp/: plain
// loops in the order of the formulas in mlp.h, dot products accumulated in double.
#include <cmath>

#include "gs/simd/mlp.h"

namespace gs::simd {

template <class T>
void mlp_fwd_ref(const MlpShape* s, int32_t batch, const T* x, const T* W1, const T* b1, const T* W2, const T* b2,
                 T* hidden, T* y) {
  const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
  for (size_t r = 0; r < size_t(batch); ++r) {
    const T* xr = x + r * I;
    T* hr = hidden + r * H;
    for (size_t j = 0; j < H; ++j) {
      double acc = 0;
      for (size_t i = 0; i < I; ++i) acc += double(W1[j * I + i]) * double(xr[i]);
      const T pre = T(acc + double(b1[j]));
      hr[j] = pre > T(0) ? pre : T(0);
    }
    for (size_t o = 0; o < O; ++o) {
      double acc = 0;
      for (size_t j = 0; j < H; ++j) acc += double(W2[o * H + j]) * double(hr[j]);
      y[r * O + o] = mlp_act2<T>(s->act2, T(acc + double(b2[o])));
    }
  }
}

template <class T>
void mlp_bwd_ref(const MlpShape* s, int32_t batch, const T* x, const T* W1, const T* b1, const T* W2, const T* b2,
                 const T* hidden, const T* y, const T* v_y, T* v_x, T* v_W1, T* v_b1, T* v_W2, T* v_b2) {
  (void)b1;
  (void)b2;
  const size_t I = size_t(s->in), H = size_t(s->hidden), O = size_t(s->out);
  for (size_t r = 0; r < size_t(batch); ++r) {
    const T* xr = x + r * I;
    const T* hr = hidden + r * H;
    // Second layer: cotangent of the pre-activation, then W2, b2.
    for (size_t o = 0; o < O; ++o) {
      const T g = v_y[r * O + o] * mlp_act2_deriv<T>(s->act2, y[r * O + o]);
      v_b2[o] += g;
      for (size_t j = 0; j < H; ++j) v_W2[o * H + j] += g * hr[j];
    }
    // Hidden cotangent through W2 and the ReLU (0 where the unit was not positive, including 0),
    // then W1, b1 and x.
    if (v_x)
      for (size_t i = 0; i < I; ++i) v_x[r * I + i] = T(0);
    for (size_t j = 0; j < H; ++j) {
      double acc = 0;
      for (size_t o = 0; o < O; ++o)
        acc += double(v_y[r * O + o] * mlp_act2_deriv<T>(s->act2, y[r * O + o])) * double(W2[o * H + j]);
      const T g = hr[j] > T(0) ? T(acc) : T(0);
      v_b1[j] += g;
      for (size_t i = 0; i < I; ++i) v_W1[j * I + i] += g * xr[i];
      if (v_x)
        for (size_t i = 0; i < I; ++i) v_x[r * I + i] += g * W1[j * I + i];
    }
  }
}

template <class T>
void adam_step_ref(const AdamParams* p, size_t n, T* param, const T* grad, T* m, T* v) {
  const AdamConsts c = adam_consts(p);
  const T b1 = T(p->beta1), b2 = T(p->beta2), eps = T(p->eps);
  const T step_size = T(c.step_size), sqrt_bc2 = T(c.sqrt_bc2);
  for (size_t k = 0; k < n; ++k) {
    const T g = grad[k];
    m[k] = b1 * m[k] + (T(1) - b1) * g;
    v[k] = b2 * v[k] + (T(1) - b2) * (g * g);
    const T denom = std::sqrt(v[k]) / sqrt_bc2 + eps;
    param[k] -= step_size * (m[k] / denom);
  }
}

#define GS_INSTANTIATE(T)                                                                                         \
  template void mlp_fwd_ref<T>(const MlpShape*, int32_t, const T*, const T*, const T*, const T*, const T*, T*, T*); \
  template void mlp_bwd_ref<T>(const MlpShape*, int32_t, const T*, const T*, const T*, const T*, const T*,        \
                               const T*, const T*, const T*, T*, T*, T*, T*, T*);                                 \
  template void adam_step_ref<T>(const AdamParams*, size_t, T*, const T*, T*, T*);
GS_INSTANTIATE(float)
GS_INSTANTIATE(double)
#undef GS_INSTANTIATE

}  // namespace gs::simd
