// SPDX-License-Identifier: MIT
// The compact model file (issue 14 part 4): a HybridModel quantised for storage and for the
// integer decoder, entropy-coded with a static rANS coder per channel, plus the activation ranges
// calibrated on the training views that the int8 MLP kernels need. load_model() (hybrid_model.h)
// reads either file kind by its magic, so every float path can use a compact file.
//
// Quantisation (docs/MODEL.md "Compact model file"):
//   positions   q = round((p - origin) / step), step = voxel_size / 2^residual_bits, u24 per axis
//               (the integer voxel coordinate is q >> residual_bits, the residual its low bits)
//   offsets     int8, symmetric, one fp16 scale per anchor (per-channel scales cost 0.036 dB on the
//               built-in scene: a few large offsets set every anchor's step)
//   log-scales  fp16
//   features    int8, symmetric, one scale per feature channel
//   image_raw   uint8, affine per channel (the valid flag is exact; invalid rows stay all zero)
//   MLPs        int8 weights with one float scale per output channel (rows of W1 and W2), float biases
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::model {

constexpr uint32_t kCompactFileVersion = 1;
constexpr char kCompactMagic[8] = {'H', 'B', 'G', 'S', 'C', 'M', 'P', 'T'};

// Calibrated activation ranges of one MLP over the visible anchors of every calibration view (the
// maximum, no percentile clipping): |input| per input channel, post-ReLU hidden per hidden unit,
// |pre-activation output| per output. The per-tensor scales are what the int8 kernels use:
// input int8 symmetric, hidden int8 after ReLU, output int16.
struct ActivationRanges {
  std::vector<float> in_absmax;   // [I]
  std::vector<float> hidden_max;  // [H]
  std::vector<float> out_absmax;  // [O], before tanh / sigmoid
  float input_scale() const;      // max(in_absmax) / 127 (1 when all are 0)
  float hidden_scale() const;     // max(hidden_max) / 127
  float output_scale() const;     // max(out_absmax) / 32767
};

// One MLP, int8 weights with per-output-channel scales: W1[h][i] = w1[h I + i] * w1_scale[h].
struct QuantMlp {
  simd::MlpShape shape{1, 1, 1, simd::MlpAct::kNone};
  std::vector<int8_t> w1;       // [H, I]
  std::vector<float> w1_scale;  // [H]
  std::vector<float> b1;        // [H]
  std::vector<int8_t> w2;       // [O, H]
  std::vector<float> w2_scale;  // [O]
  std::vector<float> b2;        // [O]
  ActivationRanges ranges;
};

struct CompactModel {
  ModelConfig config;
  float voxel_size = 0.0f, scene_extent = 1.0f;
  size_t anchor_count = 0;        // M (after pruning)
  uint64_t source_anchors = 0;    // anchors of the float model it was made from
  uint32_t calibration_views = 0; // views the activation ranges were measured on
  int residual_bits = 8;          // 0..12
  double origin[3] = {0, 0, 0};   // world position of q = 0
  std::vector<uint32_t> pos_q;    // [M, 3], each < 2^24
  std::vector<int8_t> offsets;    // [M, k, 3]
  std::vector<uint16_t> offset_scale;  // [M] fp16: one scale per anchor over its 3k offsets
  std::vector<uint16_t> log_scales; // [M, 6] fp16 bits
  std::vector<int8_t> features;     // [M, F]
  std::vector<float> feature_scale; // [F]
  std::vector<uint8_t> image_raw;   // [M, 13] (mode paper)
  float image_lo[kImageRawDim] = {}, image_hi[kImageRawDim] = {};
  QuantMlp mlps[kMlpCount];         // kMlpImage only in mode paper
};

struct CompactOptions {
  bool prune = true;       // drop anchors none of whose Gaussians is kept (opacity > 0) in any view
  int residual_bits = 8;   // position sub-voxel bits
};

// What compact_from_model did.
struct CompactStats {
  size_t anchors_in = 0, anchors_out = 0, never_visible = 0;
  size_t views = 0;
  std::vector<size_t> source_rows;  // [anchors_out]: row r of the compact model is this float row
};

// Quantises a float model. cameras: the training views (pruning and calibration); may be empty,
// then nothing is pruned and the ranges stay zero. pool may be null.
Expected<CompactModel> compact_from_model(const HybridModel& model, const std::vector<Camera>& cameras,
                                          const CompactOptions& options, platform::ThreadPool* pool,
                                          CompactStats* stats = nullptr);
// The float model the compact one stands for (rows = anchor_count; budgets from the source config).
HybridModel dequantize(const CompactModel& compact);

// IEEE half precision, round to nearest even (overflow to infinity, NaN kept).
uint16_t float_to_half(float f);
float half_to_float(uint16_t h);

// File: "HBGSCMPT", version, header, channel streams coded with byte rANS (gs/model/byte_rans.h),
// raw MLP blocks, FNV-1a 64 trailer (verified before any array is sized). Every count is checked
// against the configuration and the bytes present; errors name the file, the field and what was
// expected.
std::vector<uint8_t> serialize_compact(const CompactModel& model);
Expected<CompactModel> deserialize_compact(const uint8_t* data, size_t size, const std::string& source);
Status save_compact(const CompactModel& model, const std::string& path);  // atomic
Expected<CompactModel> load_compact(const std::string& path);
// True when the bytes start with the compact magic.
bool is_compact_file(const uint8_t* data, size_t size);

}  // namespace gs::model
