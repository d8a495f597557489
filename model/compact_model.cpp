// SPDX-License-Identifier: MIT
// The compact model file: pruning and activation calibration over the training views, per-channel
// quantisation, a static byte rANS coder (hbgs's own), and the checked reader.
#include "gs/model/compact_model.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <numeric>

#include "byte_codec.h"
#include "float_backend.h"
#include "gs/model/decode.h"
#include "gs/platform/file.h"
#include "gs/simd/kernel_table.h"

namespace gs::model {

namespace {

bool paper(const ModelConfig& c) { return uses_image_features(c.image_features); }

float max_of(const std::vector<float>& v) {
  float m = 0;
  for (float x : v) m = std::max(m, x);
  return m;
}

// ---- pruning and calibration scan -----------------------------------------------------------

struct Scan {
  std::vector<uint8_t> seen, kept;  // [M]: visible in some view; some Gaussian with opacity > 0
  ActivationRanges ranges[kMlpCount];
};

void update_absmax(const float* x, size_t rows, size_t cols, std::vector<float>* m) {
  float* out = m->data();
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < cols; ++c) out[c] = std::max(out[c], std::fabs(x[r * cols + c]));
}

// Runs the decoder (with pre-activation outputs) on every camera: visibility, opacity > 0 per
// anchor, and the maximum |activation| per channel of every MLP.
Status scan_views(const HybridModel& m, const std::vector<Camera>& cams, platform::ThreadPool* pool, Scan* out) {
  const size_t M = m.anchor_count, K = size_t(m.config.k);
  out->seen.assign(M, 0);
  out->kept.assign(M, 0);
  ModelParamsT<float> p = detail::model_params(m);
  simd::MlpShape pre[kMlpCount];
  for (int i = 0; i < kMlpCount; ++i) {
    pre[i] = m.mlps[i].shape;
    pre[i].act2 = simd::MlpAct::kNone;  // outputs before tanh / sigmoid
    out->ranges[i].in_absmax.assign(size_t(pre[i].in), 0.0f);
    out->ranges[i].hidden_max.assign(size_t(pre[i].hidden), 0.0f);
    out->ranges[i].out_absmax.assign(size_t(pre[i].out), 0.0f);
  }
  if (M == 0 || cams.empty()) return Status::Ok();
  size_t max_params = 0;
  for (const Mlp& x : m.mlps) max_params = std::max(max_params, x.params.size());
  detail::FloatBackend be;
  be.init(nullptr, &simd::best_kernel_table(), pool, max_params, 1);  // MLPs only: no renderer
  StepWorkspace<float> ws;
  ws.reserve(M, m.config.k, pre, p.image_feature_dim, 1, 1);
  const int G = p.image_feature_dim;
  for (const Camera& cam : cams) {
    const size_t V = select_visible_anchors(cam, p.anchors, ws.rows.data());
    if (V == 0) continue;
    const uint32_t* rows = ws.rows.data();
    for (size_t v = 0; v < V; ++v) out->seen[rows[v]] = 1;
    if (G > 0) {
      for (size_t v = 0; v < V; ++v)
        std::copy(p.image_raw + size_t(rows[v]) * kImageRawDim, p.image_raw + (size_t(rows[v]) + 1) * kImageRawDim,
                  ws.raw.data() + v * kImageRawDim);
      be.mlp_fwd(pre[kMlpImage], int32_t(V), ws.raw.data(), p.mlp[kMlpImage], ws.img_hidden.data(), ws.g.data());
      ActivationRanges& r = out->ranges[kMlpImage];
      update_absmax(ws.raw.data(), V, kImageRawDim, &r.in_absmax);
      update_absmax(ws.img_hidden.data(), V, size_t(pre[kMlpImage].hidden), &r.hidden_max);
      update_absmax(ws.g.data(), V, size_t(G), &r.out_absmax);
    }
    double centre[3];
    camera_centre(cam.pose, centre);
    build_decoder_input(p.anchors, rows, V, G > 0 ? ws.g.data() : static_cast<const float*>(nullptr), G, centre, ws.X.data());
    for (int i = 0; i < 3; ++i) {
      be.mlp_fwd(pre[i], int32_t(V), ws.X.data(), p.mlp[i], ws.hidden[i].data(), ws.y[i].data());
      ActivationRanges& r = out->ranges[i];
      update_absmax(ws.X.data(), V, size_t(pre[i].in), &r.in_absmax);
      update_absmax(ws.hidden[i].data(), V, size_t(pre[i].hidden), &r.hidden_max);
      update_absmax(ws.y[i].data(), V, size_t(pre[i].out), &r.out_absmax);
    }
    const float* op = ws.y[kMlpOpacity].data();  // tanh(z) > 0 iff z > 0
    for (size_t v = 0; v < V; ++v)
      for (size_t j = 0; j < K; ++j)
        if (op[v * K + j] > 0.0f) out->kept[rows[v]] = 1;
  }
  return Status::Ok();
}

// A copy of the live rows listed in keep (in that order).
HybridModel select_rows(const HybridModel& m, const std::vector<size_t>& keep) {
  HybridModel o;
  o.config = m.config;
  o.voxel_size = m.voxel_size;
  o.scene_extent = m.scene_extent;
  o.anchor_count = keep.size();
  for (int i = 0; i < kMlpCount; ++i) o.mlps[i] = m.mlps[i];
  const size_t K = size_t(m.config.k), F = size_t(m.config.feature_dim), R = paper(m.config) ? size_t(kImageRawDim) : 0;
  auto gather = [&](const std::vector<float>& src, size_t w, std::vector<float>* dst) {
    dst->resize(keep.size() * w);
    for (size_t i = 0; i < keep.size(); ++i) std::copy_n(src.begin() + std::ptrdiff_t(keep[i] * w), w, dst->begin() + std::ptrdiff_t(i * w));
  };
  gather(m.positions, 3, &o.positions);
  gather(m.offsets, 3 * K, &o.offsets);
  gather(m.log_scales, 6, &o.log_scales);
  gather(m.features, F, &o.features);
  if (R) gather(m.image_raw, R, &o.image_raw);
  return o;
}

// ---- quantisers -------------------------------------------------------------------------------

int8_t q8(float v, float scale) {
  if (!(scale > 0)) return 0;
  return int8_t(std::clamp(std::lround(double(v) / double(scale)), -127L, 127L));
}

// Symmetric int8 per channel: channel c of row r is src[r * C + c].
void quantize_channels(const float* src, size_t rows, size_t C, std::vector<int8_t>* q, std::vector<float>* scale) {
  scale->assign(C, 0.0f);
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < C; ++c) (*scale)[c] = std::max((*scale)[c], std::fabs(src[r * C + c]));
  for (float& s : *scale) s /= 127.0f;
  q->resize(rows * C);
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < C; ++c) (*q)[r * C + c] = q8(src[r * C + c], (*scale)[c]);
}

