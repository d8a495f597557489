// SPDX-License-Identifier: MIT
// The hybrid anchor model: configuration checks, initial model from SfM points, and the versioned
// model file (serialise / parse / atomic save / load).
#include "gs/model/hybrid_model.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "byte_codec.h"
#include "gs/model/anchors.h"
#include "gs/model/compact_model.h"
#include "gs/platform/file.h"

namespace gs::model {

namespace {

constexpr char kModelMagic[8] = {'H', 'B', 'G', 'S', 'M', 'O', 'D', 'L'};

simd::MlpShape mlp_shape(const ModelConfig& c, int id) {
  const int D = c.decoder_input_dim();
  switch (id) {
    case kMlpOpacity: return {D, c.hidden, c.k, simd::MlpAct::kTanh};
    case kMlpCov: return {D, c.hidden, 7 * c.k, simd::MlpAct::kNone};
    case kMlpColor: return {D, c.hidden, 3 * c.k, simd::MlpAct::kSigmoid};
    default: return {kImageRawDim, c.image_feature_hidden, c.image_feature_dim, simd::MlpAct::kNone};
  }
}

bool has_image_mlp(const ModelConfig& c) { return uses_image_features(c.image_features); }

// PyTorch's default Linear init: weights and biases ~ U(-1/sqrt(fan_in), 1/sqrt(fan_in)).
void init_mlp(Mlp* mlp, const simd::MlpShape& s, detail::SplitMix64* rng) {
  mlp->shape = s;
  mlp->params.assign(Mlp::param_count(s), 0.0f);
  float* p = mlp->params.data();
  const double b1 = 1.0 / std::sqrt(double(s.in)), b2 = 1.0 / std::sqrt(double(s.hidden));
  for (size_t i = 0; i < Mlp::off_W2(s); ++i) p[i] = float((2 * rng->uniform() - 1) * b1);
  for (size_t i = Mlp::off_W2(s); i < mlp->params.size(); ++i) p[i] = float((2 * rng->uniform() - 1) * b2);
}

}  // namespace

simd::MlpShape model_mlp_shape(const ModelConfig& config, int id) { return mlp_shape(config, id); }

const char* image_feature_mode_name(ImageFeatureMode mode) {
  switch (mode) {
    case ImageFeatureMode::kPaper: return "paper";
    case ImageFeatureMode::kVisible: return "visible";
    default: return "none";
  }
}

Expected<ImageFeatureMode> parse_image_feature_mode(const std::string& text) {
  if (text == "paper") return ImageFeatureMode::kPaper;
  if (text == "none") return ImageFeatureMode::kNone;
  if (text == "visible") return ImageFeatureMode::kVisible;
  return invalid_argument("image feature mode '" + text + "' is not one of: paper, visible, none");
}

size_t ModelConfig::anchor_capacity() const {
  if (k <= 0) return 0;
  return std::min(max_anchors, max_gaussians / size_t(k));
}

Status ModelConfig::validate() const {
  auto in = [](long v, long lo, long hi) { return v >= lo && v <= hi; };
  if (!in(k, 1, 64)) return invalid_argument("model: k (offsets per anchor) = " + std::to_string(k) + " is outside 1..64");
  if (!in(feature_dim, 1, 1024)) return invalid_argument("model: feature dimension " + std::to_string(feature_dim) + " is outside 1..1024");
  if (!in(hidden, 1, 1024)) return invalid_argument("model: MLP hidden width " + std::to_string(hidden) + " is outside 1..1024");
  if (image_features != ImageFeatureMode::kNone && image_features != ImageFeatureMode::kPaper &&
      image_features != ImageFeatureMode::kVisible)
    return invalid_argument("model: unknown image feature mode " + std::to_string(int(image_features)));
  if (uses_image_features(image_features) &&
      (!in(image_feature_dim, 1, 1024) || !in(image_feature_hidden, 1, 1024)))
    return invalid_argument("model: image feature dimensions must be in 1..1024");
  if (!(voxel_size >= 0.0f) || !std::isfinite(voxel_size))
    return invalid_argument("model: voxel size must be 0 (automatic) or a positive finite number");
  if (max_anchors > (size_t(1) << 26) || max_gaussians > (size_t(1) << 30))
    return invalid_argument("model: budgets above 2^26 anchors / 2^30 Gaussians are not supported");
  if (anchor_capacity() < 1)
    return invalid_argument("model: the budgets allow no anchor (max anchors " + std::to_string(max_anchors) +
                            ", max Gaussians " + std::to_string(max_gaussians) + " < k = " + std::to_string(k) + ")");
  return Status::Ok();
}

uint64_t HybridModel::file_bytes() const { return uint64_t(serialize_model(*this).size()); }

// Rows for `cap` anchors: the initial anchors when creating (the trainer grows them), the
// stored count when loading (a file that declares a 50-million-anchor budget but holds 100 anchors
// gets 100 rows).
static void allocate_rows(HybridModel* m, size_t cap) {
  const ModelConfig& c = m->config;
  m->positions.assign(cap * 3, 0.0f);
  m->offsets.assign(cap * size_t(c.k) * 3, 0.0f);
  m->log_scales.assign(cap * 6, 0.0f);
  m->features.assign(cap * size_t(c.feature_dim), 0.0f);
  m->image_raw.assign(has_image_mlp(c) ? cap * size_t(kImageRawDim) : 0, 0.0f);
}

Expected<HybridModel> create_model(const ModelConfig& config, const float* xyz, size_t n, float scene_extent,
                                   uint64_t seed) {
  GS_RETURN_IF_ERROR(config.validate());
  if (n == 0 || !xyz)
    return invalid_argument("model: the dataset has no 3D points; anchors are built from the SfM points "
                            "(points3D.txt / points3D.bin must not be empty)");
  if (!(scene_extent > 0) || !std::isfinite(scene_extent))
    return invalid_argument("model: scene extent must be positive and finite");
  AnchorOptions ao;
  ao.voxel_size = config.voxel_size;
  ao.max_anchors = std::max<size_t>(1, config.anchor_capacity() / 2);  // leave room to grow
  ao.k = config.k;
  ao.feature_dim = config.feature_dim;
  Expected<AnchorSet> anchors = init_anchors(xyz, n, ao);
  if (!anchors.ok()) return anchors.status();
  HybridModel m;
  m.config = config;
  const size_t M = anchors->size();
  if (M > config.anchor_capacity())
    return capacity_exceeded("model: voxel size " + std::to_string(anchors->voxel_size) + " gives " + std::to_string(M) +
                             " anchors, more than the budget of " + std::to_string(config.anchor_capacity()) +
                             " (raise --max-anchors / --max-gaussians or the voxel size)");
  // Rows for the initial anchors (at least 1,024), within the budget: the trainer grows them by half
  // again when densification adds anchors, so memory follows the scene, not the budget (headroom
  // here would be memory no step uses before the first densification).
  allocate_rows(&m, std::min(config.anchor_capacity(), std::max<size_t>(M, 1024)));
  m.anchor_count = M;
  m.voxel_size = anchors->voxel_size;
  m.scene_extent = scene_extent;
  std::copy(anchors->positions.begin(), anchors->positions.end(), m.positions.begin());
  std::copy(anchors->log_scales.begin(), anchors->log_scales.end(), m.log_scales.begin());
  detail::SplitMix64 rng{seed * 0x2545F4914F6CDD1Dull + 1};
  for (int id = 0; id < kMlpCount; ++id)
    if (id != kMlpImage || has_image_mlp(config)) init_mlp(&m.mlps[id], mlp_shape(config, id), &rng);
  return m;
}

// ---- file format ----------------------------------------------------------------------------

size_t serialized_model_size(const HybridModel& m) {
  const ModelConfig& c = m.config;
  detail::ByteWriter header;
  detail::write_model_header(&header, c, m.voxel_size, m.scene_extent);
  const size_t M = m.anchor_count;
  size_t floats = M * (3 + size_t(c.k) * 3 + 6 + size_t(c.feature_dim) + (has_image_mlp(c) ? size_t(kImageRawDim) : 0));
  size_t mlps = 0;
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !has_image_mlp(c)) continue;
    ++mlps;
    floats += m.mlps[id].params.size();
  }
  return 8 + 4 + header.bytes.size() + (m.frame.identity() ? 0 : detail::kSceneFrameBytes) + 8 + 4 * floats + 16 * mlps + 8;
}

