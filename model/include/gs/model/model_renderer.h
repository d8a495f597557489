// SPDX-License-Identifier: MIT
// Rendering a trained model's views without gradients (evaluation, the render job, baking, the
// report): the anchor model decoded and splatted in float, optionally with the on-device
// fixed-point blending and the int8 decoder of a compact model; or plain Gaussians (a baked model,
// a splat file) with their SH colours.
#pragma once

#include <cstddef>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/model/hybrid_model.h"
#include "gs/stage_times.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }
namespace gs::simd { struct KernelTable; }

namespace gs::model {

struct CompactModel;

// How ModelRenderer renders: the float path (default), or the on-device fixed-point blending.
struct ModelRenderOptions {
  bool fixed_point_raster = false;  // RenderOptions::fixed_point: the int16 tile kernel (gs/simd/qsplat.h)
  // Non-null: the decoder MLPs run as int8 (qmlp_fwd, gs/model/quant_decoder.h) with this compact
  // model's weights and calibrated ranges; the model rendered must be its dequantize(). Kept alive
  // by the caller.
  const CompactModel* int8_mlp = nullptr;
  float background[3] = {0, 0, 0};  // the colour behind the Gaussians (the model's training background)
};

// Renders views of a trained model (no gradients): the step graph's forward in float. Allocates at
// init(), and when a view decodes more anchors or Gaussians than planned (then the plan grows by
// half again of what that view needs).
class ModelRenderer {
 public:
  ModelRenderer();
  ~ModelRenderer();
  // Takes effect from the next render(); preparing the int8 decoder can fail (a compact model
  // without calibrated ranges).
  Status set_options(const ModelRenderOptions& options);
  // Plans for the model's capacity and images up to max_width x max_height. views (optional): the
  // cameras that will be rendered; the decoder workspace is then planned for the most anchors one of
  // them sees (a view that sees more later grows it: one allocation).
  Status init(const HybridModel& model, int max_width, int max_height, platform::ThreadPool* pool,
              const simd::KernelTable* kernels = nullptr, const std::vector<Camera>* views = nullptr);
  // Plans for plain Gaussians instead (a baked model or a 3DGS scene read from a file): render()
  // with the cloud then draws the Gaussians in view with their SH colours for the camera.
  Status init(const GaussianCloud& cloud, int max_width, int max_height, platform::ThreadPool* pool,
              const simd::KernelTable* kernels = nullptr);
  // rgb: [H, W, 3] floats (not clamped). gaussians: kept neural Gaussians of this view (optional).
  // alpha [H, W] (optional): the render's opacity, 1 - final transmittance.
  Status render(const HybridModel& model, const Camera& camera, float* rgb, size_t* gaussians = nullptr,
                float* alpha = nullptr);
  Status render(const GaussianCloud& cloud, const Camera& camera, float* rgb, size_t* gaussians = nullptr,
                float* alpha = nullptr);
  // Wall time of the last render's two stages, ms: decoding the anchors (MLPs) and the Gaussian
  // renderer's forward (projection, binning, sorting, blending).
  double last_decode_ms() const;
  double last_forward_ms() const;
  // Per-stage wall times of the following renders (gs/stage_times.h: anchor selection to decoding,
  // then the Gaussian renderer's projection, binning, sorting and blending) are added to *times;
  // null stops it. Not owned; bench_fixed_point --profile.
  void set_stage_times(StageTimes* times);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gs::model
