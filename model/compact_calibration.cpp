// SPDX-License-Identifier: MIT
// The calibration scan of a model over its training cameras (compact_calibration.h): visibility,
// kept anchors and activation ranges, for pruning and the int8 decoder.
#include "compact_calibration.h"

#include <algorithm>
#include <cmath>

#include "float_backend.h"
#include "gs/model/decode.h"
#include "gs/model/step_graph.h"
#include "gs/random.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"

namespace gs::model::detail {

namespace {

void update_absmax(const float* x, size_t rows, size_t cols, std::vector<float>* m) {
  float* out = m->data();
  for (size_t r = 0; r < rows; ++r)
    for (size_t c = 0; c < cols; ++c) out[c] = std::max(out[c], std::fabs(x[r * cols + c]));
}

}  // namespace

Status scan_views(const HybridModel& m, const std::vector<Camera>& cams, platform::ThreadPool* pool, CalibrationScan* out) {
  const size_t M = m.anchor_count, K = size_t(m.config.k);
  out->seen.assign(M, 0);
  out->kept.assign(M, 0);
  out->kept_gaussian.assign(M * K, 0);
  ModelParamsT<float> p = model_params(m);
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
  FloatBackend be;
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
        if (op[v * K + j] > 0.0f) out->kept[rows[v]] = 1, out->kept_gaussian[size_t(rows[v]) * K + j] = 1;
  }
  return Status::Ok();
}

Status offset_sensitivity_scan(const HybridModel& m, const std::vector<Camera>& cams, platform::ThreadPool* pool,
                               std::vector<double>* out) {
  const size_t M = m.anchor_count, K = size_t(m.config.k);
  out->assign(M, 0.0);
  if (M == 0 || cams.empty()) return Status::Ok();
  int W = 1, H = 1;
  for (const Camera& c : cams) W = std::max(W, c.intr.width), H = std::max(H, c.intr.height);
  Renderer renderer;
  FloatBackend be;
  StepWorkspace<float> ws;
  Expected<RenderCapacity> rc = plan_model_pipeline(m, M, W, H, W, H, pool, &simd::best_kernel_table(), &renderer, &be, &ws,
                                                    /*training=*/true);
  if (!rc.ok()) return rc.status();
  const ModelParamsT<float> p = model_params(m);
  gs::SplitMix64 rng{0x5eed0ff5e7ull};
  for (const Camera& cam : cams) {
    size_t V = 0;
    const size_t N = decode_view(be, p, cam, ws, &V);
    GS_RETURN_IF_ERROR(be.render_fwd(cam, ws.ng, ws.rgb.data()));
    const size_t values = size_t(cam.intr.width) * size_t(cam.intr.height) * 3;
    for (size_t i = 0; i < values; i += 64) {
      const uint64_t bits = rng.next();
      for (size_t b = 0; b < 64 && i + b < values; ++b) ws.v_rgb[i + b] = (bits >> b) & 1u ? 1.0f : -1.0f;
    }
    double v_pose[6] = {0, 0, 0, 0, 0, 0};
    GS_RETURN_IF_ERROR(be.render_bwd(ws.v_rgb.data(), ws.v_means.data(), ws.v_log_scales.data(), ws.v_quats.data(),
                                     ws.v_opacities.data(), ws.v_colors.data(), ws.v_means2d.data(), v_pose));
    for (size_t i = 0; i < N; ++i) {
      const size_t row = ws.rows[ws.ng.source[i] / K];
      const float* ls = &m.log_scales[6 * row];
      for (int l = 0; l < 3; ++l) {
        const double g = double(ws.v_means[3 * i + size_t(l)]) * std::exp(double(ls[l]));
        (*out)[row] += g * g;
      }
    }
  }
  return Status::Ok();
}

}  // namespace gs::model::detail