void append_serialized_model(const HybridModel& m, std::vector<uint8_t>* out) {
  detail::ByteWriter w;
  w.bytes.swap(*out);  // write after what *out holds, in its storage
  const size_t start = w.bytes.size();
  const ModelConfig& c = m.config;
  w.raw(kModelMagic, 8);
  w.u32(m.frame.identity() ? 1 : kModelFileVersion);
  detail::write_model_header(&w, c, m.voxel_size, m.scene_extent);
  if (!m.frame.identity()) detail::write_scene_frame(&w, m.frame);
  const size_t M = m.anchor_count;
  w.u64(M);
  w.floats(m.positions.data(), M * 3);
  w.floats(m.offsets.data(), M * size_t(c.k) * 3);
  w.floats(m.log_scales.data(), M * 6);
  w.floats(m.features.data(), M * size_t(c.feature_dim));
  if (has_image_mlp(c)) w.floats(m.image_raw.data(), M * size_t(kImageRawDim));
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !has_image_mlp(c)) continue;
    const Mlp& mlp = m.mlps[id];
    w.i32(mlp.shape.in);
    w.i32(mlp.shape.hidden);
    w.i32(mlp.shape.out);
    w.i32(int32_t(mlp.shape.act2));
    w.floats(mlp.params.data(), mlp.params.size());
  }
  w.u64(detail::fnv1a64(w.bytes.data() + start, w.bytes.size() - start));
  w.bytes.swap(*out);
}

