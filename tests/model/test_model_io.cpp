// SPDX-License-Identifier: MIT
// The hybrid model (gs/model/hybrid_model.h): create_model (shapes, init, budgets, errors) and the
// versioned model file: bit-exact round trip, other versions, wrong magic, corruption, and
// truncation at every byte offset (an error, never a crash).
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gs/hash.h"

#include "gs/model/hybrid_model.h"
#include "support/temp_dir.h"
#include "support/model_fixtures.h"

namespace gs::model {
namespace {

using test::read_bytes;
using test::sphere_points;
using test::write_bytes;


// Capacity min(300, 1000 / 4) = 250 anchors.
ModelConfig small_config(ImageFeatureMode mode) { return test::small_file_test_config(mode, 300, 1000); }

// A model whose live rows hold random values (so that a dropped or misplaced row shows), including
// a negative zero and a denormal.
HybridModel random_model(ImageFeatureMode mode, uint64_t seed) {
  HybridModel model = test::sphere_model(small_config(mode), 2000, 3.5f, seed);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  test::randomise_anchor_rows(model, rng, g, 1.0f, 0.0f, 1.0f);
  const size_t M = model.anchor_count;
  for (size_t i = 0; i < model.image_raw.size() && i < M * kImageRawDim; ++i) model.image_raw[i] = g(rng);
  model.features[0] = -0.0f;
  model.features[1] = std::numeric_limits<float>::denorm_min();
  return model;
}

bool same_bits(const float* a, const float* b, size_t n) { return n == 0 || std::memcmp(a, b, n * sizeof(float)) == 0; }

void check_identical(const HybridModel& a, const HybridModel& b) {
  const ModelConfig &x = a.config, &y = b.config;
  CHECK(x.k == y.k);
  CHECK(x.feature_dim == y.feature_dim);
  CHECK(x.hidden == y.hidden);
  CHECK(x.image_features == y.image_features);
  CHECK(x.image_feature_dim == y.image_feature_dim);
  CHECK(x.image_feature_hidden == y.image_feature_hidden);
  CHECK(x.max_anchors == y.max_anchors);
  CHECK(x.max_gaussians == y.max_gaussians);
  CHECK(std::memcmp(&x.voxel_size, &y.voxel_size, 4) == 0);
  CHECK(std::memcmp(&a.voxel_size, &b.voxel_size, 4) == 0);
  CHECK(std::memcmp(&a.scene_extent, &b.scene_extent, 4) == 0);
  CHECK(a.frame == b.frame);
  REQUIRE(a.anchor_count == b.anchor_count);
  const size_t M = a.anchor_count, K = size_t(x.k);
  CHECK(same_bits(a.positions.data(), b.positions.data(), M * 3));
  CHECK(same_bits(a.offsets.data(), b.offsets.data(), M * K * 3));
  CHECK(same_bits(a.log_scales.data(), b.log_scales.data(), M * 6));
  CHECK(same_bits(a.features.data(), b.features.data(), M * size_t(x.feature_dim)));
  if (x.image_features == ImageFeatureMode::kPaper) {
    REQUIRE(b.image_raw.size() >= M * kImageRawDim);
    CHECK(same_bits(a.image_raw.data(), b.image_raw.data(), M * kImageRawDim));
  }
  for (int i = 0; i < kMlpCount; ++i) {
    CAPTURE(i);
    CHECK(a.mlps[i].shape.in == b.mlps[i].shape.in);
    CHECK(a.mlps[i].shape.hidden == b.mlps[i].shape.hidden);
    CHECK(a.mlps[i].shape.out == b.mlps[i].shape.out);
    CHECK(a.mlps[i].shape.act2 == b.mlps[i].shape.act2);
    REQUIRE(a.mlps[i].params.size() == b.mlps[i].params.size());
    CHECK(same_bits(a.mlps[i].params.data(), b.mlps[i].params.data(), a.mlps[i].params.size()));
  }
}



TEST_CASE("model: create_model shapes initialisation budget and determinism") {
  for (ImageFeatureMode mode : {ImageFeatureMode::kPaper, ImageFeatureMode::kNone}) {
    CAPTURE(int(mode));
    const ModelConfig c = small_config(mode);
    const std::vector<float> xyz = sphere_points(2000, 3);
    Expected<HybridModel> m = create_model(c, xyz.data(), 2000, 2.5f, 42);
    REQUIRE_MESSAGE(m.ok(), m.status().to_string());
    CHECK(m->capacity() == c.anchor_capacity());
    CHECK(m->capacity() == 250);
    CHECK(m->anchor_count >= 8);
    CHECK(m->anchor_count <= m->capacity() / 2);  // automatic voxel size leaves room to grow
    CHECK(m->scene_extent == 2.5f);
    CHECK(m->voxel_size > 0);
    CHECK(m->offsets.size() == m->capacity() * size_t(c.k) * 3);
    CHECK(m->features.size() == m->capacity() * size_t(c.feature_dim));
    CHECK(m->log_scales.size() == m->capacity() * 6);
    CHECK(m->image_raw.size() == (mode == ImageFeatureMode::kPaper ? m->capacity() * kImageRawDim : 0));
    const int D = c.decoder_input_dim();
    CHECK(D == c.feature_dim + (mode == ImageFeatureMode::kPaper ? c.image_feature_dim : 0) + 4);
    const simd::MlpShape want[3] = {{D, c.hidden, c.k, simd::MlpAct::kTanh},
                                    {D, c.hidden, 7 * c.k, simd::MlpAct::kNone},
                                    {D, c.hidden, 3 * c.k, simd::MlpAct::kSigmoid}};
    for (int i = 0; i < 3; ++i) {
      CAPTURE(i);
      const Mlp& mlp = m->mlps[i];
      CHECK(mlp.shape.in == want[i].in);
      CHECK(mlp.shape.hidden == want[i].hidden);
      CHECK(mlp.shape.out == want[i].out);
      CHECK(mlp.shape.act2 == want[i].act2);
    }
    if (mode == ImageFeatureMode::kPaper) {
      CHECK(m->mlps[kMlpImage].shape.in == kImageRawDim);
      CHECK(m->mlps[kMlpImage].shape.hidden == c.image_feature_hidden);
      CHECK(m->mlps[kMlpImage].shape.out == c.image_feature_dim);
    } else {
      CHECK(m->mlps[kMlpImage].params.empty());
    }
    // PyTorch default init: every weight and bias within 1/sqrt(fan_in) of its layer, not all zero.
    for (int i = 0; i < kMlpCount; ++i) {
      const Mlp& mlp = m->mlps[i];
      if (mlp.params.empty()) continue;
      CAPTURE(i);
      REQUIRE(mlp.params.size() == Mlp::param_count(mlp.shape));
      const double b1 = 1 / std::sqrt(double(mlp.shape.in)), b2 = 1 / std::sqrt(double(mlp.shape.hidden));
      double max1 = 0, max2 = 0;
      for (size_t j = 0; j < mlp.params.size(); ++j) {
        const double a = std::fabs(double(mlp.params[j]));
        if (j < Mlp::off_W2(mlp.shape)) max1 = std::max(max1, a);
        else max2 = std::max(max2, a);
      }
      CHECK(max1 <= b1);
      CHECK(max1 > 0.5 * b1);
      CHECK(max2 <= b2);
      CHECK(max2 > 0.5 * b2);
    }
    // Zero offsets and features at start; same seed -> same model; another seed -> other MLPs.
    for (size_t i = 0; i < m->anchor_count * size_t(c.feature_dim); ++i) REQUIRE(m->features[i] == 0);
    for (size_t i = 0; i < m->anchor_count * size_t(c.k) * 3; ++i) REQUIRE(m->offsets[i] == 0);
    Expected<HybridModel> again = create_model(c, xyz.data(), 2000, 2.5f, 42);
    REQUIRE(again.ok());
    check_identical(*m, *again);
    Expected<HybridModel> other = create_model(c, xyz.data(), 2000, 2.5f, 43);
    REQUIRE(other.ok());
    CHECK(other->mlps[kMlpColor].params != m->mlps[kMlpColor].params);
  }
}

TEST_CASE("model: anchor capacity is min(max_anchors and max_gaussians / k)") {
  ModelConfig c;
  c.k = 10;
  c.max_anchors = 50000;
  c.max_gaussians = 500000;
  CHECK(c.anchor_capacity() == 50000);
  c.max_gaussians = 123456;
  CHECK(c.anchor_capacity() == 12345);
  c.max_anchors = 100;
  CHECK(c.anchor_capacity() == 100);
  c.k = 7;
  c.max_anchors = 1000;
  c.max_gaussians = 6999;
  CHECK(c.anchor_capacity() == 999);
  CHECK(c.validate().ok());
  // A Gaussian budget below k leaves no anchor: invalid, and create_model says so.
  c.max_gaussians = 6;
  CHECK(c.anchor_capacity() == 0);
  CHECK_FALSE(c.validate().ok());
  const std::vector<float> xyz = sphere_points(100, 5);
  Expected<HybridModel> m = create_model(c, xyz.data(), 100, 1.0f, 1);
  CHECK_FALSE(m.ok());
  // The allocated rows follow the budget, and the initial anchors fit it.
  ModelConfig d = small_config(ImageFeatureMode::kPaper);
  d.max_anchors = 1000;
  d.max_gaussians = 160;  // 40 anchors
  Expected<HybridModel> s = create_model(d, sphere_points(3000, 6).data(), 3000, 1.0f, 1);
  REQUIRE_MESSAGE(s.ok(), s.status().to_string());
  CHECK(s->capacity() == 40);
  CHECK(s->anchor_count <= 20);
  CHECK(s->anchor_count * size_t(d.k) <= d.max_gaussians);
}

TEST_CASE("model: create_model refuses empty or non-finite points and a bad extent") {
  const ModelConfig c = small_config(ImageFeatureMode::kPaper);
  const std::vector<float> xyz = sphere_points(50, 7);
  Expected<HybridModel> none = create_model(c, xyz.data(), 0, 1.0f, 1);
  REQUIRE_FALSE(none.ok());
  MESSAGE(none.status().to_string());
  CHECK(none.status().message().find("point") != std::string::npos);
  CHECK_FALSE(create_model(c, nullptr, 0, 1.0f, 1).ok());
  std::vector<float> bad = xyz;
  bad[31] = std::numeric_limits<float>::quiet_NaN();
  Expected<HybridModel> nan = create_model(c, bad.data(), 50, 1.0f, 1);
  CHECK_FALSE(nan.ok());
  CHECK_FALSE(create_model(c, xyz.data(), 50, 0.0f, 1).ok());
  CHECK_FALSE(create_model(c, xyz.data(), 50, std::numeric_limits<float>::infinity(), 1).ok());
}

TEST_CASE("model file: save and load round trip is bit-exact") {
  test::TempDir dir("gs_model_io");
  for (ImageFeatureMode mode : {ImageFeatureMode::kPaper, ImageFeatureMode::kNone}) {
    CAPTURE(int(mode));
    const HybridModel model = random_model(mode, 11);
    const std::vector<uint8_t> bytes = serialize_model(model);
    CHECK(model.file_bytes() == bytes.size());
    Expected<HybridModel> back = deserialize_model(bytes.data(), bytes.size(), "memory");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    check_identical(model, *back);
    CHECK(back->capacity() == back->anchor_count);  // a loaded model holds its stored rows, not its whole budget
    CHECK(serialize_model(*back) == bytes);  // byte-identical second generation
    const std::string path = dir / (std::string("model_") + image_feature_mode_name(mode) + ".bin");
    REQUIRE(save_model(model, path).ok());
    CHECK(read_bytes(path) == bytes);
    Expected<HybridModel> loaded = load_model(path);
    REQUIRE_MESSAGE(loaded.ok(), loaded.status().to_string());
    check_identical(model, *loaded);
    CHECK(loaded->capacity() == loaded->anchor_count);
    // Only live rows are stored: the size grows with the anchor count.
    HybridModel fewer = model;
    fewer.anchor_count -= 1;
    CHECK(serialize_model(fewer).size() < bytes.size());
    // Embedded use: consumed reports the model's length and allows trailing bytes.
    std::vector<uint8_t> padded = bytes;
    padded.insert(padded.end(), {1, 2, 3});
    size_t consumed = 0;
    Expected<HybridModel> emb = deserialize_model(padded.data(), padded.size(), "memory", &consumed);
    REQUIRE(emb.ok());
    CHECK(consumed == bytes.size());
    Expected<HybridModel> trailing = deserialize_model(padded.data(), padded.size(), "memory");
    CHECK_FALSE(trailing.ok());
  }
  CHECK(parse_image_feature_mode("paper").ok());
  CHECK(*parse_image_feature_mode("none") == ImageFeatureMode::kNone);
  CHECK_FALSE(parse_image_feature_mode("Paper ").ok());
}

TEST_CASE("model file: a scene frame other than the identity is stored (version 2) and checked") {
  HybridModel model = random_model(ImageFeatureMode::kNone, 13);
  const std::vector<uint8_t> plain = serialize_model(model);
  model.frame.centre[0] = 1.0e7 + 0.25, model.frame.centre[1] = -3.5e5, model.frame.centre[2] = 0.125;
  model.frame.scale = 1.0 / 1024;
  const std::vector<uint8_t> bytes = serialize_model(model);
  CHECK(model.file_bytes() == bytes.size());
  CHECK(bytes.size() == plain.size() + 32);
  uint32_t v = 0;
  std::memcpy(&v, bytes.data() + 8, 4);
  CHECK(v == 2);
  Expected<HybridModel> back = deserialize_model(bytes.data(), bytes.size(), "framed.hbgs");
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  check_identical(model, *back);
  CHECK(serialize_model(*back) == bytes);
  // A zero scale is refused (the checksum is fixed up so the frame check itself is what fails).
  model.frame.scale = 0;
  std::vector<uint8_t> bad = serialize_model(model);
  const uint64_t sum = fnv1a64(bad.data(), bad.size() - 8);
  for (int i = 0; i < 8; ++i) bad[bad.size() - 8 + size_t(i)] = uint8_t(sum >> (8 * i));
  Expected<HybridModel> refused = deserialize_model(bad.data(), bad.size(), "framed.hbgs");
  REQUIRE_FALSE(refused.ok());
  CHECK(refused.status().message().find("scene frame") != std::string::npos);
}

TEST_CASE("model file: another format version is refused with a message naming it") {
  const HybridModel model = random_model(ImageFeatureMode::kPaper, 12);
  std::vector<uint8_t> bytes = serialize_model(model);
  // The version is the little-endian u32 after the 8-byte magic.
  uint32_t v = 0;
  std::memcpy(&v, bytes.data() + 8, 4);
  CHECK(v == 1);  // the identity scene frame: version 1, as before frames existed
  for (uint32_t other : {kModelFileVersion + 1, uint32_t(0), uint32_t(77)}) {
    const uint8_t le[4] = {uint8_t(other), uint8_t(other >> 8), uint8_t(other >> 16), uint8_t(other >> 24)};
    std::memcpy(bytes.data() + 8, le, 4);
    Expected<HybridModel> r = deserialize_model(bytes.data(), bytes.size(), "old.bin");
    REQUIRE_FALSE(r.ok());
    MESSAGE(r.status().to_string());
    CHECK(r.status().message().find("version " + std::to_string(other)) != std::string::npos);
    CHECK(r.status().message().find("old.bin") != std::string::npos);
  }
}

TEST_CASE("model file: wrong magic and corrupted bytes are refused") {
  test::TempDir dir("gs_model_io");
  const HybridModel model = random_model(ImageFeatureMode::kPaper, 13);
  const std::vector<uint8_t> bytes = serialize_model(model);
  std::vector<uint8_t> magic = bytes;
  magic[3] = 'X';
  Expected<HybridModel> r = deserialize_model(magic.data(), magic.size(), "m.bin");
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("HBGSMODL") != std::string::npos);
  // A PLY or checkpoint file is not a model.
  const std::string ply = "ply\nformat binary_little_endian 1.0\n";
  CHECK_FALSE(deserialize_model(reinterpret_cast<const uint8_t*>(ply.data()), ply.size(), "x.ply").ok());
  // One flipped bit in a float of the anchor rows or the MLPs (past the header): a checksum error.
  for (size_t pos : {bytes.size() / 3, bytes.size() / 2, bytes.size() - 20}) {
    std::vector<uint8_t> c = bytes;
    c[pos] ^= 0x10;
    Expected<HybridModel> e = deserialize_model(c.data(), c.size(), "c.bin");
    CHECK_FALSE(e.ok());
  }
  // A missing file names the path.
  Expected<HybridModel> missing = load_model(dir / "nope.bin");
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().message().find("nope.bin") != std::string::npos);
}

