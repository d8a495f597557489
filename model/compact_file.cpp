// SPDX-License-Identifier: MIT
// The compact model file (gs/model/compact_model.h): "HBGSCMPT", version, header, the channel
// streams coded with byte rANS (gs/model/byte_rans.h), raw MLP blocks and an FNV-1a 64 trailer;
// the reader checks every count against the configuration and the bytes present.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "byte_codec.h"
#include "gs/model/byte_rans.h"
#include "gs/model/compact_model.h"
#include "gs/platform/file.h"
#include "quantize.h"

namespace gs::model {

bool is_compact_file(const uint8_t* data, size_t size) { return size >= 8 && std::memcmp(data, kCompactMagic, 8) == 0; }

namespace {

void write_floats(detail::ByteWriter* w, const std::vector<float>& v) { w->floats(v.data(), v.size()); }

// Order-0 entropy of n byte symbols, in bytes.
double entropy_bytes(const uint8_t* s, size_t n) {
  if (n == 0) return 0;
  size_t counts[256] = {};
  for (size_t i = 0; i < n; ++i) ++counts[s[i]];
  double bits = 0;
  for (size_t c : counts)
    if (c) bits -= double(c) * std::log2(double(c) / double(n));
  return bits / 8;
}

// Records the file's parts for CompactSection reports (no-op without a list).
class SectionLog {
 public:
  SectionLog(const detail::ByteWriter* w, std::vector<CompactSection>* list) : w_(w), list_(list), mark_(w->bytes.size()) {}
  // The bytes written since the last mark belong to group (raw, or symbols coded from s[0..n)).
  void close(const std::string& group, const uint8_t* s = nullptr, size_t n = 0) {
    const size_t now = w_->bytes.size();
    if (list_) {
      if (!list_->empty() && list_->back().group == group && !s && !list_->back().symbols) {
        list_->back().bytes += now - mark_;
      } else {
        CompactSection c;
        c.group = group;
        c.bytes = now - mark_;
        c.symbols = n;
        c.entropy_bytes = s ? entropy_bytes(s, n) : 0.0;
        list_->push_back(std::move(c));
      }
    }
    mark_ = now;
  }

