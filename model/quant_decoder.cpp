// SPDX-License-Identifier: MIT
// Preparation of the int8 decoder (gs/model/quant_decoder.h): scales to multipliers and shifts.
#include "gs/model/quant_decoder.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace gs::model {
namespace {

int32_t clamp_round(double v) {
  if (!(v > -2147483648.0)) return INT32_MIN;
  if (v >= 2147483647.0) return INT32_MAX;
  return int32_t(std::lround(v));
}

void multiplier(double real, int32_t* m, int32_t* s) {
  int shift = 0;
  simd::fxp::quantize_multiplier(real, m, &shift);
  *s = shift;
}

}  // namespace

Expected<QuantDecoder> prepare_quant_decoder(const CompactModel& cm) {
  QuantDecoder qd;
  if (cm.calibration_views == 0)
    return invalid_argument("int8 decoder: the compact model has no activation ranges (made without training views); "
                            "remake it with hbgs compact and the dataset");
  for (int id = 0; id < kMlpCount; ++id) {
    const QuantMlp& q = cm.mlps[id];
    if (q.w1.empty()) continue;
    const int32_t I = q.shape.in, H = q.shape.hidden, O = q.shape.out;
    if (I < 1 || H < 1 || O < 1 || I > simd::kQMlpMaxWidth || H > simd::kQMlpMaxWidth || O > simd::kQMlpMaxWidth)
      return invalid_argument("int8 decoder: MLP " + std::to_string(id) + " is wider than the kernel's " +
                              std::to_string(simd::kQMlpMaxWidth));
    if (q.ranges.in_absmax.size() != size_t(I) || q.ranges.hidden_max.size() != size_t(H) || q.ranges.out_absmax.size() != size_t(O))
      return invalid_argument("int8 decoder: the compact model has no activation ranges (made without training views); "
                              "remake it with hbgs compact and the dataset");
    QuantMlpKernel& k = qd.mlps[id];
    k.present = true;
    k.act2 = q.shape.act2;
    // int16 activations: each scale spreads its calibrated maximum over 32767 levels.
    auto scale = [](const std::vector<float>& m) {
      const float mx = *std::max_element(m.begin(), m.end());
      return mx > 0 ? double(mx) / 32767.0 : 1.0;
    };
    const double s_in = scale(q.ranges.in_absmax), s_hid = scale(q.ranges.hidden_max), s_out = scale(q.ranges.out_absmax);
    k.in_inv_scale = float(1.0 / s_in);
    k.out_scale = float(s_out);
    const int32_t Hp = simd::qmlp_pad(H), Op = simd::qmlp_pad(O);
    k.w1t.assign(size_t(I) * size_t(Hp), 0);
    k.w2t.assign(size_t(H) * size_t(Op), 0);
    for (int32_t h = 0; h < H; ++h)
      for (int32_t i = 0; i < I; ++i) k.w1t[size_t(i) * size_t(Hp) + size_t(h)] = q.w1[size_t(h) * size_t(I) + size_t(i)];
    for (int32_t o = 0; o < O; ++o)
      for (int32_t h = 0; h < H; ++h) k.w2t[size_t(h) * size_t(Op) + size_t(o)] = q.w2[size_t(o) * size_t(H) + size_t(h)];
    k.b1.assign(size_t(Hp), 0);
    k.b2.assign(size_t(Op), 0);
    k.m1.assign(size_t(H), 0);
    k.s1.assign(size_t(H), 0);
    k.m2.assign(size_t(O), 0);
    k.s2.assign(size_t(O), 0);
    // A row whose weights are all zero has scale 0; any scale represents it (its sum is the bias).
    for (int32_t h = 0; h < H; ++h) {
      const double acc_scale = s_in * (q.w1_scale[size_t(h)] > 0 ? double(q.w1_scale[size_t(h)]) : 1.0);
      k.b1[size_t(h)] = clamp_round(double(q.b1[size_t(h)]) / acc_scale);
      multiplier(acc_scale / s_hid, &k.m1[size_t(h)], &k.s1[size_t(h)]);
    }
    for (int32_t o = 0; o < O; ++o) {
      const double acc_scale = s_hid * (q.w2_scale[size_t(o)] > 0 ? double(q.w2_scale[size_t(o)]) : 1.0);
      k.b2[size_t(o)] = clamp_round(double(q.b2[size_t(o)]) / acc_scale);
      multiplier(acc_scale / s_out, &k.m2[size_t(o)], &k.s2[size_t(o)]);
    }
    k.in = I;
    k.hidden = H;
    k.out = O;
    qd.max_in = std::max(qd.max_in, I);
    qd.max_hidden = std::max(qd.max_hidden, H);
    qd.max_out = std::max(qd.max_out, O);
  }
  return qd;
}

}  // namespace gs::model
