// SPDX-License-Identifier: MIT
// Private to gs_model: the quantisers of the compact model (docs/MODEL.md "Compact model file"):
// symmetric int8 values and per-channel scales, int8 MLPs with a scale per output channel, and
// the 24-bit position grid. Half precision (float_to_half) is in gs/model/compact_model.h.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/model/compact_model.h"
#include "gs/model/hybrid_model.h"

namespace gs::model::detail {

constexpr uint32_t kMaxPositionQ = (1u << 24) - 1;  // positions are stored as 3 bytes per axis

// round(v / scale) clamped to [-127, 127]; 0 when scale is not positive.
int8_t q8(float v, float scale);
// Symmetric int8 per channel: channel c of row r is src[r * C + c]; scale[c] = max |channel| / levels
// (levels in 1..127).
void quantize_channels(const float* src, size_t rows, size_t C, int levels, std::vector<int8_t>* q, std::vector<float>* scale);
// An MLP as int8 weights with one scale per output channel (rows of W1 and W2), float biases;
// fine: also each weight's rounding remainder (QuantMlp::w1_fine, w2_fine).
void quantize_mlp(const Mlp& m, bool fine, QuantMlp* q);
Mlp dequantize_mlp(const QuantMlp& q);

}  // namespace gs::model::detail
