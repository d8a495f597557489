// SPDX-License-Identifier: MIT
// Baking the hybrid anchor model into plain 3D Gaussians (issue 16): what splat viewers and other
// 3DGS tools read. The model's neural Gaussians change with the view (the decoders see the view
// direction and distance); a plain Gaussian is fixed, with view-dependent colour as spherical
// harmonics. Two stages:
//   1. Fit, over the given (training) cameras: each candidate Gaussian (anchor row, offset j) is
//      decoded in every view that sees its anchor. Position is view-independent. Opacity is the mean
//      over those views of the decoded opacity (0 where the decoder drops it): the constant that is
//      closest to it in the least-squares sense. Log-scales and the rotation are opacity-weighted
//      means (quaternions sign-aligned first). Colour is a ridge least-squares fit of SH of degree
//      sh_degree to the decoded colours against the anchor's view direction (the decoder's input),
//      with the coefficients above degree 0 pulled towards 0 (so directions no view saw stay near
//      the mean colour). Candidates no view sees, or fainter than min_opacity, are dropped.
//   2. Distillation (distill_iterations > 0): the baked Gaussians are optimised (Adam, L1 + SSIM)
//      to reproduce the model's own renders of the cameras, which recovers much of what a fixed
//      Gaussian cannot express (view-dependent opacity and shape).
// Memory: stage 1 holds per visible anchor the SH normal matrix and per candidate its right-hand
// sides ((K^2 + 3 k K) doubles per anchor, K = (sh_degree + 1)^2); stage 2 the model's renders of
// the cameras at 16 bits per channel and three copies of the cloud (values, Adam moments).
#pragma once

#include <cstddef>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::model {

struct BakeOptions {
  int sh_degree = 3;              // 0..3
  double sh_ridge = 0.1;          // ridge weight on SH coefficients above degree 0, per view sample
  float min_opacity = 1.0f / 255; // baked Gaussians below this are dropped
  int distill_iterations = 0;     // stage 2 steps (one camera each, in a seeded order); 0: fit only
  uint64_t seed = 0;              // camera order of the distillation
  // Colour behind both renders during distillation (the model's training background).
  float background[3] = {0, 0, 0};
};

struct BakeStats {
  size_t candidates = 0;  // anchor rows x offsets
  size_t seen = 0;        // candidates whose anchor some camera sees
  size_t kept = 0;        // Gaussians in the baked cloud
  double fit_seconds = 0, distill_seconds = 0;
  // Mean PSNR of the baked cloud's renders against the model's renders over the cameras, after the
  // fit and after distillation (dB; float renders, unclamped); 0 when not measured.
  double psnr_fit = 0, psnr_distilled = 0;
};

// Bakes the model over cameras (typically the training views' cameras). Errors: no cameras, an
// invalid camera or option, a renderer plan that cannot be allocated.
Expected<GaussianCloud> bake_model(const HybridModel& model, const std::vector<Camera>& cameras, const BakeOptions& options,
                                   platform::ThreadPool* pool, BakeStats* stats = nullptr);

}  // namespace gs::model
