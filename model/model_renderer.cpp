// SPDX-License-Identifier: MIT
// ModelRenderer (gs/model/model_renderer.h): a trained model's views for evaluation and rendering,
// forward only in float (optionally the fixed-point blending and the int8 decoder of a compact
// model), or plain Gaussians (a baked model, a splat file) with their SH colours.
#include "gs/model/model_renderer.h"

#include <algorithm>

#include "cloud_decode.h"
#include "float_backend.h"
#include "gs/model/compact_model.h"
#include "gs/model/quant_decoder.h"
#include "gs/platform/clock.h"
#include "gs/render.h"

namespace gs::model {


struct ModelRenderer::Impl {
  Renderer renderer;
  detail::FloatBackend backend;
  StepWorkspace<float> ws;
  size_t capacity = 0;
  ModelRenderOptions options;
  double decode_ms = 0, forward_ms = 0;
  QuantDecoder int8;
  const CompactModel* int8_source = nullptr;  // what int8 was prepared from
  detail::CloudDecoder cloud;  // plain Gaussians (init with a GaussianCloud)

  void finish(Status st, const Camera& camera, float* alpha) const {
    if (!st.ok() || !alpha) return;
    const size_t n = size_t(camera.intr.width) * size_t(camera.intr.height);
    const float* T = renderer.final_transmittance();
    for (size_t i = 0; i < n; ++i) alpha[i] = 1.0f - T[i];
  }

  // Prepares (once per compact model) and attaches the int8 decoder, or detaches it.
  Status plan_int8() {
    if (!options.int8_mlp) {
      backend.set_int8_decoder(nullptr, nullptr, 0);
      return Status::Ok();
    }
    if (int8_source != options.int8_mlp) {
      Expected<QuantDecoder> q = prepare_quant_decoder(*options.int8_mlp);
      if (!q.ok()) return q.status();
      int8 = std::move(q).value();
      int8_source = options.int8_mlp;
    }
    if (capacity > 0) backend.set_int8_decoder(&int8, nullptr, ws.visible_capacity);
    return Status::Ok();
  }
};

ModelRenderer::ModelRenderer() : impl_(new Impl) {}
ModelRenderer::~ModelRenderer() = default;

Status ModelRenderer::set_options(const ModelRenderOptions& options) {
  Impl& d = *impl_;
  d.options = options;
  d.backend.fixed_point_raster = options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) d.backend.background[c] = options.background[c];
  return d.plan_int8();
}

Status ModelRenderer::init(const HybridModel& model, int max_width, int max_height, platform::ThreadPool* pool,
                           const simd::KernelTable* kernels, const std::vector<Camera>* views) {
  GS_RETURN_IF_ERROR(model.config.validate());
  const simd::KernelTable* kt = kernels ? kernels : &simd::best_kernel_table();
  const size_t cap = std::max<size_t>(model.anchor_count, 1);
  // With the views to render: their most visible anchors (a dry run of the visibility test; exact
  // for this model). The kept Gaussians are planned by the first views that decode (a few grow the
  // plan by half again; a snowmiku view keeps about 40 % of its k per visible anchor).
  size_t visible = 0;
  if (views && !views->empty()) {
    const AnchorParams<float> a = detail::model_params(model).anchors;
    for (const Camera& cam : *views) visible = std::max(visible, select_visible_anchors(cam, a, static_cast<uint32_t*>(nullptr)));
    visible = std::max<size_t>(visible, 1);
  }
  Expected<RenderCapacity> rc = detail::plan_model_pipeline(model, cap, max_width, max_height, max_width, max_height, pool,
                                                            kt, &impl_->renderer, &impl_->backend, &impl_->ws,
                                                            /*training=*/false, detail::kReplannedIsectsPerGaussian, visible,
                                                            visible > 0 ? 1 : 0);
  if (!rc.ok()) return rc.status();
  impl_->capacity = cap;
  impl_->backend.fixed_point_raster = impl_->options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) impl_->backend.background[c] = impl_->options.background[c];
  return impl_->plan_int8();
}

Status ModelRenderer::render(const HybridModel& model, const Camera& camera, float* rgb, size_t* gaussians, float* alpha) {
  Impl& d = *impl_;
  if (model.anchor_count > d.capacity) return capacity_exceeded("model renderer: the model has more anchors than planned");
  GS_RETURN_IF_ERROR(validate_camera(camera));
  ModelParamsT<float> p = detail::model_params(model);
  if (d.options.int8_mlp) {
    const float* keys[kMlpCount];
    for (int id = 0; id < kMlpCount; ++id) keys[id] = model.mlps[id].params.empty() ? nullptr : model.mlps[id].params.data();
    d.backend.set_int8_keys(keys);
  }
  size_t V = 0;
  const uint64_t t0 = platform::now_ns();
  const size_t N = decode_view(d.backend, p, camera, d.ws, &V);
  const uint64_t t1 = platform::now_ns();
  if (gaussians) *gaussians = N;
  const Status st = d.backend.render_fwd(camera, d.ws.ng, rgb);
  d.decode_ms = double(t1 - t0) * 1e-6;
  d.forward_ms = double(platform::now_ns() - t1) * 1e-6;
  d.finish(st, camera, alpha);
  return st;
}

Status ModelRenderer::init(const GaussianCloud& cloud, int max_width, int max_height, platform::ThreadPool* pool,
                           const simd::KernelTable* kernels) {
  Impl& d = *impl_;
  if (cloud.size() == 0) return invalid_argument("model renderer: the cloud has no Gaussians");
  const simd::KernelTable* kt = kernels ? kernels : &simd::best_kernel_table();
  GS_RETURN_IF_ERROR(d.renderer.init(detail::cloud_render_capacity(cloud.size(), max_width, max_height), pool, kt));
  d.backend.init(&d.renderer, kt, pool, 1, max_width);
  d.backend.fixed_point_raster = d.options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) d.backend.background[c] = d.options.background[c];
  d.cloud.reserve(cloud.size(), cloud.sh_degree);
  d.capacity = 0;  // no anchor model planned
  return Status::Ok();
}

Status ModelRenderer::render(const GaussianCloud& cloud, const Camera& camera, float* rgb, size_t* gaussians, float* alpha) {
  Impl& d = *impl_;
  if (cloud.size() > d.cloud.capacity()) return capacity_exceeded("model renderer: the cloud has more Gaussians than planned");
  GS_RETURN_IF_ERROR(validate_camera(camera));
  const uint64_t t0 = platform::now_ns();
  const size_t n = d.cloud.decode(cloud, camera);
  const uint64_t t1 = platform::now_ns();
  if (gaussians) *gaussians = n;
  const Status st = d.backend.render_params(camera, d.cloud.params(), rgb);
  d.decode_ms = double(t1 - t0) * 1e-6;
  d.forward_ms = double(platform::now_ns() - t1) * 1e-6;
  d.finish(st, camera, alpha);
  return st;
}

double ModelRenderer::last_decode_ms() const { return impl_->decode_ms; }
double ModelRenderer::last_forward_ms() const { return impl_->forward_ms; }

void ModelRenderer::set_stage_times(StageTimes* times) {
  impl_->renderer.set_stage_times(times);
  impl_->ws.stage_times = times;
}

}  // namespace gs::model
