// SPDX-License-Identifier: MIT
// Evaluation of a trained model on held-out views (ALGORITHM.md Part A item 10): render each view
// on the model's background, quantise to 8 bits, then PSNR, SSIM and (when weights are given)
// LPIPS-Alex against the 8-bit ground truth (a masked view's photo composited on the same
// background, gs/io/composite.h), and for masked views PSNR inside the mask and the rendered alpha
// against the mask; optional PNG output. The figures come back as data (EvalResult); the jobs
// write them as the 3DGS results.json / per_view.json (gs::jobs::write_eval_files).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/model_renderer.h"
#include "gs/status.h"

namespace gs::metrics { class LpipsAlex; }
namespace gs::platform { class ThreadPool; }

namespace gs::model {

class Trainer;

struct ViewMetrics {
  std::string name;
  // A view with pixels that have no source (io::DatasetView::valid: undistortion's outside) is
  // measured over the others: those pixels are 0 in both the render and the ground truth (what
  // they held does not matter), PSNR is over the valid pixels (psnr_u8_masked), SSIM is
  // 1 - (1 - SSIM of the images) / (valid fraction) (the SSIM deficit per valid pixel: a window
  // wholly inside the missing pixels has SSIM 1, one across their edge counts), and LPIPS is of
  // the filled images.
  double psnr = 0, ssim = 0;
  double lpips = -1;       // < 0: not computed (no weights)
  // Views with a mask (DatasetView::mask; < 0 otherwise): PSNR over the subject only (squared
  // errors weighted by the mask), and the rendered alpha (1 - final transmittance) against the
  // mask: mean absolute difference and intersection over union of the two thresholded at 0.5.
  double psnr_masked = -1, alpha_mae = -1, alpha_iou = -1;
  double render_ms = 0;    // model decode + render, one view
  size_t gaussians = 0;    // kept neural Gaussians in this view
};

struct EvalResult {
  std::vector<ViewMetrics> views;
  double psnr = 0, ssim = 0, lpips = -1;  // means over views (lpips < 0: not computed)
  double psnr_masked = -1, alpha_mae = -1, alpha_iou = -1;  // means over the views with a mask (< 0: none)
  double render_ms_median = 0;
};

struct EvalOptions {
  const metrics::LpipsAlex* lpips = nullptr;  // null: skip LPIPS
  std::string render_dir;                     // non-empty: write <dir>/<view stem>.png (atomic)
  bool psnr_only = false;                     // quick evaluation during training (no SSIM / LPIPS / PNG)
  ModelRenderOptions render;                  // e.g. the fixed-point blending of the on-device path
  // Masked views: the render is composited through the view's mask on the background before any
  // metric (render * mask + background * (1 - mask)), as its photo is. For a model trained on the
  // whole photos (no masks): its figures inside the mask then compare with those of a masked run.
  bool composite_renders = false;
};

// The render file of each view: <dir>/<image name with .png>, sub-folders kept. Refused with a
// message when a name would lead outside dir (gs/platform/path.h) or two views would write one file
// ("a.jpg" and "a.png"). evaluate_views and the render job name their PNGs with this.
Expected<std::vector<std::string>> render_png_paths(const std::string& dir, const std::vector<const io::DatasetView*>& views);

Expected<EvalResult> evaluate_views(const HybridModel& model, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool);
// The same with a trainer's own pipeline (its current model, forward only, float): no second
// renderer and workspace during training. Views larger than the training views, fixed point and
// int8 fall back to a ModelRenderer of the trainer's model (on pool).
Expected<EvalResult> evaluate_views(Trainer& trainer, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool);
// The same for plain Gaussians (a baked model or a 3DGS scene; int8_mlp does not apply).
Expected<EvalResult> evaluate_views(const GaussianCloud& cloud, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool);

}  // namespace gs::model
