// SPDX-License-Identifier: MIT
// The compact model file (gs/model/compact_model.h): half-precision conversion against an exact
// nearest-value search, the rANS byte coder, quantisation error bounds of every field, pruning and
// calibration on cameras, the file round trip, and refusal of corrupt, truncated or foreign files.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gs/hash.h"
#include "gs/model/byte_rans.h"
#include "gs/model/compact_model.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/quant_decoder.h"
#include "gs/model/model_renderer.h"
#include "gs/platform/file.h"
#include "support/alloc_counter.h"
#include "support/model_fixtures.h"
#include "support/temp_dir.h"

namespace gs::model {
namespace {

using test::sphere_points;

// The value of a half bit pattern computed from its fields in double (the definition, not a cast).
double half_value(uint16_t h) {
  const int sign = h >> 15, e = (h >> 10) & 31, m = h & 1023;
  double v = e == 0 ? std::ldexp(double(m), -24) : std::ldexp(1.0 + double(m) / 1024.0, e - 15);
  if (e == 31) v = m ? std::numeric_limits<double>::quiet_NaN() : std::numeric_limits<double>::infinity();
  return sign ? -v : v;
}

// Round to nearest even over every finite half: the half whose value is nearest to f (ties to the
// even mantissa), infinity past the largest half + half an ulp (65520).
uint16_t nearest_half(float f) {
  const double x = std::fabs(double(f));
  const uint16_t sign = std::signbit(f) ? 0x8000 : 0;
  if (x >= 65520.0) return uint16_t(sign | 0x7c00);
  uint16_t best = 0;
  double best_d = x;
  for (uint32_t h = 1; h < 0x7c00; ++h) {
    const double d = std::fabs(half_value(uint16_t(h)) - x);
    if (d < best_d || (d == best_d && (h & 1) == 0)) best = uint16_t(h), best_d = d;
  }
  return uint16_t(sign | best);
}

TEST_CASE("compact: half precision matches the exact nearest half and round-trips every half") {
  for (uint32_t h = 0; h < 0x10000; ++h) {
    const float f = half_to_float(uint16_t(h));
    const double v = half_value(uint16_t(h));
    if (std::isnan(v)) {
      REQUIRE(std::isnan(f));
      REQUIRE(std::isnan(half_to_float(float_to_half(f))));
      continue;
    }
    REQUIRE(double(f) == v);
    REQUIRE(float_to_half(f) == uint16_t(h));
  }
  // Midpoints between neighbouring halves (ties to even) and random floats of every magnitude.
  std::mt19937 rng(7);
  std::vector<float> probes = {0.0f, -0.0f, 65504.0f, 65519.99f, 65520.0f, 1e-8f, 2.98e-8f, 2.9802322e-8f, 6.1e-5f,
                               std::numeric_limits<float>::denorm_min(), 1e30f, -1e30f};
  for (uint32_t h = 0; h + 1 < 0x7c00; h += 37) probes.push_back(float((half_value(uint16_t(h)) + half_value(uint16_t(h + 1))) / 2));
  std::uniform_real_distribution<float> e(-30.0f, 17.0f), s(-1.0f, 1.0f);
  for (int i = 0; i < 3000; ++i) probes.push_back(s(rng) * std::exp2(e(rng)));
  for (float f : probes) {
    CAPTURE(f);
    REQUIRE(float_to_half(f) == nearest_half(f));
  }
  CHECK(float_to_half(std::numeric_limits<float>::infinity()) == 0x7c00);
  CHECK(std::isnan(half_to_float(float_to_half(std::numeric_limits<float>::quiet_NaN()))));
}

TEST_CASE("compact: rANS byte streams round-trip and malformed streams are refused") {
  std::mt19937 rng(3);
  std::vector<std::vector<uint8_t>> cases;
  cases.push_back({});
  cases.push_back({42});
  cases.push_back(std::vector<uint8_t>(5000, 7));  // one symbol only
  std::vector<uint8_t> uni(20000), skew(20000), two(777);
  for (uint8_t& b : uni) b = uint8_t(rng());
  std::geometric_distribution<int> geo(0.3);
  for (uint8_t& b : skew) b = uint8_t(std::min(255, geo(rng)));
  for (uint8_t& b : two) b = (rng() % 100) ? 0 : 255;
  cases.push_back(uni);
  cases.push_back(skew);
  cases.push_back(two);
  for (const std::vector<uint8_t>& c : cases) {
    CAPTURE(c.size());
    std::vector<uint8_t> enc = {0xAB};  // a prefix: streams sit inside a file
    detail::rans_encode_bytes(c.data(), c.size(), &enc);
    std::vector<uint8_t> dec(c.size(), 0);
    size_t pos = 1;
    std::string err;
    REQUIRE_MESSAGE(detail::rans_decode_bytes(enc.data(), enc.size(), &pos, c.size(), dec.data(), &err), err);
    CHECK(pos == enc.size());
    CHECK(dec == c);
    // Truncated: refused with a message, never a read past the end.
    for (size_t cut = 1; cut < enc.size(); cut += std::max<size_t>(1, enc.size() / 50)) {
      pos = 1;
      err.clear();
      CHECK_FALSE(detail::rans_decode_bytes(enc.data(), cut, &pos, c.size(), dec.data(), &err));
      CHECK_FALSE(err.empty());
    }
  }
  // A skewed stream codes to well under a byte per symbol (the point of coding it).
  std::vector<uint8_t> enc;
  detail::rans_encode_bytes(skew.data(), skew.size(), &enc);
  CHECK(enc.size() < skew.size() / 2);
}

ModelConfig small_config(ImageFeatureMode mode) { return test::small_file_test_config(mode, 400, 1600); }

// A model with random rows and MLPs scaled so that some Gaussians are kept in every view.
HybridModel random_model(ImageFeatureMode mode, uint64_t seed) {
  HybridModel model = test::sphere_model(small_config(mode), 3000, 3.0f, seed);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  test::randomise_anchor_rows(model, rng, g, 0.3f * model.voxel_size, -3.0f, 0.5f);
  const size_t M = model.anchor_count;
  for (size_t r = 0; r < M && mode == ImageFeatureMode::kPaper; ++r) {
    for (int ch = 0; ch + 1 < kImageRawDim; ++ch) model.image_raw[r * kImageRawDim + size_t(ch)] = 0.5f + 0.2f * g(rng);
    model.image_raw[r * kImageRawDim + kImageRawDim - 1] = (r % 5) ? 1.0f : 0.0f;  // the valid flag
    if (!(r % 5)) std::fill_n(&model.image_raw[r * kImageRawDim], kImageRawDim, 0.0f);
  }
  return model;
}

std::vector<Camera> ring_cameras(int n) {
  std::vector<Camera> cams;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    const double C[3] = {6 * std::cos(a), 0.5, 6 * std::sin(a)}, at[3] = {0, 0, 0};
    cams.push_back(test::look_at(C, at, PinholeIntrinsics{60, 60, 32, 24, 64, 48}));
  }
  return cams;
}

TEST_CASE("compact: every field is within its quantisation step of the float model") {
  for (ImageFeatureMode mode : {ImageFeatureMode::kPaper, ImageFeatureMode::kNone})
    for (bool fine : {true, false}) {
    CAPTURE(int(mode));
    CAPTURE(fine);
    const HybridModel m = random_model(mode, 11);
    CompactOptions opt;
    opt.prune = false;
    opt.mlp_fine = fine;
    CompactStats st;
    Expected<CompactModel> cm = compact_from_model(m, {}, opt, nullptr, &st);
    REQUIRE_MESSAGE(cm.ok(), cm.status().to_string());
    REQUIRE(cm->anchor_count == m.anchor_count);
    REQUIRE(st.source_rows.size() == m.anchor_count);
    const HybridModel d = dequantize(*cm);
    const size_t K = size_t(m.config.k), F = size_t(m.config.feature_dim);
    const double pos_step = double(m.voxel_size) / double(1 << opt.residual_bits);
    std::vector<float> feat_absmax(F, 0.0f);
    for (size_t r = 0; r < m.anchor_count; ++r)
      for (size_t c = 0; c < F; ++c) feat_absmax[c] = std::max(feat_absmax[c], std::fabs(m.features[r * F + c]));
    // Feature steps never clip (at least max / 127) and are at most max / 127 * 127 / levels * their weight.
    for (size_t c = 0; c < F; ++c) REQUIRE(cm->feature_scale[c] * 127.0f >= feat_absmax[c] * 0.9999f);
    REQUIRE(cm->log_scale_step == opt.log_scale_step);
    for (size_t r = 0; r < m.anchor_count; ++r) {
      const size_t s = st.source_rows[r];  // rows are reordered (Morton order on the grid)
      for (int a = 0; a < 3; ++a)
        REQUIRE(std::fabs(double(d.positions[3 * r + size_t(a)]) - double(m.positions[3 * s + size_t(a)])) <= 0.5 * pos_step * 1.001 + 1e-6);
      float off_max = 0;
      for (size_t i = 0; i < 3 * K; ++i) off_max = std::max(off_max, std::fabs(m.offsets[3 * K * s + i]));
      // Without cameras: one step of max / levels, its fp16 rounded up so nothing clips.
      const float off_step = half_to_float(cm->offset_scale[r]);
      REQUIRE(off_step * 127.0f >= off_max);
      REQUIRE(off_step <= off_max / float(opt.offset_levels) * 1.002f + 1e-7f);
      for (size_t i = 0; i < 3 * K; ++i)
        REQUIRE(std::fabs(d.offsets[3 * K * r + i] - m.offsets[3 * K * s + i]) <= 0.5f * off_step * 1.0001f + 1e-7f);
      for (size_t i = 0; i < 6; ++i)
        REQUIRE(std::fabs(d.log_scales[6 * r + i] - m.log_scales[6 * s + i]) <= 0.5f * cm->log_scale_step * 1.001f + 1e-5f);
      for (size_t c = 0; c < F; ++c)
        REQUIRE(std::fabs(d.features[F * r + c] - m.features[F * s + c]) <= 0.5f * cm->feature_scale[c] * 1.0001f);
      if (mode == ImageFeatureMode::kPaper) {
        const bool valid = m.image_raw[s * kImageRawDim + kImageRawDim - 1] >= 0.5f;
        for (int ch = 0; ch < kImageRawDim; ++ch) {
          const float want = m.image_raw[s * kImageRawDim + size_t(ch)], got = d.image_raw[r * kImageRawDim + size_t(ch)];
          if (!valid) REQUIRE(got == 0.0f);  // an unseen anchor stays exactly all zero
          else REQUIRE(std::fabs(got - want) <= 0.5f * (cm->image_hi[ch] - cm->image_lo[ch]) / float(opt.image_levels) * 1.001f + 1e-6f);
        }
      }
    }
    // MLP weights: per output row, half a step of max|row| / 127 (with the remainders, of that
    // step / 254); biases exact.
    const float weight_step = fine ? 1.0f / (127.0f * 254.0f) : 1.0f / 127.0f;
    for (int id = 0; id < kMlpCount; ++id) {
      if (m.mlps[id].params.empty()) continue;
      CAPTURE(id);
      const simd::MlpShape& sh = m.mlps[id].shape;
      const float* a = m.mlps[id].params.data();
      const float* b = d.mlps[id].params.data();
      REQUIRE(d.mlps[id].params.size() == m.mlps[id].params.size());
      auto check_rows = [&](size_t off, size_t rows, size_t cols) {
        for (size_t r = 0; r < rows; ++r) {
          float mx = 0;
          for (size_t c = 0; c < cols; ++c) mx = std::max(mx, std::fabs(a[off + r * cols + c]));
          for (size_t c = 0; c < cols; ++c)
            REQUIRE(std::fabs(a[off + r * cols + c] - b[off + r * cols + c]) <= 0.5f * mx * weight_step * 1.01f + mx * 1e-6f);
        }
      };
      check_rows(0, size_t(sh.hidden), size_t(sh.in));
      check_rows(Mlp::off_W2(sh), size_t(sh.out), size_t(sh.hidden));
      for (size_t i = Mlp::off_b1(sh); i < Mlp::off_b1(sh) + size_t(sh.hidden); ++i) REQUIRE(a[i] == b[i]);
      for (size_t i = Mlp::off_b2(sh); i < Mlp::off_b2(sh) + size_t(sh.out); ++i) REQUIRE(a[i] == b[i]);
    }
  }
}

TEST_CASE("compact: measured offset steps never clip, and offsets of Gaussians no view keeps are 0 and change no render") {
  const HybridModel m = random_model(ImageFeatureMode::kPaper, 17);
  const std::vector<Camera> cams = ring_cameras(6);
  CompactOptions opt;
  opt.prune = false;  // same rows, so the float model can be compared row by row
  CompactStats st;
  Expected<CompactModel> cm = compact_from_model(m, cams, opt, nullptr, &st);
  REQUIRE_MESSAGE(cm.ok(), cm.status().to_string());
  const size_t K = size_t(m.config.k);
  const HybridModel d = dequantize(*cm);
  // The float model with exactly the dropped offsets set to 0 (a dropped offset is stored as 0
  // and lies outside half a step of its value, or is 0 within it: both are counted below).
  HybridModel z = m;
  size_t zeroed = 0;
  for (size_t r = 0; r < cm->anchor_count; ++r) {
    const size_t s = st.source_rows[r];
    const float step = half_to_float(cm->offset_scale[r]);
    for (size_t j = 0; j < K; ++j) {
      bool all_zero = true, within = true;
      for (size_t l = 0; l < 3; ++l) {
        const size_t i = 3 * j + l;
        all_zero &= cm->offsets[3 * K * r + i] == 0;
        within &= std::fabs(d.offsets[3 * K * r + i] - m.offsets[3 * K * s + i]) <= 0.5f * step * 1.0001f + 1e-7f;
      }
      if (!within) {
        REQUIRE(all_zero);  // only a dropped offset may be off by more than half a step: never clipped
        for (size_t l = 0; l < 3; ++l) z.offsets[3 * K * s + 3 * j + l] = 0.0f;
        ++zeroed;
      }
    }
  }
  CHECK(st.offsets_dropped > 0);
  CHECK(zeroed > 0);  // the render comparison below tests something
  CHECK(zeroed <= st.offsets_dropped);
  // Those Gaussians are never drawn in the calibration views: the renders are bit-identical.
  ModelRenderer a, b;
  REQUIRE(a.init(m, 64, 48, nullptr).ok());
  REQUIRE(b.init(z, 64, 48, nullptr).ok());
  std::vector<float> ra(64 * 48 * 3), rb(64 * 48 * 3);
  for (const Camera& c : cams) {
    REQUIRE(a.render(m, c, ra.data()).ok());
    REQUIRE(b.render(z, c, rb.data()).ok());
    REQUIRE(ra == rb);
  }
}

TEST_CASE("compact: pruning drops anchors no camera sees, calibration measures every MLP") {
  HybridModel m = random_model(ImageFeatureMode::kPaper, 5);
  // Move a tenth of the anchors far below the cameras' ring, where no camera looks.
  size_t moved = 0;
  for (size_t r = 0; r < m.anchor_count; r += 10, ++moved) m.positions[3 * r + 1] = 500.0f + float(r);
  CompactStats st;
  Expected<CompactModel> cm = compact_from_model(m, ring_cameras(8), CompactOptions{}, nullptr, &st);
  REQUIRE_MESSAGE(cm.ok(), cm.status().to_string());
  CHECK(st.views == 8);
  CHECK(st.never_visible >= moved);
  CHECK(st.anchors_out <= m.anchor_count - moved);
  CHECK(st.anchors_out > m.anchor_count / 3);
  for (size_t s : st.source_rows) REQUIRE(m.positions[3 * s + 1] < 100.0f);
  CHECK(cm->calibration_views == 8);
  for (int id = 0; id < kMlpCount; ++id) {
    CAPTURE(id);
    const ActivationRanges& r = cm->mlps[id].ranges;
    REQUIRE(r.in_absmax.size() == size_t(cm->mlps[id].shape.in));
    CHECK(*std::max_element(r.in_absmax.begin(), r.in_absmax.end()) > 0);
    CHECK(*std::max_element(r.hidden_max.begin(), r.hidden_max.end()) > 0);
    CHECK(*std::max_element(r.out_absmax.begin(), r.out_absmax.end()) > 0);
    CHECK(r.input_scale() > 0);
  }
}

TEST_CASE("compact: the file round-trips and load_model reads it as the dequantised model") {
  for (ImageFeatureMode mode : {ImageFeatureMode::kPaper, ImageFeatureMode::kNone}) {
    CAPTURE(int(mode));
    const HybridModel m = random_model(mode, 21);
    Expected<CompactModel> cm = compact_from_model(m, ring_cameras(6), CompactOptions{}, nullptr);
    REQUIRE_MESSAGE(cm.ok(), cm.status().to_string());
    const std::vector<uint8_t> bytes = serialize_compact(*cm);
    CHECK(is_compact_file(bytes.data(), bytes.size()));
    Expected<CompactModel> back = deserialize_compact(bytes.data(), bytes.size(), "mem");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    CHECK(serialize_compact(*back) == bytes);  // every field survives (the writer is deterministic)
    test::TempDir dir;
    const std::string path = dir.path() + "/m.hbgc";
    REQUIRE(save_compact(*cm, path).ok());
    Expected<HybridModel> loaded = load_model(path);
    REQUIRE_MESSAGE(loaded.ok(), loaded.status().to_string());
    const HybridModel d = dequantize(*cm);
    REQUIRE(loaded->anchor_count == d.anchor_count);
    CHECK(loaded->positions == d.positions);
    CHECK(loaded->offsets == d.offsets);
    CHECK(loaded->features == d.features);
    CHECK(loaded->log_scales == d.log_scales);
    CHECK(loaded->image_raw == d.image_raw);
    for (int id = 0; id < kMlpCount; ++id) CHECK(loaded->mlps[id].params == d.mlps[id].params);
  }
}

TEST_CASE("compact: version 1, 2 and 3 files are still read, and rewritten as the current version without loss") {
  // Fuzz corpus seeds: files written by hbgs compact in each older version, after the harness's
  // first byte (version 3: a scene frame other than the identity).
  for (uint8_t version : {uint8_t(1), uint8_t(2), uint8_t(3)}) {
    CAPTURE(int(version));
    const std::string name = "tiny_v" + std::to_string(version) + ".hbgc";
    Expected<std::vector<uint8_t>> seed = platform::read_file(std::string(GS_SOURCE_DIR) + "/fuzz/corpus/compact/" + name);
    REQUIRE_MESSAGE(seed.ok(), seed.status().to_string());
    REQUIRE(seed->size() > 21);
    const std::vector<uint8_t> old_bytes(seed->begin() + 1, seed->end());
    REQUIRE(old_bytes[8] == version);  // the format version, little-endian
    Expected<CompactModel> old = deserialize_compact(old_bytes.data(), old_bytes.size(), name);
    REQUIRE_MESSAGE(old.ok(), old.status().to_string());
    CHECK(old->log_scale_step == (version == 1 ? 0.0f : 0.02f));  // version 1: fp16 log-scales
    CHECK(old->image_levels == (version == 1 ? 255 : 15));
    for (const QuantMlp& q : old->mlps) CHECK(q.w1_fine.empty() == (version == 1));
    CHECK(old->frame.identity() == (version < 3));
    const std::vector<uint8_t> now = serialize_compact(*old);
    REQUIRE(now[8] == kCompactFileVersion);
    if (version >= 2) CHECK(now.size() < old_bytes.size() + (version == 2 ? 32 : 0));  // the masks pay for the 32-byte frame
    Expected<CompactModel> back = deserialize_compact(now.data(), now.size(), "now.hbgc");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    CHECK(back->frame == old->frame);
    CHECK(dequantize(*back).frame == old->frame);
    const HybridModel a = dequantize(*old), b = dequantize(*back);
    CHECK(a.positions == b.positions);
    CHECK(a.offsets == b.offsets);
    CHECK(a.log_scales == b.log_scales);
    CHECK(a.features == b.features);
    CHECK(a.image_raw == b.image_raw);
    for (int id = 0; id < kMlpCount; ++id) CHECK(a.mlps[id].params == b.mlps[id].params);
  }
}

TEST_CASE("compact: version 4 codes which neural Gaussians have an offset, then only their offsets") {
  for (size_t k : {size_t(1), size_t(5), size_t(8), size_t(9), size_t(10), size_t(16), size_t(17)}) {
    const OffsetMaskLayout layout(k);
    CAPTURE(k);
    CHECK(layout.bits <= 8);
    CHECK(layout.streams * layout.bits >= k);
    CHECK((layout.streams - 1) * layout.bits < k);  // no stream is empty
  }
  CHECK(OffsetMaskLayout(10).streams == 2);
  CHECK(OffsetMaskLayout(10).bits == 5);
  const HybridModel m = random_model(ImageFeatureMode::kPaper, 41);
  Expected<CompactModel> cm = compact_from_model(m, ring_cameras(4), CompactOptions{}, nullptr);
  REQUIRE(cm.ok());
  // Unset offsets in a pattern: whole anchors, single slots, and a slot with one zero axis only.
  const size_t K = size_t(cm->config.k), M = cm->anchor_count;
  REQUIRE(M >= 8);
  for (size_t r = 0; r < M; ++r)
    for (size_t j = 0; j < K; ++j) {
      int8_t* o = cm->offsets.data() + (r * K + j) * 3;
      if (r % 3 == 0 || (r + j) % 4 == 0) o[0] = o[1] = o[2] = 0;
      else if (j == 1) o[0] = 0, o[2] = o[2] ? o[2] : 1;  // still set
    }
  const std::vector<uint8_t> bytes = serialize_compact(*cm);
  REQUIRE(bytes[8] == 4);
  Expected<CompactModel> back = deserialize_compact(bytes.data(), bytes.size(), "masked.hbgc");
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  CHECK(back->offsets == cm->offsets);
  // The offset streams: the masks (one symbol per anchor) then one symbol per set Gaussian.
  size_t set = 0;
  for (size_t r = 0; r < M; ++r)
    for (size_t j = 0; j < K; ++j) {
      const int8_t* o = cm->offsets.data() + (r * K + j) * 3;
      set += (o[0] || o[1] || o[2]);
    }
  size_t mask_symbols = 0, offset_symbols = 0, offset_streams = 0;
  for (const CompactStream& s : compact_streams(*cm))
    if (s.group == "offsets") (offset_streams++ < OffsetMaskLayout(K).streams ? mask_symbols : offset_symbols) += s.symbols.size();
  CHECK(mask_symbols == OffsetMaskLayout(K).streams * M);
  CHECK(offset_symbols == 3 * set);
  // No offset set at all: empty channel streams.
  CompactModel none = *cm;
  std::fill(none.offsets.begin(), none.offsets.end(), int8_t(0));
  const std::vector<uint8_t> zero = serialize_compact(none);
  Expected<CompactModel> zero_back = deserialize_compact(zero.data(), zero.size(), "zero.hbgc");
  REQUIRE_MESSAGE(zero_back.ok(), zero_back.status().to_string());
  CHECK(zero_back->offsets == none.offsets);
  // A mask symbol with a bit beyond its stream's slots (bit `width` of a `width`-slot stream) is refused
  // by name: the first mask stream recoded with one such symbol, the checksum made valid.
  const size_t width = OffsetMaskLayout(K).bits;
  REQUIRE(width < 8);
  std::vector<CompactSection> sections;
  serialize_compact(*cm, &sections);
  size_t at = 0, i = 0;
  while (sections[i].group != "offsets") at += sections[i++].bytes;
  std::vector<uint8_t> masks(compact_streams(*cm)[11].symbols);  // 9 position + 2 offset-scale streams before it
  REQUIRE(masks.size() == M);
  masks[M / 2] = uint8_t(1u << width);
  std::vector<uint8_t> coded;
  detail::rans_encode_bytes(masks.data(), masks.size(), &coded);
  std::vector<uint8_t> bad(bytes.begin(), bytes.begin() + long(at));
  bad.insert(bad.end(), coded.begin(), coded.end());
  bad.insert(bad.end(), bytes.begin() + long(at + sections[i].bytes), bytes.end());
  const uint64_t sum = fnv1a64(bad.data(), bad.size() - 8);
  std::memcpy(bad.data() + bad.size() - 8, &sum, 8);  // little-endian hosts (all hbgs targets)
  Expected<CompactModel> refused = deserialize_compact(bad.data(), bad.size(), "mask.hbgc");
  REQUIRE_FALSE(refused.ok());
  CHECK(refused.status().message().find("mask.hbgc: offset mask 0 of anchor " + std::to_string(M / 2) + " (" +
                                        std::to_string(1u << width) + ") must have at most " + std::to_string(width) + " bits") !=
        std::string::npos);
}

TEST_CASE("compact: corrupt, truncated, foreign and future files are refused with a message") {
  const HybridModel m = random_model(ImageFeatureMode::kPaper, 31);
  Expected<CompactModel> cm = compact_from_model(m, ring_cameras(4), CompactOptions{}, nullptr);
  REQUIRE(cm.ok());
  const std::vector<uint8_t> good = serialize_compact(*cm);
  // Truncation at every length: an error naming the source, never a crash.
  for (size_t n = 0; n < good.size(); n += (n < 64 ? 1 : 7)) {
    Expected<CompactModel> r = deserialize_compact(good.data(), n, "cut.hbgc");
    REQUIRE_FALSE(r.ok());
    REQUIRE(r.status().message().find("cut.hbgc") != std::string::npos);
  }
  // One flipped byte anywhere: the checksum catches it.
  for (size_t i = 0; i < good.size(); i += 13) {
    std::vector<uint8_t> bad = good;
    bad[i] ^= 0x5a;
    Expected<CompactModel> r = deserialize_compact(bad.data(), bad.size(), "flip.hbgc");
    REQUIRE_FALSE(r.ok());
  }
  // A later format version (checksum made valid): refused by version, with the remedy.
  std::vector<uint8_t> future = good;
  future[8] = uint8_t(kCompactFileVersion + 1);
  const uint64_t sum = fnv1a64(future.data(), future.size() - 8);
  std::memcpy(future.data() + future.size() - 8, &sum, 8);  // little-endian hosts (all hbgs targets)
  Expected<CompactModel> r = deserialize_compact(future.data(), future.size(), "future.hbgc");
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("version " + std::to_string(kCompactFileVersion + 1)) != std::string::npos);
  // Version 2's own fields, out of range (the writer writes what it is given; the checksum is valid).
  auto refused = [&](const char* what, auto&& mutate, const char* expect) {
    CAPTURE(what);
    CompactModel bad = *cm;
    mutate(bad);
    const std::vector<uint8_t> bytes = serialize_compact(bad);
    Expected<CompactModel> e = deserialize_compact(bytes.data(), bytes.size(), "bad.hbgc");
    REQUIRE_FALSE(e.ok());
    CHECK(e.status().message().find(expect) != std::string::npos);
  };
  refused("levels 0", [](CompactModel& b) { b.image_levels = 0; }, "image feature levels");
  refused("levels 256", [](CompactModel& b) { b.image_levels = 256; }, "image feature levels");
  refused("value above the levels", [](CompactModel& b) { b.image_levels = 3; b.image_raw[5] = 4; }, "exceeds the 3 levels");
  refused("negative step", [](CompactModel& b) { b.log_scale_step = -0.5f; }, "log-scale step");
  refused("NaN step", [](CompactModel& b) { b.log_scale_step = std::numeric_limits<float>::quiet_NaN(); }, "log-scale step");
  refused("grid overflow", [](CompactModel& b) { b.log_scale_step = 1e35f; }, "log-scale grid");
  refused("remainder -128", [](CompactModel& b) { b.mlps[kMlpColor].w2_fine[3] = -128; }, "remainder");
  // A float model file is not a compact one, and the other way round.
  const std::vector<uint8_t> float_bytes = serialize_model(m);
  CHECK_FALSE(is_compact_file(float_bytes.data(), float_bytes.size()));
  r = deserialize_compact(float_bytes.data(), float_bytes.size(), "float.hbgs");
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("not an hbgs compact model file") != std::string::npos);
  CHECK_FALSE(deserialize_model(good.data(), good.size(), "c.hbgc").ok());
}

