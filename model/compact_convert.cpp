// SPDX-License-Identifier: MIT
// A float model to a compact one and back (gs/model/compact_model.h): pruning by the calibration
// scan, positions on the voxel grid in Morton order for delta coding, per-channel quantisation, and the
// activation ranges of the dequantised model.
#include <algorithm>
#include <cmath>
#include <numeric>

#include "compact_calibration.h"
#include "gs/model/compact_model.h"
#include "quantize.h"

namespace gs::model {

namespace {

constexpr int kValidFlag = kImageRawDim - 1;  // image_raw's last channel: 1 when some view sees the anchor
// Measured offset steps stay at most max |offset| / 8: coarser ones move a Gaussian by a good part
// of its offset, where the small-error model behind the steps no longer holds.
constexpr double kMinOffsetLevels = 8;

// A copy of the live rows listed in keep (in that order).
HybridModel select_rows(const HybridModel& m, const std::vector<size_t>& keep) {
  HybridModel o;
  o.config = m.config;
  o.voxel_size = m.voxel_size;
  o.scene_extent = m.scene_extent;
  o.frame = m.frame;
  o.anchor_count = keep.size();
  for (int i = 0; i < kMlpCount; ++i) o.mlps[i] = m.mlps[i];
  const size_t K = size_t(m.config.k), F = size_t(m.config.feature_dim);
  const size_t R = uses_image_features(m.config.image_features) ? size_t(kImageRawDim) : 0;
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

}  // namespace

Expected<CompactModel> compact_from_model(const HybridModel& model, const std::vector<Camera>& cameras,
                                          const CompactOptions& options, platform::ThreadPool* pool, CompactStats* stats) {
  GS_RETURN_IF_ERROR(model.config.validate());
  GS_RETURN_IF_ERROR(check_model_finite(model, "compact: the float model"));
  if (options.residual_bits < 0 || options.residual_bits > 12)
    return invalid_argument("compact: residual bits " + std::to_string(options.residual_bits) + " outside 0..12");
  if (options.offset_levels < 1 || options.offset_levels > 127 || options.feature_levels < 1 || options.feature_levels > 127)
    return invalid_argument("compact: offset and feature levels must be in 1..127");
  if (options.image_levels < 1 || options.image_levels > 255) return invalid_argument("compact: image feature levels must be in 1..255");
  if (!(options.log_scale_step >= 0 && options.log_scale_step <= 1))
    return invalid_argument("compact: the log-scale step must be in [0, 1] (0: half precision)");
  if (!(model.voxel_size > 0) || !std::isfinite(model.voxel_size))
    return invalid_argument("compact: the model's voxel size " + std::to_string(model.voxel_size) + " is not positive");
  const ModelConfig& c = model.config;
  const size_t K = size_t(c.k), F = size_t(c.feature_dim);
  CompactStats st;
  st.anchors_in = model.anchor_count;
  st.views = cameras.size();

  // 1. Pruning on the float model.
  std::vector<size_t> keep;
  detail::CalibrationScan scan;
  {
    if ((options.prune || options.prune_offsets) && !cameras.empty()) GS_RETURN_IF_ERROR(detail::scan_views(model, cameras, pool, &scan));
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
  cm.frame = model.frame;
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
      if (!(v >= 0 && v <= double(detail::kMaxPositionQ)))
        return invalid_argument("compact: anchor positions span more than 2^24 steps of voxel size / 2^" +
                                std::to_string(options.residual_bits) + " on axis " + std::to_string(a) + "; use fewer residual bits");
      q[3 * r + size_t(a)] = uint32_t(v);
    }
  std::vector<size_t> order(M);
  std::iota(order.begin(), order.end(), size_t(0));
  // Morton (Z) order of the voxel cells, so that rows next to each other are near in space and
  // their positions and image features differ little; ties by the full grid position.
  const int rb = options.residual_bits;
  std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
    const uint32_t* a = &q[3 * x];
    const uint32_t* b = &q[3 * y];
    int axis = 0;
    uint32_t top = 0;
    for (int d = 2; d >= 0; --d) {  // the axis whose cells differ in the highest bit decides (z > y > x at equal bits)
      const uint32_t diff = (a[d] >> rb) ^ (b[d] >> rb);
      if (top < diff && top < (top ^ diff)) top = diff, axis = d;
    }
    if (top) return (a[axis] >> rb) < (b[axis] >> rb);
    return std::lexicographical_compare(a, a + 3, b, b + 3);
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
  // A neural Gaussian no training view keeps (opacity <= 0 in all) is never drawn there: its offset
  // is stored as 0 and does not widen the anchor's step (its opacity does not depend on it).
  const bool drop_offsets = options.prune_offsets && !cameras.empty();
  std::vector<float> largest(M, 0.0f);  // per anchor: max |offset| of its stored Gaussians
  for (size_t r = 0; r < M; ++r) {
    const uint8_t* live = drop_offsets ? &scan.kept_gaussian[rows[r] * K] : nullptr;
    for (size_t i = 0; i < 3 * K; ++i)
      if (!live || live[i / 3]) largest[r] = std::max(largest[r], std::fabs(sel.offsets[r * 3 * K + i]));
  }
  std::vector<double> offset_step(M);
  for (size_t r = 0; r < M; ++r) offset_step[r] = double(largest[r]) / options.offset_levels;
  if (options.weighted_offsets && !cameras.empty() && M) {
    // Rate-distortion: the steps that give the same rendered error (sum over anchors of the
    // measured sensitivity times step^2) as max / levels everywhere at the fewest bits are
    // proportional to 1 / sqrt(sensitivity) (each anchor then adds the same error), kept within
    // [max / 127, max / kMinOffsetLevels] (finer would clip); the common factor by bisection.
    std::vector<double> sens;
    GS_RETURN_IF_ERROR(detail::offset_sensitivity_scan(sel, cameras, pool, &sens));
    double target = 0;
    for (size_t r = 0; r < M; ++r) target += sens[r] * offset_step[r] * offset_step[r];
    auto steps_at = [&](double lambda, std::vector<double>* out) {
      double d = 0;
      for (size_t r = 0; r < M; ++r) {
        const double lo = double(largest[r]) / 127.0, hi = double(largest[r]) / kMinOffsetLevels;
        const double s = sens[r] > 0 ? std::clamp(lambda / std::sqrt(sens[r]), lo, hi) : hi;
        if (out) (*out)[r] = s;
        d += sens[r] * s * s;
      }
      return d;
    };
    if (target > 0) {
      double lo = -80, hi = 80;  // log2 lambda
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (steps_at(std::exp2(mid), nullptr) > target ? hi : lo) = mid;
      }
      steps_at(std::exp2(lo), &offset_step);
    }
  }
  for (size_t r = 0; r < M; ++r) {
    const float* o = &sel.offsets[r * 3 * K];
    const uint8_t* live = drop_offsets ? &scan.kept_gaussian[rows[r] * K] : nullptr;
    cm.offset_scale[r] = float_to_half(float(offset_step[r]));
    // fp16 rounding may land just under max / 127: round the step up so no offset clips.
    while (largest[r] > 0 && half_to_float(cm.offset_scale[r]) * 127.0f < largest[r] && cm.offset_scale[r] < 0x7bffu)
      ++cm.offset_scale[r];
    const float sc = half_to_float(cm.offset_scale[r]);
    for (size_t i = 0; i < 3 * K; ++i) {
      const bool used = !live || live[i / 3];
      cm.offsets[r * 3 * K + i] = used ? detail::q8(o[i], sc) : int8_t(0);
      if (!used && i % 3 == 0) ++st.offsets_dropped;
    }
  }
  detail::quantize_channels(sel.features.data(), M, F, options.feature_levels, &cm.features, &cm.feature_scale);
  if (options.weighted_features && M) {
    // Steps by each channel's weight in the decoders' first layers: the same first-layer noise
    // power as max / levels per channel, spread so every channel adds the same share.
    std::vector<double> g2(F, 0.0);
    for (int id : {kMlpOpacity, kMlpCov, kMlpColor}) {
      const Mlp& mlp = model.mlps[id];
      const size_t I = size_t(mlp.shape.in), H = size_t(mlp.shape.hidden);
      for (size_t h = 0; h < H; ++h)
        for (size_t ch = 0; ch < F; ++ch) g2[ch] += double(mlp.params[h * I + ch]) * mlp.params[h * I + ch];
    }
    double power = 0;
    for (size_t ch = 0; ch < F; ++ch) power += g2[ch] * double(cm.feature_scale[ch]) * cm.feature_scale[ch];
    const double lambda = std::sqrt(power / double(F));
    for (size_t ch = 0; ch < F; ++ch) {
      const float fine = cm.feature_scale[ch] * float(options.feature_levels) / 127.0f;  // max / 127
      if (g2[ch] > 0 && fine > 0) cm.feature_scale[ch] = std::max(fine, float(lambda / std::sqrt(g2[ch])));
    }
    for (size_t r = 0; r < M; ++r)
      for (size_t ch = 0; ch < F; ++ch) cm.features[r * F + ch] = detail::q8(sel.features[r * F + ch], cm.feature_scale[ch]);
  }
  cm.log_scales.resize(M * 6);
  cm.log_scale_step = options.log_scale_step;
  if (cm.log_scale_step > 0) {
    // A grid per channel from its minimum; a span over 65,535 steps coarsens the step to fit.
    float span = 0;
    for (size_t ch = 0; ch < 6; ++ch) {
      float lo = M ? sel.log_scales[ch] : 0.0f, hi = lo;
      for (size_t r = 0; r < M; ++r) lo = std::min(lo, sel.log_scales[6 * r + ch]), hi = std::max(hi, sel.log_scales[6 * r + ch]);
      cm.log_scale_lo[ch] = lo;
      span = std::max(span, hi - lo);
    }
    cm.log_scale_step = std::max(cm.log_scale_step, span / 65535.0f);
    for (size_t r = 0; r < M; ++r)
      for (size_t ch = 0; ch < 6; ++ch) {
        const double t = (double(sel.log_scales[6 * r + ch]) - cm.log_scale_lo[ch]) / cm.log_scale_step;
        cm.log_scales[6 * r + ch] = uint16_t(std::clamp(std::lround(t), 0L, 65535L));
      }
  } else {
    for (size_t i = 0; i < M * 6; ++i) cm.log_scales[i] = float_to_half(sel.log_scales[i]);
  }
  cm.image_levels = options.image_levels;
  if (uses_image_features(c.image_features)) {
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
        const double t = span > 0 ? (double(sel.image_raw[r * R + ch]) - cm.image_lo[ch]) / span * cm.image_levels : 0.0;
        cm.image_raw[r * R + ch] = uint8_t(std::clamp(std::lround(t), 0L, long(cm.image_levels)));
      }
  }
  for (int i = 0; i < kMlpCount; ++i)
    if (i != kMlpImage || uses_image_features(c.image_features)) detail::quantize_mlp(model.mlps[i], options.mlp_fine, &cm.mlps[i]);