void quantize_mlp(const Mlp& m, QuantMlp* q) {
  const simd::MlpShape& s = m.shape;
  q->shape = s;
  const float* p = m.params.data();
  const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out);
  auto rows = [](const float* w, size_t n_rows, size_t n_cols, std::vector<int8_t>* qw, std::vector<float>* sc) {
    qw->resize(n_rows * n_cols);
    sc->assign(n_rows, 0.0f);
    for (size_t r = 0; r < n_rows; ++r) {
      float a = 0;
      for (size_t c = 0; c < n_cols; ++c) a = std::max(a, std::fabs(w[r * n_cols + c]));
      (*sc)[r] = a / 127.0f;
      for (size_t c = 0; c < n_cols; ++c) (*qw)[r * n_cols + c] = q8(w[r * n_cols + c], (*sc)[r]);
    }
  };
  rows(p, H, I, &q->w1, &q->w1_scale);
  q->b1.assign(p + Mlp::off_b1(s), p + Mlp::off_b1(s) + H);
  rows(p + Mlp::off_W2(s), O, H, &q->w2, &q->w2_scale);
  q->b2.assign(p + Mlp::off_b2(s), p + Mlp::off_b2(s) + O);
}

Mlp dequantize_mlp(const QuantMlp& q) {
  Mlp m;
  m.shape = q.shape;
  m.params.assign(Mlp::param_count(q.shape), 0.0f);
  const size_t I = size_t(q.shape.in), H = size_t(q.shape.hidden), O = size_t(q.shape.out);
  float* p = m.params.data();
  for (size_t r = 0; r < H; ++r)
    for (size_t c = 0; c < I; ++c) p[r * I + c] = float(q.w1[r * I + c]) * q.w1_scale[r];
  std::copy(q.b1.begin(), q.b1.end(), p + Mlp::off_b1(q.shape));
  float* w2 = p + Mlp::off_W2(q.shape);
  for (size_t r = 0; r < O; ++r)
    for (size_t c = 0; c < H; ++c) w2[r * H + c] = float(q.w2[r * H + c]) * q.w2_scale[r];
  std::copy(q.b2.begin(), q.b2.end(), p + Mlp::off_b2(q.shape));
  return m;
}

