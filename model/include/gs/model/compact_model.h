// SPDX-License-Identifier: MIT
// The compact model file (issue 14 part 4): a HybridModel quantised for storage and for the
// integer decoder, entropy-coded with a static rANS coder per channel, plus the activation ranges
// calibrated on the training views that the int8 MLP kernels need. load_model() (hybrid_model.h)
// reads either file kind by its magic, so every float path can use a compact file.
//
// Quantisation (docs/MODEL.md "The compact model file"; rows in Morton order of their voxel cell):
//   positions   q = round((p - origin) / step), step = voxel_size / 2^residual_bits, u24 per axis
//               (the integer voxel coordinate is q >> residual_bits, the residual its low bits)
//   offsets     int8, symmetric, one fp16 step per anchor (per-channel scales cost 0.036 dB on the
//               built-in scene: a few large offsets set every anchor's step), measured from the
//               training views' sensitivity to the anchor; 0 for a Gaussian no view keeps
//               (version 4 codes which Gaussians have an offset, then only theirs)
//   log-scales  a uniform grid per channel, log_scale_lo[c] + q log_scale_step, q uint16
//               (version 1 files: fp16)
//   features    int8, symmetric, one step per feature channel, by its first-layer weight
//   image_raw   uint8, affine per channel in image_levels steps (the valid flag is exact; invalid
//               rows stay all zero)
//   MLPs        int8 weights with one float scale per output channel (rows of W1 and W2), float
//               biases; version 2 adds each weight's rounding remainder in 1/254 of its step (the
//               float path reads both, the int8 decoder the int8 weights alone)
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

constexpr uint32_t kCompactFileVersion = 4;  // versions 1 to 3 are still read
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
  // Empty, or the rounding remainder of every weight in 1/254 of its row's step:
  // W = (w + fine / 254) scale (|fine| <= 127). The int8 decoder ignores them.
  std::vector<int8_t> w1_fine;  // [H, I]
  std::vector<int8_t> w2_fine;  // [O, H]
  ActivationRanges ranges;
};

struct CompactModel {
  ModelConfig config;
  float voxel_size = 0.0f, scene_extent = 1.0f;
  SceneFrame frame;               // HybridModel::frame (version 3 and on; older files: the identity)
  size_t anchor_count = 0;        // M (after pruning)
  uint64_t source_anchors = 0;    // anchors of the float model it was made from
  uint32_t calibration_views = 0; // views the activation ranges were measured on
  int residual_bits = 8;          // 0..12
  double origin[3] = {0, 0, 0};   // world position of q = 0
  std::vector<uint32_t> pos_q;    // [M, 3], each < 2^24
  std::vector<int8_t> offsets;    // [M, k, 3]
  std::vector<uint16_t> offset_scale;  // [M] fp16: one scale per anchor over its 3k offsets
  std::vector<uint16_t> log_scales; // [M, 6]: grid indices, or fp16 bits when log_scale_step is 0
  float log_scale_step = 0.0f;      // > 0: log-scale = log_scale_lo[c] + q step; 0: fp16 (version 1)
  float log_scale_lo[6] = {};
  std::vector<int8_t> features;     // [M, F]
  std::vector<float> feature_scale; // [F]
  std::vector<uint8_t> image_raw;   // [M, 13] (mode paper), 0..image_levels
  int image_levels = 255;           // 1..255: value = lo + q (hi - lo) / image_levels
  float image_lo[kImageRawDim] = {}, image_hi[kImageRawDim] = {};
  QuantMlp mlps[kMlpCount];         // kMlpImage only in mode paper
};

struct CompactOptions {
  bool prune = true;       // drop anchors none of whose Gaussians is kept (opacity > 0) in any view
  int residual_bits = 8;   // position sub-voxel bits
  // Quantisation steps (defaults measured in docs/MODEL.md "The compact model file"): the largest
  // |value| of an anchor's offsets / of a feature channel is this many steps (1..127), or with
  // weighting the steps give the rendered error that would have; image features span
  // image_levels steps (1..255); log-scales are on a grid of log_scale_step (natural log; 0: fp16).
  int offset_levels = 80;
  int feature_levels = 80;
  int image_levels = 15;
  float log_scale_step = 0.02f;
  bool mlp_fine = true;    // store the MLP weights' rounding remainders (float path precision)
  // Store 0 for the offset of every neural Gaussian no view keeps (opacity <= 0 in all of them).
  bool prune_offsets = true;
  // Feature steps per channel by the channel's weight in the decoders' first layers.
  bool weighted_features = true;
  // Offset steps per anchor by the measured sensitivity of the training views to its offsets
  // (a render and a backward per view).
  bool weighted_offsets = true;
};

// What compact_from_model did.
struct CompactStats {
  size_t anchors_in = 0, anchors_out = 0, never_visible = 0;
  size_t views = 0;
  size_t offsets_dropped = 0;
  size_t low_contribution = 0;  // anchors pruned for adding less than min_contribution to every view  // neural Gaussians (of the kept anchors) whose offset was stored as 0
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
// One part of a written file (what bench_compact and the docs' byte table report): group (e.g.
// "features"), coded bytes (tables and payload, or raw bytes), symbols coded, and the order-0
// entropy of those symbols in bytes (0 for raw parts).
struct CompactSection {
  std::string group;
  size_t bytes = 0, symbols = 0;
  double entropy_bytes = 0;
};
// The byte streams the file entropy-codes, in file order (group names as in CompactSection), one
// symbol per anchor, except the offsets' channels (one per neural Gaussian whose offset is set):
// what serialize_compact codes and bench_entropy measures.
struct CompactStream {
  std::string group;
  std::vector<uint8_t> symbols;
};
std::vector<CompactStream> compact_streams(const CompactModel& model);
// Version 4's offset masks: the k slots of an anchor in `streams` byte streams of `bits` slots each
// (bit b of stream g: slot g bits + b has an offset other than (0, 0, 0)); k = 10: 2 x 5 bits.
struct OffsetMaskLayout {
  explicit OffsetMaskLayout(size_t k);
  size_t streams, bits;
};
// sections (optional): appended in file order, one per stream or raw block.
std::vector<uint8_t> serialize_compact(const CompactModel& model, std::vector<CompactSection>* sections = nullptr);
Expected<CompactModel> deserialize_compact(const uint8_t* data, size_t size, const std::string& source);
Status save_compact(const CompactModel& model, const std::string& path);  // atomic
Expected<CompactModel> load_compact(const std::string& path);
// True when the bytes start with the compact magic.
bool is_compact_file(const uint8_t* data, size_t size);

}  // namespace gs::model