TEST_CASE("model file: truncation at every byte offset is an error and never a crash") {
  test::TempDir dir("gs_model_io");
  for (ImageFeatureMode mode : {ImageFeatureMode::kPaper, ImageFeatureMode::kNone}) {
    const HybridModel model = random_model(mode, 14);
    const std::vector<uint8_t> bytes = serialize_model(model);
    int failures = 0;
    for (size_t n = 0; n < bytes.size(); ++n) {
      // A copy of exactly n bytes so that ASan sees any read past the end.
      const std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + long(n));
      Expected<HybridModel> r = deserialize_model(cut.data(), cut.size(), "cut.bin");
      if (r.ok() || r.status().message().empty()) {
        ++failures;
        if (failures < 5) MESSAGE("truncated to " << n << " of " << bytes.size() << " bytes: accepted or silent");
      }
    }
    CHECK(failures == 0);
    // Through the file API at a few offsets (inside the header, the rows, the MLPs, the checksum).
    for (size_t n : {size_t(0), size_t(5), size_t(40), bytes.size() / 2, bytes.size() - 1}) {
      const std::string path = dir / "cut.bin";
      write_bytes(path, std::vector<uint8_t>(bytes.begin(), bytes.begin() + long(n)));
      Expected<HybridModel> r = load_model(path);
      REQUIRE_FALSE(r.ok());
      CHECK(r.status().message().find("cut.bin") != std::string::npos);
    }
  }
}

}  // namespace
}  // namespace gs::model