TEST_CASE("compact: the int8 decoder renders like the float decoder of the same model, allocation-free") {
  const HybridModel m = random_model(ImageFeatureMode::kPaper, 41);
  const std::vector<Camera> cams = ring_cameras(8);
  Expected<CompactModel> cm = compact_from_model(m, cams, CompactOptions{}, nullptr);
  REQUIRE(cm.ok());
  const HybridModel d = dequantize(*cm);
  ModelRenderer flt, q8;
  REQUIRE(flt.init(d, 64, 48, nullptr).ok());
  ModelRenderOptions ro;
  ro.int8_mlp = &*cm;
  REQUIRE(q8.set_options(ro).ok());
  REQUIRE(q8.init(d, 64, 48, nullptr).ok());
  std::vector<float> a(64 * 48 * 3), b(a.size());
  double worst = 0;
  for (const Camera& c : cams) {
    REQUIRE(flt.render(d, c, a.data()).ok());
    REQUIRE(q8.render(d, c, b.data()).ok());
    for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::fabs(double(a[i]) - double(b[i])));
  }
  MESSAGE("int8 vs float decoder: max colour difference " << worst * 255 << " 8-bit levels");
  CHECK(worst * 255 < 2.0);
  CHECK(worst > 0);  // the int8 path really ran
  test::AllocationScope scope;
  REQUIRE(q8.render(d, cams[0], b.data()).ok());
  CHECK(scope.count() == 0);
  // A compact model without calibrated ranges cannot drive the int8 decoder: refused, not guessed.
  Expected<CompactModel> uncal = compact_from_model(m, {}, CompactOptions{}, nullptr);
  REQUIRE(uncal.ok());
  ModelRenderOptions bad;
  bad.int8_mlp = &*uncal;
  ModelRenderer r;
  const Status st = r.set_options(bad);
  CHECK_FALSE(st.ok());
  CHECK(st.message().find("activation ranges") != std::string::npos);
}

}  // namespace
}  // namespace gs::model
