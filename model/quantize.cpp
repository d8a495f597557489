// SPDX-License-Identifier: MIT
// The compact model's quantisers (quantize.h), IEEE half precision and the activation-range
// scales of the int8 kernels (gs/model/compact_model.h).
#include "quantize.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace gs::model {

namespace {

float max_of(const std::vector<float>& v) {
  float m = 0;
  for (float x : v) m = std::max(m, x);
  return m;
}

}  // namespace

namespace detail {

int8_t q8(float v, float scale) {
  if (!(scale > 0)) return 0;
  return int8_t(std::clamp(std::lround(double(v) / double(scale)), -127L, 127L));
}

void quantize_channels(const float* src, size_t rows, size_t C, int levels, std::vector<int8_t>* q, std::vector<float>* scale) {
  scale->assign(C, 0.0f);
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < C; ++c) (*scale)[c] = std::max((*scale)[c], std::fabs(src[r * C + c]));
  for (float& s : *scale) s /= float(levels);
  q->resize(rows * C);
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < C; ++c) (*q)[r * C + c] = q8(src[r * C + c], (*scale)[c]);
}

void quantize_mlp(const Mlp& m, bool fine, QuantMlp* q) {
  const simd::MlpShape& s = m.shape;
  q->shape = s;
  const float* p = m.params.data();
  const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out);
  auto rows = [fine](const float* w, size_t n_rows, size_t n_cols, std::vector<int8_t>* qw, std::vector<float>* sc,
                     std::vector<int8_t>* qf) {
    qw->resize(n_rows * n_cols);
    sc->assign(n_rows, 0.0f);
    qf->assign(fine ? n_rows * n_cols : 0, 0);
    for (size_t r = 0; r < n_rows; ++r) {
      float a = 0;
      for (size_t c = 0; c < n_cols; ++c) a = std::max(a, std::fabs(w[r * n_cols + c]));
      (*sc)[r] = a / 127.0f;
      for (size_t c = 0; c < n_cols; ++c) {
        const int8_t v = q8(w[r * n_cols + c], (*sc)[r]);
        (*qw)[r * n_cols + c] = v;
        // The remainder is within half a step (|v| <= 127 never clips: the row's maximum is 127 steps).
        if (fine) (*qf)[r * n_cols + c] = q8(w[r * n_cols + c] - float(v) * (*sc)[r], (*sc)[r] / 254.0f);
      }
    }
  };
  rows(p, H, I, &q->w1, &q->w1_scale, &q->w1_fine);
  q->b1.assign(p + Mlp::off_b1(s), p + Mlp::off_b1(s) + H);
  rows(p + Mlp::off_W2(s), O, H, &q->w2, &q->w2_scale, &q->w2_fine);
  q->b2.assign(p + Mlp::off_b2(s), p + Mlp::off_b2(s) + O);
}

Mlp dequantize_mlp(const QuantMlp& q) {
  Mlp m;
  m.shape = q.shape;
  m.params.assign(Mlp::param_count(q.shape), 0.0f);
  const size_t I = size_t(q.shape.in), H = size_t(q.shape.hidden), O = size_t(q.shape.out);
  float* p = m.params.data();
  auto weight = [](const std::vector<int8_t>& w, const std::vector<int8_t>& fine, size_t i, float scale) {
    return fine.empty() ? float(w[i]) * scale : (float(w[i]) + float(fine[i]) / 254.0f) * scale;
  };
  for (size_t r = 0; r < H; ++r)
    for (size_t c = 0; c < I; ++c) p[r * I + c] = weight(q.w1, q.w1_fine, r * I + c, q.w1_scale[r]);
  std::copy(q.b1.begin(), q.b1.end(), p + Mlp::off_b1(q.shape));
  float* w2 = p + Mlp::off_W2(q.shape);
  for (size_t r = 0; r < O; ++r)
    for (size_t c = 0; c < H; ++c) w2[r * H + c] = weight(q.w2, q.w2_fine, r * H + c, q.w2_scale[r]);
  std::copy(q.b2.begin(), q.b2.end(), p + Mlp::off_b2(q.shape));
  return m;
}

}  // namespace detail

float ActivationRanges::input_scale() const { const float m = max_of(in_absmax); return m > 0 ? m / 127.0f : 1.0f; }
float ActivationRanges::hidden_scale() const { const float m = max_of(hidden_max); return m > 0 ? m / 127.0f : 1.0f; }
float ActivationRanges::output_scale() const { const float m = max_of(out_absmax); return m > 0 ? m / 32767.0f : 1.0f; }

uint16_t float_to_half(float f) {
  uint32_t x;
  std::memcpy(&x, &f, 4);
  const uint16_t sign = uint16_t((x >> 16) & 0x8000u);
  const uint32_t ax = x & 0x7fffffffu;
  if (ax >= 0x7f800000u) return uint16_t(sign | 0x7c00u | (ax > 0x7f800000u ? 0x200u : 0u));  // inf / NaN
  if (ax >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // rounds to >= 65520: infinity
  if (ax < 0x38800000u) {  // below the smallest normal half (2^-14): subnormal or zero
    if (ax < 0x33000000u) return sign;  // < 2^-25 rounds to zero
    const uint32_t mant = (ax & 0x7fffffu) | 0x800000u;
    const int shift = 126 - int(ax >> 23);  // 14..24 (2^e with e = exp - 127, half sub unit 2^-24)
    const uint32_t q = mant >> shift, rem = mant & ((1u << shift) - 1), half = 1u << (shift - 1);
    const uint32_t r = q + ((rem > half || (rem == half && (q & 1u))) ? 1u : 0u);
    return uint16_t(sign | r);
  }
  const uint32_t e = (ax >> 23) - 112;  // rebias 127 -> 15
  uint32_t h = (e << 10) | ((ax >> 13) & 0x3ffu);
  const uint32_t rem = ax & 0x1fffu;
  if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) ++h;  // carries into the exponent correctly
  return uint16_t(sign | h);
}

float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
  uint32_t x;
  if (e == 0) {
    if (m == 0) {
      x = sign;
    } else {  // subnormal: m 2^-24
      const float v = float(m) * 5.9604644775390625e-8f;
      std::memcpy(&x, &v, 4);
      x |= sign;
    }
  } else if (e == 31) {
    x = sign | 0x7f800000u | (m << 13);
  } else {
    x = sign | ((e + 112) << 23) | (m << 13);
  }
  float f;
  std::memcpy(&f, &x, 4);
  return f;
}

}  // namespace gs::model