constexpr uint32_t kMaxQ = (1u << 24) - 1;  // positions are stored as 3 bytes per axis
constexpr int kValidFlag = kImageRawDim - 1;

}  // namespace

float ActivationRanges::input_scale() const { const float m = max_of(in_absmax); return m > 0 ? m / 127.0f : 1.0f; }
float ActivationRanges::hidden_scale() const { const float m = max_of(hidden_max); return m > 0 ? m / 127.0f : 1.0f; }
float ActivationRanges::output_scale() const { const float m = max_of(out_absmax); return m > 0 ? m / 32767.0f : 1.0f; }

uint16_t float_to_half(float f) {
  uint32_t x;
  std::memcpy(&x, &f, 4);
  const uint16_t sign = uint16_t((x >> 16) & 0x8000u);
  const uint32_t ax = x & 0x7fffffffu;
  if (ax >= 0x7f800000u) return uint16_t(sign | 0x7c00u | (ax > 0x7f800000u ? 0x200u : 0u));  // inf / NaN
  if (ax >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // rounds to >= 65520: infinity
  if (ax < 0x38800000u) {  // below the smallest normal half (2^-14): subnormal or zero
    if (ax < 0x33000000u) return sign;  // < 2^-25 rounds to zero
    const uint32_t mant = (ax & 0x7fffffu) | 0x800000u;
    const int shift = 126 - int(ax >> 23);  // 14..24 (2^e with e = exp - 127, half sub unit 2^-24)
    const uint32_t q = mant >> shift, rem = mant & ((1u << shift) - 1), half = 1u << (shift - 1);
    const uint32_t r = q + ((rem > half || (rem == half && (q & 1u))) ? 1u : 0u);
    return uint16_t(sign | r);
  }
  const uint32_t e = (ax >> 23) - 112;  // rebias 127 -> 15
  uint32_t h = (e << 10) | ((ax >> 13) & 0x3ffu);
  const uint32_t rem = ax & 0x1fffu;
  if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) ++h;  // carries into the exponent correctly
  return uint16_t(sign | h);
}

float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
  uint32_t x;
  if (e == 0) {
    if (m == 0) {
      x = sign;
    } else {  // subnormal: m 2^-24
      const float v = float(m) * 5.9604644775390625e-8f;
      std::memcpy(&x, &v, 4);
      x |= sign;
    }
  } else if (e == 31) {
    x = sign | 0x7f800000u | (m << 13);
  } else {
    x = sign | ((e + 112) << 23) | (m << 13);
  }
  float f;
  std::memcpy(&f, &x, 4);
  return f;
}

// ---- rANS ---------------------------------------------------------------------------------------

