// SPDX-License-Identifier: MIT
// The int8 decoder of the on-device path: the MLPs of a compact model (int8 weights with one scale
// per output row, activation ranges calibrated on the training views; gs/model/compact_model.h)
// prepared for the integer kernel qmlp_fwd (gs/simd/qmlp.h): weights transposed and widened,
// biases in accumulator units, requantisation multipliers and shifts per output channel.
//   input   x_q = sat16(round(x / s_in)),       s_in  = max |input| / 32767 over the calibration
//   hidden  h_q = clamp(rq(acc1), 0, 32767),    s_hid = max hidden / 32767
//   output  y = act2(y_q s_out),                s_out = max |pre-activation output| / 32767
// so one MLP evaluation is integer from the quantised input to the int16 output.
#pragma once

#include <cstdint>
#include <vector>

#include "gs/model/compact_model.h"
#include "gs/model/hybrid_model.h"
#include "gs/simd/qmlp.h"
#include "gs/status.h"

namespace gs::model {

struct QuantMlpKernel {
  bool present = false;
  int32_t in = 0, hidden = 0, out = 0;
  simd::MlpAct act2 = simd::MlpAct::kNone;
  float in_inv_scale = 1, out_scale = 1;  // 1 / s_in, s_out
  std::vector<int32_t> w1t, b1, m1, s1, w2t, b2, m2, s2;
  // The kernel's view (pointers into the vectors above; valid while this object is unchanged).
  simd::QMlpParams params() const {
    return simd::QMlpParams{in, hidden, out, simd::qmlp_pad(hidden), simd::qmlp_pad(out), w1t.data(), b1.data(), m1.data(),
                            s1.data(), w2t.data(), b2.data(), m2.data(), s2.data()};
  }
};

struct QuantDecoder {
  QuantMlpKernel mlps[kMlpCount];
  int32_t max_in = 0, max_hidden = 0, max_out = 0;  // widest MLP (scratch sizing)
};

// Prepares the MLPs of a compact model; refuses a model without calibrated ranges (one made without
// training views) or widths beyond the kernel's.
Expected<QuantDecoder> prepare_quant_decoder(const CompactModel& compact);

}  // namespace gs::model
