// SPDX-License-Identifier: MIT
// Reference int8 decoder MLP (the spec of qmlp_fwd, gs/simd/qmlp.h): plain loops, int32 sums.
#include "gs/simd/qmlp.h"

namespace gs::simd {

void qmlp_fwd_ref(const QMlpParams* p, int32_t batch, const int8_t* x, int8_t* hidden, int16_t* y) {
  int32_t acc[kQMlpMaxWidth];
  const int32_t I = p->in, H = p->hidden, O = p->out;
  for (int32_t b = 0; b < batch; ++b) {
    const int8_t* xr = x + size_t(b) * size_t(I);
    int8_t* hr = hidden + size_t(b) * size_t(H);
    for (int32_t h = 0; h < H; ++h) {
      int32_t a = p->b1[h];
      for (int32_t i = 0; i < I; ++i) a += int32_t(xr[i]) * p->w1t[size_t(i) * size_t(p->hidden_pad) + size_t(h)];
      acc[h] = a;
    }
    qmlp_requant_hidden(p, acc, hr);
    for (int32_t o = 0; o < O; ++o) {
      int32_t a = p->b2[o];
      for (int32_t h = 0; h < H; ++h) a += int32_t(hr[h]) * p->w2t[size_t(h) * size_t(p->out_pad) + size_t(o)];
      acc[o] = a;
    }
    qmlp_requant_out(p, acc, y + size_t(b) * size_t(O));
  }
}

}  // namespace gs::simd