namespace detail {
namespace {

constexpr int kProbBits = 14;
constexpr uint32_t kProbScale = 1u << kProbBits;
constexpr uint32_t kRansL = 1u << 23;  // state kept in [L, 2^31)

void put_varint(std::vector<uint8_t>* out, uint64_t v) {
  while (v >= 0x80) {
    out->push_back(uint8_t(v | 0x80));
    v >>= 7;
  }
  out->push_back(uint8_t(v));
}

bool get_varint(const uint8_t* d, size_t n, size_t* pos, uint64_t* v) {
  uint64_t r = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*pos >= n) return false;
    const uint8_t b = d[(*pos)++];
    r |= uint64_t(b & 0x7f) << shift;
    if (!(b & 0x80)) {
      *v = r;
      return true;
    }
  }
  return false;
}

// Frequencies summing to kProbScale, >= 1 for every symbol that occurs.
void normalize(const uint64_t counts[256], size_t n, uint32_t freq[256]) {
  int64_t sum = 0;
  for (int s = 0; s < 256; ++s) {
    freq[s] = counts[s] ? uint32_t(std::max<uint64_t>(1, (counts[s] * kProbScale + n / 2) / n)) : 0;
    sum += freq[s];
  }
  while (sum != int64_t(kProbScale)) {
    int big = 0;
    for (int s = 1; s < 256; ++s) big = freq[s] > freq[big] ? s : big;
    if (sum < int64_t(kProbScale)) {
      freq[big] += uint32_t(int64_t(kProbScale) - sum);
      sum = kProbScale;
    } else {
      const uint32_t take = uint32_t(std::min<int64_t>(sum - int64_t(kProbScale), int64_t(freq[big]) - 1));
      freq[big] -= take;
      sum -= take;
    }
  }
}

}  // namespace

void rans_encode_bytes(const uint8_t* sym, size_t n, std::vector<uint8_t>* out) {
  if (n == 0) return;
  uint64_t counts[256] = {};
  for (size_t i = 0; i < n; ++i) ++counts[sym[i]];
  uint32_t freq[256], start[256];
  normalize(counts, n, freq);
  for (uint32_t s = 0, acc = 0; s < 256; ++s) start[s] = acc, acc += freq[s];
  // Table: nonzero frequencies as varints, a run of absent symbols as 0 then its length.
  for (int s = 0; s < 256;) {
    if (freq[s]) {
      put_varint(out, freq[s]);
      ++s;
    } else {
      int r = 0;
      while (s + r < 256 && !freq[s + r]) ++r;
      put_varint(out, 0);
      put_varint(out, uint64_t(r));
      s += r;
    }
  }
  std::vector<uint8_t> rev;
  rev.reserve(n / 2 + 8);
  uint32_t x = kRansL;
  for (size_t i = n; i-- > 0;) {
    const uint32_t f = freq[sym[i]];
    const uint32_t x_max = ((kRansL >> kProbBits) << 8) * f;
    while (x >= x_max) {
      rev.push_back(uint8_t(x & 0xff));
      x >>= 8;
    }
    x = ((x / f) << kProbBits) + (x % f) + start[sym[i]];
  }
  for (int b = 0; b < 4; ++b) rev.push_back(uint8_t(x >> (8 * b)));
  put_varint(out, rev.size());
  out->insert(out->end(), rev.rbegin(), rev.rend());
}

