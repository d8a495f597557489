// SPDX-License-Identifier: MIT
// Evaluation of a trained model on held-out views: ModelRenderer -> clamp -> 8 bits -> PSNR / SSIM
// / LPIPS-Alex against the 8-bit ground truth, optional PNGs; the figures as an EvalResult (the
// jobs write the 3DGS JSON files).
#include "gs/model/evaluate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <type_traits>

#include "gs/io/composite.h"
#include "gs/io/image.h"
#include "gs/metrics/image_metrics.h"
#include "gs/metrics/lpips.h"
#include "gs/model/model_renderer.h"
#include "gs/model/trainer.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/path.h"
#include "gs/stats.h"

namespace gs::model {
namespace {

double mean(const std::vector<ViewMetrics>& views, double ViewMetrics::*field) {
  if (views.empty()) return 0.0;
  double sum = 0;
  for (const ViewMetrics& v : views) sum += v.*field;
  return sum / double(views.size());
}

// Mean over the views that have the metric (masked views; >= 0), -1 when none has it.
double mean_of_masked(const std::vector<ViewMetrics>& views, double ViewMetrics::*field) {
  double sum = 0;
  int n = 0;
  for (const ViewMetrics& v : views)
    if (v.*field >= 0) sum += v.*field, ++n;
  return n ? sum / n : -1.0;
}

// PSNR inside the mask (gs::metrics::psnr_u8_masked: squared errors weighted by coverage; -1 when
// the mask covers nothing), and the render's alpha against the mask (mean absolute difference; IoU
// of both thresholded at 0.5).
void mask_metrics(const uint8_t* render, const uint8_t* gt, const uint8_t* mask, const float* alpha, int w, int h,
                  ViewMetrics* m) {
  const size_t n = size_t(w) * size_t(h);
  double abs_diff = 0;
  size_t both = 0, either = 0;
  for (size_t p = 0; p < n; ++p) {
    const double cover = mask[p] / 255.0;
    abs_diff += std::fabs(double(alpha[p]) - cover);
    const bool in_mask = mask[p] >= 128, in_render = alpha[p] >= 0.5f;
    both += in_mask && in_render;
    either += in_mask || in_render;
  }
  const double psnr = metrics::psnr_u8_masked(render, gt, mask, w, h);
  m->psnr_masked = std::isnan(psnr) ? -1.0 : psnr;
  m->alpha_mae = abs_diff / double(n);
  m->alpha_iou = either ? double(both) / double(either) : 1.0;
}

}  // namespace

Expected<std::vector<std::string>> render_png_paths(const std::string& dir, const std::vector<const io::DatasetView*>& views) {
  std::vector<std::string> out;
  std::map<std::string, std::string> owner;  // output path -> view name
  for (const io::DatasetView* v : views) {
    std::filesystem::path rel(v->name);
    rel.replace_extension(".png");
    Expected<std::string> path = platform::join_inside(dir, rel.string());
    if (!path.ok()) return Status(path.status().code(), "view " + v->name + ": " + path.status().message());
    const auto [it, fresh] = owner.emplace(*path, v->name);
    if (!fresh)
      return invalid_argument("views '" + it->second + "' and '" + v->name + "' would both be rendered to " + *path +
                              "; rename one of the images");
    out.push_back(*path);
  }
  return out;
}

namespace {

// The evaluation itself. Render(camera, rgb, gaussians, alpha) draws a view; plan(max_w, max_h)
// prepares it for the largest view (a ModelRenderer over a model or a cloud, or a trainer's own
// pipeline).
template <class Plan, class Render>
Expected<EvalResult> evaluate_with(const std::vector<const io::DatasetView*>& views, const EvalOptions& options, Plan&& plan,
                                   Render&& render) {
  if (views.empty()) return invalid_argument("evaluation: no views to evaluate");
  int max_w = 0, max_h = 0;
  for (const io::DatasetView* v : views) {
    const int w = v->camera.intr.width, h = v->camera.intr.height;
    if (v->image.width != w || v->image.height != h || v->image.channels != 3)
      return invalid_argument("evaluation: view " + v->name + ": its image is not a " + std::to_string(w) + "x" +
                              std::to_string(h) + " RGB image");
    if (!v->mask.empty() && (v->mask.width != w || v->mask.height != h || v->mask.channels != 1))
      return invalid_argument("evaluation: view " + v->name + ": its mask is not one channel of the image's size");
    if (!v->valid.empty() && (v->valid.width != w || v->valid.height != h || v->valid.channels != 1))
      return invalid_argument("evaluation: view " + v->name + ": its valid-pixel map is not one channel of the image's size");
    max_w = std::max(max_w, w);
    max_h = std::max(max_h, h);
  }
  const bool full = !options.psnr_only;
  std::vector<std::string> pngs;
  if (full && !options.render_dir.empty()) {
    Expected<std::vector<std::string>> paths = render_png_paths(options.render_dir, views);
    if (!paths.ok()) return Status(paths.status().code(), "evaluation: " + paths.status().message());
    pngs = std::move(paths).value();
    GS_RETURN_IF_ERROR(platform::make_dirs(options.render_dir));
  }

  // LPIPS-Alex needs 31 px a side: smaller views are evaluated without it (for every view, so the
  // mean stays over one set), instead of failing a whole training run at its last evaluation.
  bool small = false;
  for (const io::DatasetView* v : views)
    small = small || v->camera.intr.width < metrics::LpipsAlex::kMinSide || v->camera.intr.height < metrics::LpipsAlex::kMinSide;
  const metrics::LpipsAlex* lpips = small ? nullptr : options.lpips;
  GS_RETURN_IF_ERROR(plan(max_w, max_h));
  std::vector<float> rgb(size_t(max_w) * size_t(max_h) * 3), alpha(size_t(max_w) * size_t(max_h));
  EvalResult result;
  result.views.reserve(views.size());
  std::vector<double> render_ms;
  for (const io::DatasetView* v : views) {
    ViewMetrics m;
    m.name = v->name;
    const double t0 = platform::now_seconds();
    GS_RETURN_IF_ERROR(render(v->camera, rgb.data(), &m.gaussians, alpha.data()));
    m.render_ms = 1e3 * (platform::now_seconds() - t0);
    render_ms.push_back(m.render_ms);
    const int w = v->camera.intr.width, h = v->camera.intr.height;
    if (options.composite_renders && !v->mask.empty()) {
      const float* bg = options.render.background;
      for (size_t p = 0; p < size_t(w) * size_t(h); ++p) {
        const float m = float(v->mask.pixels[p]) * (1.0f / 255.0f);
        for (size_t c = 0; c < 3; ++c) rgb[3 * p + c] = rgb[3 * p + c] * m + bg[c] * (1.0f - m);
      }
    }
    io::Image8 img = io::image_from_float_rgb(rgb.data(), w, h);  // clamps to [0, 1], rounds
    io::Image8 composited = io::composite_rgb8(v->image, v->mask, options.render.background);
    const uint8_t* gt = composited.pixels.data();
    // Pixels without a source (DatasetView::valid) are 0 in both the render and the ground truth,
    // so they add no error and what they held does not matter; the figures are over the valid
    // pixels (see ViewMetrics).
    size_t missing = 0;
    if (!v->valid.empty()) {
      for (size_t p = 0; p < size_t(w) * size_t(h); ++p) {
        if (v->valid.pixels[p]) continue;
        ++missing;
        for (size_t c = 0; c < 3; ++c) img.pixels[3 * p + c] = composited.pixels[3 * p + c] = 0;
      }
    }
    const double valid_fraction = 1.0 - double(missing) / (double(w) * double(h));
    m.psnr = missing ? metrics::psnr_u8_masked(img.pixels.data(), gt, v->valid.pixels.data(), w, h)
                     : metrics::psnr_u8(img.pixels.data(), gt, w, h);
    if (!v->mask.empty()) mask_metrics(img.pixels.data(), gt, v->mask.pixels.data(), alpha.data(), w, h, &m);
    if (full) {
      m.ssim = metrics::ssim_u8(img.pixels.data(), gt, w, h);
      if (missing) m.ssim = valid_fraction > 0 ? 1 - (1 - m.ssim) / valid_fraction : 1.0;
      if (lpips) {
        Expected<double> d = lpips->distance(img.pixels.data(), gt, w, h);
        if (!d.ok()) return Status(d.status().code(), "evaluation: view " + v->name + ": " + d.status().message());
        m.lpips = *d;
      }
      if (!options.render_dir.empty()) {
        const std::string& path = pngs[result.views.size()];
        const std::string parent = std::filesystem::path(path).parent_path().string();
        if (!parent.empty()) GS_RETURN_IF_ERROR(platform::make_dirs(parent));
        GS_RETURN_IF_ERROR(io::write_png(path, img));
      }
    }
    result.views.push_back(std::move(m));
  }
  result.psnr = mean(result.views, &ViewMetrics::psnr);
  result.ssim = mean(result.views, &ViewMetrics::ssim);
  result.lpips = full && lpips ? mean(result.views, &ViewMetrics::lpips) : -1.0;
  result.psnr_masked = mean_of_masked(result.views, &ViewMetrics::psnr_masked);
  result.alpha_mae = mean_of_masked(result.views, &ViewMetrics::alpha_mae);
  result.alpha_iou = mean_of_masked(result.views, &ViewMetrics::alpha_iou);
  result.render_ms_median = median(render_ms);
  return result;
}

// A model or a cloud through a ModelRenderer of its own.
template <class Scene>
Expected<EvalResult> evaluate_scene(const Scene& scene, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool) {
  ModelRenderer renderer;
  return evaluate_with(
      views, options,
      [&](int w, int h) {
        GS_RETURN_IF_ERROR(renderer.set_options(options.render));
        if constexpr (std::is_same_v<Scene, HybridModel>) {
          std::vector<Camera> cameras;  // the decoder workspace is planned for what these views see
          for (const io::DatasetView* v : views) cameras.push_back(v->camera);
          return renderer.init(scene, w, h, pool, nullptr, &cameras);
        } else {
          return renderer.init(scene, w, h, pool);
        }
      },
      [&](const Camera& cam, float* rgb, size_t* n, float* alpha) { return renderer.render(scene, cam, rgb, n, alpha); });
}

}  // namespace

Expected<EvalResult> evaluate_views(const HybridModel& model, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool) {
  return evaluate_scene(model, views, options, pool);
}

Expected<EvalResult> evaluate_views(const GaussianCloud& cloud, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool) {
  return evaluate_scene(cloud, views, options, pool);
}

Expected<EvalResult> evaluate_views(Trainer& trainer, const std::vector<const io::DatasetView*>& views,
                                    const EvalOptions& options, platform::ThreadPool* pool) {
  int max_w = 0, max_h = 0;
  for (const io::DatasetView* v : views) max_w = std::max(max_w, v->camera.intr.width), max_h = std::max(max_h, v->camera.intr.height);
  if (options.render.fixed_point_raster || options.render.int8_mlp || !trainer.can_render(max_w, max_h))
    return evaluate_scene(trainer.model(), views, options, pool);
  return evaluate_with(
      views, options, [](int, int) { return Status::Ok(); },
      [&](const Camera& cam, float* rgb, size_t* n, float* alpha) {
        return trainer.render(cam, options.render.background, rgb, n, alpha);
      });
}

}  // namespace gs::model