  // 4. Activation ranges of the model as it will be decoded (the dequantised one).
  {
    const HybridModel dq = dequantize(cm);
    detail::CalibrationScan scan;
    GS_RETURN_IF_ERROR(detail::scan_views(dq, cameras, pool, &scan));
    for (int i = 0; i < kMlpCount; ++i)
      if (i != kMlpImage || uses_image_features(c.image_features)) cm.mlps[i].ranges = std::move(scan.ranges[i]);
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
  m.frame = cm.frame;
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
  if (cm.log_scale_step > 0) {
    for (size_t i = 0; i < M * 6; ++i) m.log_scales[i] = cm.log_scale_lo[i % 6] + float(cm.log_scales[i]) * cm.log_scale_step;
  } else {
    for (size_t i = 0; i < M * 6; ++i) m.log_scales[i] = half_to_float(cm.log_scales[i]);
  }
  if (uses_image_features(cm.config.image_features)) {
    const size_t R = kImageRawDim;
    m.image_raw.assign(M * R, 0.0f);
    for (size_t r = 0; r < M; ++r) {
      const float levels = float(cm.image_levels);
      const float flag = cm.image_lo[kValidFlag] + float(cm.image_raw[r * R + kValidFlag]) * ((cm.image_hi[kValidFlag] - cm.image_lo[kValidFlag]) / levels);
      if (!(flag >= 0.5f)) continue;  // no view sees it: the raw vector stays all zero
      for (size_t ch = 0; ch < R; ++ch)
        m.image_raw[r * R + ch] = cm.image_lo[ch] + float(cm.image_raw[r * R + ch]) * ((cm.image_hi[ch] - cm.image_lo[ch]) / levels);
    }
  }
  for (int i = 0; i < kMlpCount; ++i)
    if (i != kMlpImage || uses_image_features(cm.config.image_features)) m.mlps[i] = detail::dequantize_mlp(cm.mlps[i]);
  return m;
}

}  // namespace gs::model