bool rans_decode_bytes(const uint8_t* data, size_t size, size_t* pos, size_t n, uint8_t* symbols, std::string* error) {
  if (n == 0) return true;
  uint32_t freq[256] = {}, start[256];
  uint64_t sum = 0;
  for (int s = 0; s < 256;) {
    uint64_t v;
    if (!get_varint(data, size, pos, &v)) return *error = "frequency table truncated", false;
    if (v == 0) {
      uint64_t r;
      if (!get_varint(data, size, pos, &r)) return *error = "frequency table truncated", false;
      if (r == 0 || r > uint64_t(256 - s)) return *error = "frequency table run of " + std::to_string(r) + " absent symbols at symbol " + std::to_string(s), false;
      s += int(r);
    } else {
      if (v > kProbScale) return *error = "frequency " + std::to_string(v) + " above " + std::to_string(kProbScale), false;
      freq[s++] = uint32_t(v);
      sum += v;
    }
  }
  if (sum != kProbScale) return *error = "frequencies sum to " + std::to_string(sum) + ", expected " + std::to_string(kProbScale), false;
  uint64_t len;
  if (!get_varint(data, size, pos, &len)) return *error = "payload length truncated", false;
  if (len < 4 || len > size - *pos)
    return *error = "payload of " + std::to_string(len) + " bytes (at least 4, at most the " + std::to_string(size - *pos) + " left)", false;
  std::vector<uint8_t> slot_sym(kProbScale);
  for (uint32_t s = 0, acc = 0; s < 256; ++s) {
    start[s] = acc;
    std::fill_n(slot_sym.begin() + acc, freq[s], uint8_t(s));
    acc += freq[s];
  }
  const uint8_t* p = data + *pos;
  const uint8_t* end = p + len;
  uint32_t x = uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | uint32_t(p[3]);
  p += 4;
  if (x < kRansL || x >= (1u << 31)) return *error = "initial coder state out of range", false;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t slot = x & (kProbScale - 1);
    const uint8_t s = slot_sym[slot];
    symbols[i] = s;
    x = freq[s] * (x >> kProbBits) + slot - start[s];
    while (x < kRansL) {
      if (p == end) return *error = "payload ends after " + std::to_string(i + 1) + " of " + std::to_string(n) + " symbols", false;
      x = (x << 8) | *p++;
    }
  }
  if (p != end || x != kRansL) return *error = "payload does not end where its last symbol does (corrupt stream)", false;
  *pos += size_t(len);
  return true;
}

}  // namespace detail

// ---- from a float model and back -------------------------------------------------------------