std::vector<uint8_t> serialize_model(const HybridModel& m) {
  std::vector<uint8_t> bytes;
  bytes.reserve(serialized_model_size(m));
  append_serialized_model(m, &bytes);
  return bytes;
}

Expected<HybridModel> deserialize_model(const uint8_t* data, size_t size, const std::string& source, size_t* consumed) {
  detail::ByteReader r(data, size, source);
  char magic[8] = {};
  if (!r.bytes(magic, 8, "the file signature")) return r.status();
  if (std::memcmp(magic, kModelMagic, 8) != 0)
    return parse_error(source + ": not an hbgs model file (the first 8 bytes are not \"HBGSMODL\")");
  const uint32_t version = r.u32("the format version");
  if (!r.status().ok()) return r.status();
  if (version < 1 || version > kModelFileVersion)
    return unsupported(source + ": model file format version " + std::to_string(version) + ", but this hbgs reads versions 1 to " +
                       std::to_string(kModelFileVersion) + " (retrain, or use the hbgs release that wrote it)");
  HybridModel m;
  ModelConfig& c = m.config;
  detail::read_model_header(&r, &c, &m.voxel_size, &m.scene_extent);
  if (version >= 2 && !detail::read_scene_frame(&r, &m.frame))
    return r.status().ok() ? parse_error(source + ": " + scene_frame_problem(m.frame)) : r.status();
  const uint64_t M = r.u64("the anchor count");
  if (!r.status().ok()) return r.status();
  Status valid = c.validate();
  if (!valid.ok()) return parse_error(source + ": invalid configuration: " + valid.message());
  // Verify the checksum (of a whole file) before sizing anything from the header, so a corrupt
  // count cannot ask for gigabytes; then refuse budgets whose arrays would not fit a sane amount of memory.
  if (!consumed && (size < 8 || detail::fnv1a64(data, size - 8) != bytes::load_u64(data + size - 8)))
    return parse_error(source + ": checksum mismatch (the file is truncated or corrupt)");
  const uint64_t row_floats = 3 + uint64_t(c.k) * 3 + 6 + uint64_t(c.feature_dim) + uint64_t(kImageRawDim);
  if (uint64_t(c.anchor_capacity()) * row_floats * 4 > (uint64_t(8) << 30))
    return parse_error(source + ": the model's anchor budget (" + std::to_string(c.anchor_capacity()) +
                       " anchors) needs more than 8 GiB");
  if (M > c.anchor_capacity())
    return parse_error(source + ": " + std::to_string(M) + " anchors exceed the model's own budget of " +
                       std::to_string(c.anchor_capacity()));
  // The rows must be in the file before they are allocated.
  const uint64_t row_bytes = (3 + uint64_t(c.k) * 3 + 6 + uint64_t(c.feature_dim) + (has_image_mlp(c) ? uint64_t(kImageRawDim) : 0)) * 4;
  if (M > (size - r.offset()) / row_bytes)
    return parse_error(source + ": " + std::to_string(M) + " anchors of " + std::to_string(row_bytes) + " bytes do not fit in the " +
                       std::to_string(size - r.offset()) + " bytes left (truncated or corrupt)");
  allocate_rows(&m, size_t(M));
  m.anchor_count = size_t(M);
  r.floats(m.positions.data(), M * 3, "anchor positions");
  r.floats(m.offsets.data(), M * size_t(c.k) * 3, "anchor offsets");
  r.floats(m.log_scales.data(), M * 6, "anchor log-scales");
  r.floats(m.features.data(), M * size_t(c.feature_dim), "anchor features");
  if (has_image_mlp(c)) r.floats(m.image_raw.data(), M * size_t(kImageRawDim), "image features");
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !has_image_mlp(c)) continue;
    simd::MlpShape s;
    s.in = r.i32("an MLP shape");
    s.hidden = r.i32("an MLP shape");
    s.out = r.i32("an MLP shape");
    s.act2 = simd::MlpAct(r.i32("an MLP activation"));
    if (!r.status().ok()) return r.status();
    const simd::MlpShape want = mlp_shape(c, id);
    if (s.in != want.in || s.hidden != want.hidden || s.out != want.out || s.act2 != want.act2)
      return parse_error(source + ": MLP " + std::to_string(id) + " has shape " + std::to_string(s.in) + "-" +
                         std::to_string(s.hidden) + "-" + std::to_string(s.out) + ", which does not match the configuration");
    m.mlps[id].shape = s;
    m.mlps[id].params.assign(Mlp::param_count(s), 0.0f);
    r.floats(m.mlps[id].params.data(), m.mlps[id].params.size(), "MLP weights");
  }
  const size_t body = r.offset();
  const uint64_t checksum = r.u64("the checksum");
  if (!r.status().ok()) return r.status();
  // A whole file was verified up front; an embedded model (consumed != null) is verified here.
  if (consumed && checksum != detail::fnv1a64(data, body))
    return parse_error(source + ": checksum mismatch (the file is corrupt)");
  if (Status st = check_model_finite(m, source); !st.ok()) return parse_error(st.message());
  if (consumed) *consumed = r.offset();
  else if (r.offset() != size)
    return parse_error(source + ": " + std::to_string(size - r.offset()) + " unexpected bytes after the model");
  return m;
}

