// SPDX-License-Identifier: MIT
// The hybrid anchor model (ALGORITHM.md Part A items 2-4): Scaffold-style anchors with learned
// features, k offsets and 6 log-scales, optionally fused with image-based features, and the tiny
// MLPs that decode neural Gaussians per view. Also its versioned binary file format.
//
// Memory: every per-anchor array has capacity() rows, rows [0, anchor_count) live. capacity()
// follows the scene: create_model allocates rows for the initial anchors, the trainer grows the rows
// (by half again, at densification steps only) up to the hard budget config.anchor_capacity().
#pragma once

#include <cstddef>
#include <memory>
#include <cstdint>
#include <string>
#include <vector>

#include "gs/scene_frame.h"
#include "gs/simd/mlp.h"
#include "gs/status.h"

namespace gs::model {

// Image-based feature mode: kNone is plain Scaffold-GS (the ablation baseline); kPaper the paper's
// feature (the colour of the one view that sees the anchor best, and the ray's deviation from its
// optical axis); kVisible hbgs's design (the mean and spread of the colour over the best views in
// which no other anchor hides the anchor; gs/model/image_features.h).
enum class ImageFeatureMode : int32_t { kNone = 0, kPaper = 1, kVisible = 2 };
// True for the modes that feed an image feature g = F(raw) to the decoders.
inline bool uses_image_features(ImageFeatureMode mode) { return mode != ImageFeatureMode::kNone; }
const char* image_feature_mode_name(ImageFeatureMode mode);
Expected<ImageFeatureMode> parse_image_feature_mode(const std::string& text);

// Raw image-feature vector per anchor (input of the learned MLP F): bilinear colour at pyramid
// levels 0, 1, 2 (9 values in [0, 1]), the unit ray camera->anchor in the chosen camera's frame minus
// the optical axis (3), and a valid flag (1; all 13 values are 0 when no training view sees it).
constexpr int kImageRawDim = 13;
constexpr int kImagePyramidLevels = 3;

struct ModelConfig {
  int k = 10;                     // neural Gaussians (offsets) per anchor
  int feature_dim = 32;           // learned anchor feature f
  int hidden = 32;                // hidden width of the decoder MLPs
  ImageFeatureMode image_features = ImageFeatureMode::kPaper;
  int image_feature_dim = 16;     // g = F(raw), concatenated with f
  int image_feature_hidden = 32;  // hidden width of F
  size_t max_anchors = 50000;     // hard budget on anchors (initial + grown)
  size_t max_gaussians = 500000;  // hard budget on neural Gaussians per view (anchors x k)
  float voxel_size = 0.0f;        // eps, world units; 0 = automatic from the point spacing

  // Decoder input width: [f ; g ; view direction (3) ; distance (1)].
  int decoder_input_dim() const {
    return feature_dim + (uses_image_features(image_features) ? image_feature_dim : 0) + 4;
  }
  // Rows allocated per anchor array: min(max_anchors, max_gaussians / k).
  size_t anchor_capacity() const;
  Status validate() const;
};

// One 2-layer MLP with its parameters packed as [W1 (H x I) | b1 (H) | W2 (O x H) | b2 (O)].
struct Mlp {
  simd::MlpShape shape{1, 1, 1, simd::MlpAct::kNone};
  std::vector<float> params;
  static size_t param_count(const simd::MlpShape& s) {
    return size_t(s.hidden) * size_t(s.in) + size_t(s.hidden) + size_t(s.out) * size_t(s.hidden) + size_t(s.out);
  }
  // Offsets of the four blocks inside a packed parameter array.
  static size_t off_b1(const simd::MlpShape& s) { return size_t(s.hidden) * size_t(s.in); }
  static size_t off_W2(const simd::MlpShape& s) { return off_b1(s) + size_t(s.hidden); }
  static size_t off_b2(const simd::MlpShape& s) { return off_W2(s) + size_t(s.out) * size_t(s.hidden); }
};

// The four MLPs in a fixed order (used for file layout and optimiser groups).
enum MlpId : int { kMlpOpacity = 0, kMlpCov = 1, kMlpColor = 2, kMlpImage = 3, kMlpCount = 4 };

struct HybridModel {
  ModelConfig config;
  size_t anchor_count = 0;   // live rows M
  float voxel_size = 0.0f;   // eps actually used
  float scene_extent = 1.0f; // 1.1 x max distance of a training camera centre from their mean
  // The frame the model lives in (gs/scene_frame.h; its dataset's, io::Dataset::frame): positions,
  // offsets, scales and scene_extent are in its units. Outputs for the user (exported Gaussians,
  // poses) are converted back to the user's frame with it; datasets are loaded into it.
  SceneFrame frame;
  std::vector<float> positions;   // [cap, 3] fixed
  std::vector<float> offsets;     // [cap, k, 3]
  std::vector<float> log_scales;  // [cap, 6]: [0:3] offset scale, [3:6] Gaussian base scale
  std::vector<float> features;    // [cap, F]
  std::vector<float> image_raw;   // [cap, kImageRawDim] (kPaper), refreshed from the training views
  Mlp mlps[kMlpCount];            // opacity (tanh, k), cov (none, 7k), colour (sigmoid, 3k), image F

  size_t capacity() const { return positions.size() / 3; }
  // Bytes of the live model on disk (header + live rows + MLPs).
  uint64_t file_bytes() const;
};

// Builds the initial model from SfM points [n, 3]: anchors (voxelised, 3-NN log-scales, zero offsets
// and features) with the automatic voxel size aiming at half the anchor budget (room to grow), and
// MLPs with PyTorch-default uniform init from a seeded generator. scene_extent as documented above.
// Errors: no points, non-finite points, invalid config.
Expected<HybridModel> create_model(const ModelConfig& config, const float* xyz, size_t n, float scene_extent,
                                   uint64_t seed);

// Shape of MLP `id` (MlpId) for a configuration: what every model file's MLP must match.
simd::MlpShape model_mlp_shape(const ModelConfig& config, int id);

// Model file: magic "HBGSMODL", format version, config, (version 2: the scene frame, centre[3] and
// scale as f64), live rows, MLPs; little-endian; written atomically. A model in the identity frame
// is written as version 1, byte for byte as before frames existed (older hbgs reads it); another
// frame needs version 2. Reading accepts both (version 1: the identity frame) and refuses other
// versions, truncated or inconsistent files with a message.
constexpr uint32_t kModelFileVersion = 2;
std::vector<uint8_t> serialize_model(const HybridModel& model);
// The same bytes appended to *out (the trainer's checkpoint embeds them without a second copy), and
// their count (serialize_model reserves exactly that: no growth doubling of the buffer).
void append_serialized_model(const HybridModel& model, std::vector<uint8_t>* out);
size_t serialized_model_size(const HybridModel& model);
Expected<HybridModel> deserialize_model(const uint8_t* data, size_t size, const std::string& source,
                                        size_t* consumed = nullptr);
// Refuses (kNumerical, naming the array and anchor) a model holding NaN or infinity in its live rows
// or MLPs: save_model and the trainer's checkpoint never write one, and loading refuses one.
Status check_model_finite(const HybridModel& model, const std::string& source);
Status save_model(const HybridModel& model, const std::string& path);
// Reads a float model file or a compact one ("HBGSCMPT", gs/model/compact_model.h, dequantised),
// told apart by the magic, not the extension.
// compact (optional): set to the compact model when the file is one (the int8 decoder needs its
// weights and ranges), left empty otherwise.
struct CompactModel;
Expected<HybridModel> load_model(const std::string& path, std::unique_ptr<CompactModel>* compact = nullptr);

}  // namespace gs::model