Expected<CompactModel> compact_from_model(const HybridModel& model, const std::vector<Camera>& cameras,
                                          const CompactOptions& options, platform::ThreadPool* pool, CompactStats* stats) {
  GS_RETURN_IF_ERROR(model.config.validate());
  GS_RETURN_IF_ERROR(check_model_finite(model, "compact: the float model"));
  if (options.residual_bits < 0 || options.residual_bits > 12)
    return invalid_argument("compact: residual bits " + std::to_string(options.residual_bits) + " outside 0..12");
  if (!(model.voxel_size > 0) || !std::isfinite(model.voxel_size))
    return invalid_argument("compact: the model's voxel size " + std::to_string(model.voxel_size) + " is not positive");
  const ModelConfig& c = model.config;
  const size_t K = size_t(c.k), F = size_t(c.feature_dim);
  CompactStats st;
  st.anchors_in = model.anchor_count;
  st.views = cameras.size();

  // 1. Pruning on the float model.
  std::vector<size_t> keep;
  {
    Scan scan;
    if (options.prune && !cameras.empty()) GS_RETURN_IF_ERROR(scan_views(model, cameras, pool, &scan));
    for (size_t i = 0; i < model.anchor_count; ++i) {
      const bool prune = options.prune && !cameras.empty() && !scan.kept[i];
      if (options.prune && !cameras.empty() && !scan.seen[i]) ++st.never_visible;
      if (!prune) keep.push_back(i);
    }
    if (keep.empty() && model.anchor_count > 0) keep.push_back(0);  // a model keeps one anchor
  }

  // 2. Positions on the voxel grid; rows sorted by (qx, qy, qz) so x can be delta-coded.
  const size_t M = keep.size();
  CompactModel cm;
  cm.config = c;
  cm.voxel_size = model.voxel_size;
  cm.scene_extent = model.scene_extent;
  cm.anchor_count = M;
  cm.source_anchors = model.anchor_count;
  cm.residual_bits = options.residual_bits;
  const double step = double(model.voxel_size) / double(1u << options.residual_bits);
  for (int a = 0; a < 3; ++a) {
    double lo = M ? double(model.positions[3 * keep[0] + size_t(a)]) : 0.0;
    for (size_t i : keep) lo = std::min(lo, double(model.positions[3 * i + size_t(a)]));
    cm.origin[a] = lo;
  }
  std::vector<uint32_t> q(M * 3);
  for (size_t r = 0; r < M; ++r)
    for (int a = 0; a < 3; ++a) {
      const double v = std::round((double(model.positions[3 * keep[r] + size_t(a)]) - cm.origin[a]) / step);
      if (!(v >= 0 && v <= double(kMaxQ)))
        return invalid_argument("compact: anchor positions span more than 2^24 steps of voxel size / 2^" +
                                std::to_string(options.residual_bits) + " on axis " + std::to_string(a) + "; use fewer residual bits");
      q[3 * r + size_t(a)] = uint32_t(v);
    }
  std::vector<size_t> order(M);
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
    return std::lexicographical_compare(&q[3 * x], &q[3 * x + 3], &q[3 * y], &q[3 * y + 3]);
  });
  std::vector<size_t> rows(M);
  cm.pos_q.resize(M * 3);
  for (size_t r = 0; r < M; ++r) {
    rows[r] = keep[order[r]];
    std::copy_n(&q[3 * order[r]], 3, &cm.pos_q[3 * r]);
  }
  const HybridModel sel = select_rows(model, rows);

  // 3. Per-channel quantisation of the rows.
  cm.offsets.resize(M * 3 * K);
  cm.offset_scale.resize(M);
  for (size_t r = 0; r < M; ++r) {
    const float* o = &sel.offsets[r * 3 * K];
    float a = 0;
    for (size_t i = 0; i < 3 * K; ++i) a = std::max(a, std::fabs(o[i]));
    cm.offset_scale[r] = float_to_half(a / 127.0f);
    const float sc = half_to_float(cm.offset_scale[r]);
    for (size_t i = 0; i < 3 * K; ++i) cm.offsets[r * 3 * K + i] = q8(o[i], sc);
  }
  quantize_channels(sel.features.data(), M, F, &cm.features, &cm.feature_scale);
  cm.log_scales.resize(M * 6);
  for (size_t i = 0; i < M * 6; ++i) cm.log_scales[i] = float_to_half(sel.log_scales[i]);
  if (paper(c)) {
    const size_t R = kImageRawDim;
    for (size_t ch = 0; ch < R; ++ch) {
      float lo = M ? sel.image_raw[ch] : 0.0f, hi = lo;
      for (size_t r = 0; r < M; ++r) lo = std::min(lo, sel.image_raw[r * R + ch]), hi = std::max(hi, sel.image_raw[r * R + ch]);
      cm.image_lo[ch] = lo;
      cm.image_hi[ch] = hi;
    }
    cm.image_raw.resize(M * R);
    for (size_t r = 0; r < M; ++r)
      for (size_t ch = 0; ch < R; ++ch) {
        const float span = cm.image_hi[ch] - cm.image_lo[ch];
        const double t = span > 0 ? (double(sel.image_raw[r * R + ch]) - cm.image_lo[ch]) / span * 255.0 : 0.0;
        cm.image_raw[r * R + ch] = uint8_t(std::clamp(std::lround(t), 0L, 255L));
      }
  }
  for (int i = 0; i < kMlpCount; ++i)
    if (i != kMlpImage || paper(c)) quantize_mlp(model.mlps[i], &cm.mlps[i]);

  // 4. Activation ranges of the model as it will be decoded (the dequantised one).
  {
    const HybridModel dq = dequantize(cm);
    Scan scan;
    GS_RETURN_IF_ERROR(scan_views(dq, cameras, pool, &scan));
    for (int i = 0; i < kMlpCount; ++i)
      if (i != kMlpImage || paper(c)) cm.mlps[i].ranges = std::move(scan.ranges[i]);
    cm.calibration_views = uint32_t(cameras.size());
  }
  st.anchors_out = M;
  st.source_rows = std::move(rows);
  if (stats) *stats = st;
  return cm;
}