 private:
  const detail::ByteWriter* w_;
  std::vector<CompactSection>* list_;
  size_t mark_;
};

// Version 2's coded value of axis a of row r (see serialize_compact).
uint32_t position_symbol(const CompactModel& m, size_t r, int a) {
  const int rb = m.residual_bits;
  const uint32_t q = m.pos_q[3 * r + size_t(a)], prev = r ? m.pos_q[3 * (r - 1) + size_t(a)] : 0u;
  const uint32_t residual = q & ((1u << rb) - 1u);
  const uint32_t cell_delta = ((q >> rb) - (prev >> rb)) & (detail::kMaxPositionQ >> rb);
  return cell_delta << rb | residual;
}

// Neural Gaussian `slot` of row r has an offset other than (0, 0, 0).
bool offset_is_set(const CompactModel& m, size_t r, size_t slot) {
  const int8_t* o = m.offsets.data() + (r * size_t(m.config.k) + slot) * 3;
  return o[0] != 0 || o[1] != 0 || o[2] != 0;
}

}  // namespace

OffsetMaskLayout::OffsetMaskLayout(size_t k) : streams((k + 7) / 8), bits(streams ? (k + streams - 1) / streams : 0) {}

std::vector<CompactStream> compact_streams(const CompactModel& m) {
  const size_t M = m.anchor_count, K = size_t(m.config.k), F = size_t(m.config.feature_dim);
  std::vector<CompactStream> out;
  auto add = [&](const char* group, auto&& symbol_of_row) {
    CompactStream cs{group, std::vector<uint8_t>(M)};
    for (size_t r = 0; r < M; ++r) cs.symbols[r] = uint8_t(symbol_of_row(r));
    out.push_back(std::move(cs));
  };
  // Positions: per axis, the voxel cell (q >> residual bits) as the difference to the previous
  // row's modulo 2^(24 - residual bits) (rows are in Morton order, so neighbours are near) above
  // the residual bits as they are, as 3 byte streams (low, middle, high). Version 1 wrote q, x as
  // the difference to the previous row (rows sorted by x).
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) add("positions", [&](size_t r) { return position_symbol(m, r, a) >> (8 * b); });
  for (int b = 0; b < 2; ++b) add("offset scales", [&](size_t r) { return m.offset_scale[r] >> (8 * b); });
  // Offsets (version 4): first which neural Gaussians have an offset other than (0, 0, 0), as
  // OffsetMaskLayout's bit fields of the slots (joint, since an anchor's slots are kept alike),
  // then per channel the offsets of those Gaussians alone. 45 % of the built-in model's Gaussians
  // are kept in no view and stored as 0 (compact_from_model); coding them as symbols among the
  // real offsets cost 48 kB of its 293 kB, the masks 16 kB.
  const OffsetMaskLayout mask_layout(K);
  for (size_t g = 0; g < mask_layout.streams; ++g)
    add("offsets", [&](size_t r) {
      uint32_t bits = 0;
      for (size_t b = 0; b < mask_layout.bits; ++b) {
        const size_t slot = g * mask_layout.bits + b;
        if (slot < K && offset_is_set(m, r, slot)) bits |= 1u << b;
      }
      return bits;
    });
  for (size_t ch = 0; ch < 3 * K; ++ch) {
    CompactStream cs{"offsets", {}};
    for (size_t r = 0; r < M; ++r)
      if (offset_is_set(m, r, ch / 3)) cs.symbols.push_back(uint8_t(m.offsets[r * 3 * K + ch]));
    out.push_back(std::move(cs));
  }
  for (size_t ch = 0; ch < 6; ++ch)
    for (int b = 0; b < 2; ++b) add("log-scales", [&](size_t r) { return m.log_scales[6 * r + ch] >> (8 * b); });
  for (size_t ch = 0; ch < F; ++ch) add("features", [&](size_t r) { return m.features[r * F + ch]; });
  if (uses_image_features(m.config.image_features))  // the difference to the previous row modulo 256 (version 1: the values)
    for (size_t ch = 0; ch < size_t(kImageRawDim); ++ch)
      add("image features", [&](size_t r) {
        return m.image_raw[r * kImageRawDim + ch] - (r ? m.image_raw[(r - 1) * kImageRawDim + ch] : 0);
      });
  return out;
}

std::vector<uint8_t> serialize_compact(const CompactModel& m, std::vector<CompactSection>* sections) {
  detail::ByteWriter w;
  SectionLog log(&w, sections);
  auto code = [&](const std::string& group, const uint8_t* sym, size_t n) {
    detail::rans_encode_bytes(sym, n, &w.bytes);
    log.close(group, sym, n);
  };
  const ModelConfig& c = m.config;
  const size_t M = m.anchor_count;
  w.raw(kCompactMagic, 8);
  w.u32(kCompactFileVersion);
  detail::write_model_header(&w, c, m.voxel_size, m.scene_extent);
  w.u64(M);
  w.u64(m.source_anchors);
  w.u32(m.calibration_views);
  w.i32(m.residual_bits);
  for (double o : m.origin) w.f64(o);
  write_floats(&w, m.feature_scale);
  if (uses_image_features(c.image_features)) {
    w.floats(m.image_lo, kImageRawDim);
    w.floats(m.image_hi, kImageRawDim);
  }
  // Version 2: the image feature levels and the log-scale grid (step 0: fp16 as in version 1).
  w.u32(uint32_t(m.image_levels));
  w.f32(m.log_scale_step);
  w.floats(m.log_scale_lo, 6);
  detail::write_scene_frame(&w, m.frame);  // version 3: only when not the identity; version 4: always
  log.close("header");
  for (const CompactStream& cs : compact_streams(m)) code(cs.group, cs.symbols.data(), cs.symbols.size());
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !uses_image_features(c.image_features)) continue;
    const QuantMlp& q = m.mlps[id];
    w.i32(q.shape.in);
    w.i32(q.shape.hidden);
    w.i32(q.shape.out);
    w.i32(int32_t(q.shape.act2));
    w.raw(q.w1.data(), q.w1.size());
    write_floats(&w, q.w1_scale);
    write_floats(&w, q.b1);
    w.raw(q.w2.data(), q.w2.size());
    write_floats(&w, q.w2_scale);
    write_floats(&w, q.b2);
    // Version 2: 1 and the weights' rounding remainders, or 0.
    const bool fine = !q.w1_fine.empty() && !q.w2_fine.empty();
    w.u8(fine ? 1 : 0);
    if (fine) {
      w.raw(q.w1_fine.data(), q.w1_fine.size());
      w.raw(q.w2_fine.data(), q.w2_fine.size());
    }
    write_floats(&w, q.ranges.in_absmax);
    write_floats(&w, q.ranges.hidden_max);
    write_floats(&w, q.ranges.out_absmax);
    log.close("MLPs");
  }
  w.u64(detail::fnv1a64(w.bytes.data(), w.bytes.size()));
  log.close("header");
  return std::move(w.bytes);
}