Status check_model_finite(const HybridModel& m, const std::string& source) {
  const size_t M = m.anchor_count;
  const size_t K = size_t(m.config.k), F = size_t(m.config.feature_dim);
  struct Rows {
    const char* name;
    const std::vector<float>* v;
    size_t per_anchor;
  };
  const Rows rows[] = {{"anchor position", &m.positions, 3},
                       {"offset", &m.offsets, 3 * K},
                       {"log-scale", &m.log_scales, 6},
                       {"anchor feature", &m.features, F},
                       {"image feature", &m.image_raw, m.image_raw.empty() ? 0 : size_t(kImageRawDim)}};
  for (const Rows& r : rows) {
    const size_t n = std::min(r.v->size(), M * r.per_anchor);
    for (size_t i = 0; i < n; ++i)
      if (!std::isfinite((*r.v)[i]))
        return numerical_error(source + ": non-finite " + r.name + " (anchor " + std::to_string(i / r.per_anchor) + ")");
  }
  static const char* const kMlpNames[kMlpCount] = {"opacity", "covariance", "colour", "image-feature"};
  for (int k = 0; k < kMlpCount; ++k)
    for (float v : m.mlps[k].params)
      if (!std::isfinite(v)) return numerical_error(source + ": non-finite weight in the " + kMlpNames[k] + " MLP");
  return Status::Ok();
}

Status save_model(const HybridModel& model, const std::string& path) {
  if (Status st = check_model_finite(model, path); !st.ok())
    return Status(st.code(), "refusing to write " + st.message());
  const std::vector<uint8_t> bytes = serialize_model(model);
  return platform::write_file_atomic(path, bytes.data(), bytes.size());
}

Expected<HybridModel> load_model(const std::string& path, std::unique_ptr<CompactModel>* compact_out) {
  if (compact_out) compact_out->reset();
  Expected<std::vector<uint8_t>> bytes = platform::read_file(path);
  if (!bytes.ok()) return bytes.status();
  if (is_compact_file(bytes->data(), bytes->size())) {
    Expected<CompactModel> compact = deserialize_compact(bytes->data(), bytes->size(), path);
    if (!compact.ok()) return compact.status();
    HybridModel m = dequantize(*compact);
    if (Status st = check_model_finite(m, path); !st.ok()) return parse_error(st.message());
    if (compact_out) *compact_out = std::make_unique<CompactModel>(std::move(compact).value());
    return m;
  }
  return deserialize_model(bytes->data(), bytes->size(), path);
}

}  // namespace gs::model