HybridModel dequantize(const CompactModel& cm) {
  HybridModel m;
  m.config = cm.config;
  m.voxel_size = cm.voxel_size;
  m.scene_extent = cm.scene_extent;
  const size_t M = cm.anchor_count, K = size_t(cm.config.k), F = size_t(cm.config.feature_dim);
  m.anchor_count = M;
  const double step = double(cm.voxel_size) / double(1u << cm.residual_bits);
  m.positions.resize(M * 3);
  for (size_t r = 0; r < M; ++r)
    for (int a = 0; a < 3; ++a) m.positions[3 * r + size_t(a)] = float(cm.origin[a] + double(cm.pos_q[3 * r + size_t(a)]) * step);
  m.offsets.resize(M * K * 3);
  for (size_t r = 0; r < M; ++r)
    for (size_t ch = 0; ch < 3 * K; ++ch) m.offsets[r * 3 * K + ch] = float(cm.offsets[r * 3 * K + ch]) * half_to_float(cm.offset_scale[r]);
  m.features.resize(M * F);
  for (size_t r = 0; r < M; ++r)
    for (size_t ch = 0; ch < F; ++ch) m.features[r * F + ch] = float(cm.features[r * F + ch]) * cm.feature_scale[ch];
  m.log_scales.resize(M * 6);
  for (size_t i = 0; i < M * 6; ++i) m.log_scales[i] = half_to_float(cm.log_scales[i]);
  if (paper(cm.config)) {
    const size_t R = kImageRawDim;
    m.image_raw.assign(M * R, 0.0f);
    for (size_t r = 0; r < M; ++r) {
      const float flag = cm.image_lo[kValidFlag] + float(cm.image_raw[r * R + kValidFlag]) * ((cm.image_hi[kValidFlag] - cm.image_lo[kValidFlag]) / 255.0f);
      if (!(flag >= 0.5f)) continue;  // no view sees it: the raw vector stays all zero
      for (size_t ch = 0; ch < R; ++ch)
        m.image_raw[r * R + ch] = cm.image_lo[ch] + float(cm.image_raw[r * R + ch]) * ((cm.image_hi[ch] - cm.image_lo[ch]) / 255.0f);
    }
  }
  for (int i = 0; i < kMlpCount; ++i)
    if (i != kMlpImage || paper(cm.config)) m.mlps[i] = dequantize_mlp(cm.mlps[i]);
  return m;
}

// ---- file -------------------------------------------------------------------------------------

bool is_compact_file(const uint8_t* data, size_t size) { return size >= 8 && std::memcmp(data, kCompactMagic, 8) == 0; }

namespace {

// Channel ch of a row-major [rows, C] byte array as one stream.
template <class T>
std::vector<uint8_t> channel_bytes(const std::vector<T>& v, size_t rows, size_t C, size_t ch) {
  std::vector<uint8_t> s(rows);
  for (size_t r = 0; r < rows; ++r) s[r] = uint8_t(v[r * C + ch]);
  return s;
}

void write_floats(detail::ByteWriter* w, const std::vector<float>& v) { w->floats(v.data(), v.size()); }

}  // namespace