Expected<CompactModel> deserialize_compact(const uint8_t* data, size_t size, const std::string& source) {
  detail::ByteReader r(data, size, source);
  char magic[8] = {};
  if (!r.bytes(magic, 8, "the file signature")) return r.status();
  if (std::memcmp(magic, kCompactMagic, 8) != 0)
    return parse_error(source + ": not an hbgs compact model file (the first 8 bytes are not \"HBGSCMPT\")");
  const uint32_t version = r.u32("the format version");
  if (!r.status().ok()) return r.status();
  if (version < 1 || version > kCompactFileVersion)
    return unsupported(source + ": compact model format version " + std::to_string(version) + ", but this hbgs reads versions 1 to " +
                       std::to_string(kCompactFileVersion) + " (remake it with hbgs compact)");
  // The checksum covers the whole file and is verified before any size is trusted.
  if (size < 20 || detail::fnv1a64(data, size - 8) != bytes::load_u64(data + size - 8))
    return parse_error(source + ": checksum mismatch (the file is truncated or corrupt)");
  const size_t body_end = size - 8;
  CompactModel m;
  ModelConfig& c = m.config;
  detail::read_model_header(&r, &c, &m.voxel_size, &m.scene_extent);
  const uint64_t M = r.u64("the anchor count");
  m.source_anchors = r.u64("the source anchor count");
  m.calibration_views = r.u32("the calibration view count");
  m.residual_bits = r.i32("the position residual bits");
  for (double& o : m.origin) o = r.f64("the position origin");
  if (!r.status().ok()) return r.status();
  if (Status valid = c.validate(); !valid.ok()) return parse_error(source + ": invalid configuration: " + valid.message());
  auto bad = [&](const std::string& field, const std::string& expected) {
    return parse_error(source + ": " + field + " " + expected);
  };
  if (!(m.voxel_size > 0) || !std::isfinite(m.voxel_size)) return bad("voxel size", "must be positive and finite");
  if (!(m.scene_extent > 0) || !std::isfinite(m.scene_extent)) return bad("scene extent", "must be positive and finite");
  if (m.residual_bits < 0 || m.residual_bits > 12)
    return bad("position residual bits " + std::to_string(m.residual_bits), "must be in 0..12");
  for (double o : m.origin)
    if (!std::isfinite(o) || std::fabs(o) > 1e30) return bad("position origin", "must be finite");
  if (M > c.anchor_capacity())
    return bad("anchor count " + std::to_string(M), "exceeds the model's own budget of " + std::to_string(c.anchor_capacity()));
  // Every anchor codes 3 + 3k + 6 + F (+ 13) values; hbgs never writes fewer than one byte per
  // anchor, so a count above the file size is corrupt (and cannot make the reader allocate more
  // than a few hundred bytes per byte of file).
  if (M > size) return bad("anchor count " + std::to_string(M), "is more than the file's " + std::to_string(size) + " bytes can hold");
  m.anchor_count = size_t(M);
  const size_t K = size_t(c.k), F = size_t(c.feature_dim), R = uses_image_features(c.image_features) ? size_t(kImageRawDim) : 0;
  auto floats = [&](std::vector<float>* v, size_t n, const char* what, bool nonneg) -> Status {
    v->assign(n, 0.0f);
    if (!r.floats(v->data(), n, what)) return r.status();
    for (float x : *v)
      if (!std::isfinite(x) || (nonneg && x < 0)) return bad(what, "must be finite" + std::string(nonneg ? " and >= 0" : ""));
    return Status::Ok();
  };
  GS_RETURN_IF_ERROR(floats(&m.feature_scale, F, "feature scales", true));
  if (R) {
    std::vector<float> lo, hi;
    GS_RETURN_IF_ERROR(floats(&lo, R, "image feature minima", false));
    GS_RETURN_IF_ERROR(floats(&hi, R, "image feature maxima", false));
    for (size_t ch = 0; ch < R; ++ch) {
      if (lo[ch] > hi[ch]) return bad("image feature range of channel " + std::to_string(ch), "must have minimum <= maximum");
      m.image_lo[ch] = lo[ch];
      m.image_hi[ch] = hi[ch];
    }
  }
  if (version >= 2) {
    const uint32_t levels = r.u32("the image feature levels");
    m.log_scale_step = r.f32("the log-scale step");
    if (!r.floats(m.log_scale_lo, 6, "the log-scale minima")) return r.status();
    if (levels < 1 || levels > 255) return bad("image feature levels " + std::to_string(levels), "must be in 1..255");
    m.image_levels = int(levels);
    if (!(m.log_scale_step >= 0) || !std::isfinite(m.log_scale_step)) return bad("log-scale step", "must be finite and >= 0");
    for (float lo : m.log_scale_lo)
      if (!std::isfinite(lo) || !std::isfinite(lo + 65535.0f * m.log_scale_step))
        return bad("log-scale grid", "must stay finite over its 65,536 steps");
  }
  if (version >= 3 && !detail::read_scene_frame(&r, &m.frame))  // the writer of version 3 left out the identity
    return r.status().ok() ? bad("scene frame", scene_frame_problem(m.frame)) : r.status();
  size_t pos = r.offset();
  std::vector<uint8_t> s(static_cast<size_t>(M));
  std::string err;
  auto stream = [&](const std::string& what, size_t n = SIZE_MAX) -> Status {
    if (!detail::rans_decode_bytes(data, body_end, &pos, n == SIZE_MAX ? size_t(M) : n, s.data(), &err))
      return parse_error(source + ": " + what + " stream at byte " + std::to_string(pos) + ": " + err);
    return Status::Ok();
  };
  m.pos_q.assign(size_t(M) * 3, 0);
  static const char* const kAxis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      GS_RETURN_IF_ERROR(stream(std::string("position ") + kAxis[a]));
      for (size_t i = 0; i < M; ++i) m.pos_q[3 * i + size_t(a)] |= uint32_t(s[i]) << (8 * b);
    }
  if (version == 1) {
    for (size_t i = 1; i < M; ++i) {  // undo the x differences; the sum must stay a 24-bit value
      const uint64_t x = uint64_t(m.pos_q[3 * i]) + m.pos_q[3 * (i - 1)];
      if (x > detail::kMaxPositionQ) return bad("position x of anchor " + std::to_string(i), "exceeds 2^24 grid steps");
      m.pos_q[3 * i] = uint32_t(x);
    }
  } else {
    // Undo the cell differences modulo 2^(24 - residual bits) (every value stays a 24-bit one).
    const int rb = m.residual_bits;
    const uint32_t low = (1u << rb) - 1u, cells = detail::kMaxPositionQ >> rb;
    for (size_t i = 0; i < M; ++i)
      for (size_t a = 0; a < 3; ++a) {
        const uint32_t v = m.pos_q[3 * i + a], prev_cell = i ? m.pos_q[3 * (i - 1) + a] >> rb : 0u;
        m.pos_q[3 * i + a] = (((v >> rb) + prev_cell) & cells) << rb | (v & low);
      }
  }
  m.offset_scale.assign(size_t(M), 0);
  for (int b = 0; b < 2; ++b) {
    GS_RETURN_IF_ERROR(stream("offset scale"));
    for (size_t i = 0; i < M; ++i) m.offset_scale[i] |= uint16_t(s[i] << (8 * b));
  }
  for (size_t i = 0; i < M; ++i)
    if ((m.offset_scale[i] & 0x7c00u) == 0x7c00u || (m.offset_scale[i] & 0x8000u))
      return bad("offset scale of anchor " + std::to_string(i), "must be finite and >= 0");
  m.offsets.assign(size_t(M) * 3 * K, 0);
  if (version >= 4) {  // the slot masks, then each channel's offsets of the set slots alone
    const OffsetMaskLayout layout(K);
    std::vector<uint8_t> set(size_t(M) * K, 0);  // [M, k]
    std::vector<size_t> set_count(K, 0);
    for (size_t g = 0; g < layout.streams; ++g) {
      GS_RETURN_IF_ERROR(stream("offset mask " + std::to_string(g)));
      const size_t first = g * layout.bits, width = std::min(layout.bits, K - first);
      for (size_t i = 0; i < M; ++i) {
        if (s[i] >> width)
          return bad("offset mask " + std::to_string(g) + " of anchor " + std::to_string(i) + " (" + std::to_string(s[i]) + ")",
                     "must have at most " + std::to_string(width) + " bits");
        for (size_t b = 0; b < width; ++b)
          if (s[i] >> b & 1u) set[i * K + first + b] = 1, ++set_count[first + b];
      }
    }
    for (size_t ch = 0; ch < 3 * K; ++ch) {
      GS_RETURN_IF_ERROR(stream("offset channel " + std::to_string(ch), set_count[ch / 3]));
      for (size_t i = 0, j = 0; i < M; ++i)
        if (set[i * K + ch / 3]) m.offsets[i * 3 * K + ch] = int8_t(s[j++]);
    }
  } else {
    for (size_t ch = 0; ch < 3 * K; ++ch) {
      GS_RETURN_IF_ERROR(stream("offset channel " + std::to_string(ch)));
      for (size_t i = 0; i < M; ++i) m.offsets[i * 3 * K + ch] = int8_t(s[i]);
    }
  }
  m.log_scales.assign(size_t(M) * 6, 0);
  for (size_t ch = 0; ch < 6; ++ch)
    for (int b = 0; b < 2; ++b) {
      GS_RETURN_IF_ERROR(stream("log-scale channel " + std::to_string(ch)));
      for (size_t i = 0; i < M; ++i) m.log_scales[6 * i + ch] |= uint16_t(s[i] << (8 * b));
    }
  if (m.log_scale_step == 0)
    for (size_t i = 0; i < M * 6; ++i)
      if ((m.log_scales[i] & 0x7c00u) == 0x7c00u) return bad("log-scale of anchor " + std::to_string(i / 6), "is not finite");
  m.features.assign(size_t(M) * F, 0);
  for (size_t ch = 0; ch < F; ++ch) {
    GS_RETURN_IF_ERROR(stream("feature channel " + std::to_string(ch)));
    for (size_t i = 0; i < M; ++i) m.features[i * F + ch] = int8_t(s[i]);
  }
  m.image_raw.assign(size_t(M) * R, 0);
  for (size_t ch = 0; ch < R; ++ch) {
    GS_RETURN_IF_ERROR(stream("image feature channel " + std::to_string(ch)));
    if (version >= 2)  // undo the differences modulo 256
      for (size_t i = 1; i < M; ++i) s[i] = uint8_t(s[i] + s[i - 1]);
    for (size_t i = 0; i < M; ++i) {
      if (s[i] > m.image_levels)
        return bad("image feature " + std::to_string(s[i]) + " of anchor " + std::to_string(i), "exceeds the " + std::to_string(m.image_levels) + " levels");
      m.image_raw[i * R + ch] = s[i];
    }
  }
  detail::ByteReader t(data, body_end, source);
  t.skip(pos);
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !uses_image_features(c.image_features)) continue;
    QuantMlp& q = m.mlps[id];
    simd::MlpShape sh;
    sh.in = t.i32("an MLP shape");
    sh.hidden = t.i32("an MLP shape");
    sh.out = t.i32("an MLP shape");
    sh.act2 = simd::MlpAct(t.i32("an MLP activation"));
    if (!t.status().ok()) return t.status();
    const simd::MlpShape want = model_mlp_shape(c, id);
    if (sh.in != want.in || sh.hidden != want.hidden || sh.out != want.out || sh.act2 != want.act2)
      return bad("MLP " + std::to_string(id) + " shape " + std::to_string(sh.in) + "-" + std::to_string(sh.hidden) + "-" +
                     std::to_string(sh.out),
                 "does not match the configuration (" + std::to_string(want.in) + "-" + std::to_string(want.hidden) + "-" +
                     std::to_string(want.out) + ")");
    q.shape = sh;
    const size_t I = size_t(sh.in), H = size_t(sh.hidden), O = size_t(sh.out);
    q.w1.assign(H * I, 0);
    if (!t.bytes(q.w1.data(), q.w1.size(), "MLP weights")) return t.status();
    auto fl = [&](std::vector<float>* v, size_t n, const char* what, bool nonneg) -> Status {
      v->assign(n, 0.0f);
      if (!t.floats(v->data(), n, what)) return t.status();
      for (float x : *v)
        if (!std::isfinite(x) || (nonneg && x < 0))
          return bad(std::string("MLP ") + std::to_string(id) + " " + what, "must be finite" + std::string(nonneg ? " and >= 0" : ""));
      return Status::Ok();
    };
    GS_RETURN_IF_ERROR(fl(&q.w1_scale, H, "weight scales", true));
    GS_RETURN_IF_ERROR(fl(&q.b1, H, "biases", false));
    q.w2.assign(O * H, 0);
    if (!t.bytes(q.w2.data(), q.w2.size(), "MLP weights")) return t.status();
    GS_RETURN_IF_ERROR(fl(&q.w2_scale, O, "weight scales", true));
    GS_RETURN_IF_ERROR(fl(&q.b2, O, "biases", false));
    if (version >= 2) {
      const uint8_t fine = t.u8("the MLP remainder flag");
      if (!t.status().ok()) return t.status();
      if (fine > 1) return bad("MLP " + std::to_string(id) + " remainder flag " + std::to_string(fine), "must be 0 or 1");
      if (fine) {
        q.w1_fine.assign(H * I, 0);
        q.w2_fine.assign(O * H, 0);
        if (!t.bytes(q.w1_fine.data(), q.w1_fine.size(), "MLP weight remainders")) return t.status();
        if (!t.bytes(q.w2_fine.data(), q.w2_fine.size(), "MLP weight remainders")) return t.status();
        for (const std::vector<int8_t>* f : {&q.w1_fine, &q.w2_fine})
          for (int8_t v : *f)
            if (v == -128) return bad("MLP " + std::to_string(id) + " weight remainder -128", "must be in -127..127");
      }
    }
    GS_RETURN_IF_ERROR(fl(&q.ranges.in_absmax, I, "input ranges", true));
    GS_RETURN_IF_ERROR(fl(&q.ranges.hidden_max, H, "hidden ranges", true));
    GS_RETURN_IF_ERROR(fl(&q.ranges.out_absmax, O, "output ranges", true));
  }
  if (t.offset() != body_end)
    return parse_error(source + ": " + std::to_string(body_end - t.offset()) + " unexpected bytes before the checksum");
  return m;
}

Status save_compact(const CompactModel& model, const std::string& path) {
  const std::vector<uint8_t> bytes = serialize_compact(model);
  return platform::write_file_atomic(path, bytes.data(), bytes.size());
}

Expected<CompactModel> load_compact(const std::string& path) {
  Expected<std::vector<uint8_t>> bytes = platform::read_file(path);
  if (!bytes.ok()) return bytes.status();
  return deserialize_compact(bytes->data(), bytes->size(), path);
}

}  // namespace gs::model