std::vector<uint8_t> serialize_compact(const CompactModel& m) {
  detail::ByteWriter w;
  const ModelConfig& c = m.config;
  const size_t M = m.anchor_count, K = size_t(c.k), F = size_t(c.feature_dim);
  w.raw(kCompactMagic, 8);
  w.u32(kCompactFileVersion);
  detail::write_model_header(&w, c, m.voxel_size, m.scene_extent);
  w.u64(M);
  w.u64(m.source_anchors);
  w.u32(m.calibration_views);
  w.i32(m.residual_bits);
  for (double o : m.origin) w.f64(o);
  write_floats(&w, m.feature_scale);
  if (paper(c)) {
    w.floats(m.image_lo, kImageRawDim);
    w.floats(m.image_hi, kImageRawDim);
  }
  // Positions: x as the difference to the previous row (rows are sorted by x), y and z as they
  // are; each as 3 byte streams (low, middle, high).
  std::vector<uint8_t> s(M);
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      for (size_t r = 0; r < M; ++r) {
        const uint32_t v = a == 0 ? m.pos_q[3 * r] - (r ? m.pos_q[3 * (r - 1)] : 0u) : m.pos_q[3 * r + size_t(a)];
        s[r] = uint8_t(v >> (8 * b));
      }
      detail::rans_encode_bytes(s.data(), M, &w.bytes);
    }
  for (int b = 0; b < 2; ++b) {
    for (size_t r = 0; r < M; ++r) s[r] = uint8_t(m.offset_scale[r] >> (8 * b));
    detail::rans_encode_bytes(s.data(), M, &w.bytes);
  }
  for (size_t ch = 0; ch < 3 * K; ++ch) detail::rans_encode_bytes(channel_bytes(m.offsets, M, 3 * K, ch).data(), M, &w.bytes);
  for (size_t ch = 0; ch < 6; ++ch)
    for (int b = 0; b < 2; ++b) {
      for (size_t r = 0; r < M; ++r) s[r] = uint8_t(m.log_scales[6 * r + ch] >> (8 * b));
      detail::rans_encode_bytes(s.data(), M, &w.bytes);
    }
  for (size_t ch = 0; ch < F; ++ch) detail::rans_encode_bytes(channel_bytes(m.features, M, F, ch).data(), M, &w.bytes);
  if (paper(c))
    for (size_t ch = 0; ch < size_t(kImageRawDim); ++ch)
      detail::rans_encode_bytes(channel_bytes(m.image_raw, M, kImageRawDim, ch).data(), M, &w.bytes);
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !paper(c)) continue;
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
    write_floats(&w, q.ranges.in_absmax);
    write_floats(&w, q.ranges.hidden_max);
    write_floats(&w, q.ranges.out_absmax);
  }
  w.u64(detail::fnv1a64(w.bytes.data(), w.bytes.size()));
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
  if (version != kCompactFileVersion)
    return unsupported(source + ": compact model format version " + std::to_string(version) + ", but this hbgs reads version " +
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
  const size_t K = size_t(c.k), F = size_t(c.feature_dim), R = paper(c) ? size_t(kImageRawDim) : 0;
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
  size_t pos = r.offset();
  std::vector<uint8_t> s(static_cast<size_t>(M));
  std::string err;
  auto stream = [&](const std::string& what) -> Status {
    if (!detail::rans_decode_bytes(data, body_end, &pos, size_t(M), s.data(), &err))
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
  for (size_t i = 1; i < M; ++i) {  // undo the x differences; the sum must stay a 24-bit value
    const uint64_t x = uint64_t(m.pos_q[3 * i]) + m.pos_q[3 * (i - 1)];
    if (x > kMaxQ) return bad("position x of anchor " + std::to_string(i), "exceeds 2^24 grid steps");
    m.pos_q[3 * i] = uint32_t(x);
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
  for (size_t ch = 0; ch < 3 * K; ++ch) {
    GS_RETURN_IF_ERROR(stream("offset channel " + std::to_string(ch)));
    for (size_t i = 0; i < M; ++i) m.offsets[i * 3 * K + ch] = int8_t(s[i]);
  }
  m.log_scales.assign(size_t(M) * 6, 0);
  for (size_t ch = 0; ch < 6; ++ch)
    for (int b = 0; b < 2; ++b) {
      GS_RETURN_IF_ERROR(stream("log-scale channel " + std::to_string(ch)));
      for (size_t i = 0; i < M; ++i) m.log_scales[6 * i + ch] |= uint16_t(s[i] << (8 * b));
    }
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
    for (size_t i = 0; i < M; ++i) m.image_raw[i * R + ch] = s[i];
  }
  detail::ByteReader t(data, body_end, source);
  t.skip(pos);
  for (int id = 0; id < kMlpCount; ++id) {
    if (id == kMlpImage && !paper(c)) continue;
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
