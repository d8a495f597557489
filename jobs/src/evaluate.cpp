// SPDX-License-Identifier: MIT
// The evaluation job (gs/jobs/evaluate.h).
#include "gs/jobs/evaluate.h"

#include <algorithm>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "gs/io/splat_formats.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "json_util.h"

namespace gs::jobs {

namespace fs = std::filesystem;

Status evaluate_run(const EvaluateRunOptions& a, EvaluateRunSummary* summary) {
  if (!platform::file_exists(a.input)) return invalid_argument(a.input + " not found");
  if (!is_model_input(a.input))
    return invalid_argument(a.input + " is neither a run folder (with run.json or model.hbgs), a model file (.hbgs, .hbgc) nor "
                            "a splat file (" + std::string(io::supported_splat_extensions()) + ")");
  if (a.split != "test" && a.split != "train" && a.split != "all")
    return invalid_argument("--split: '" + a.split + "' is not one of test, train, all");
  Expected<ModelViews> loaded = load_model_views(a.input, a.dataset, a.max_width, a.split, a.fisheye_fov);
  if (!loaded.ok()) return loaded.status();
  const ModelSource* src = &loaded->source;
  const model::HybridModel* model = &loaded->model;
  const std::unique_ptr<LoadedDataset>* data = &loaded->data;
  EvaluateRunSummary s;
  Expected<std::unique_ptr<metrics::LpipsAlex>> lpips = load_lpips(a.lpips_weights, a.threads, &s.note);
  if (!lpips.ok()) return lpips.status();

  s.source = *src;
  s.out_dir = a.out.empty() ? (fs::path(src->run_dir) / "eval").string() : a.out;
  platform::ThreadPool pool(a.threads);
  Expected<model::Background> background = model_background(*src, a.background);
  if (!background.ok()) return background.status();
  model::EvalOptions eo;
  std::copy(background->rgb, background->rgb + 3, eo.render.background);
  eo.lpips = lpips->get();
  eo.render.fixed_point_raster = a.fixed_point;
  eo.composite_renders = a.composite_renders;
  if (a.fixed_point) eo.render.int8_mlp = loaded->compact.get();  // int8 MLPs when the file is compact
  if (a.renders) eo.render_dir = s.render_dir = (fs::path(s.out_dir) / a.split / a.method / "renders").string();
  const double t0 = platform::now_seconds();
  Expected<model::EvalResult> r = evaluate_loaded(*loaded, (*data)->views, eo, &pool);
  if (!r.ok()) return r.status();
  s.seconds = platform::now_seconds() - t0;
  for (const model::ViewMetrics& v : r->views) s.mean_gaussians += double(v.gaussians);
  s.mean_gaussians /= double(r->views.size());
  s.anchors = model->anchor_count;
  const bool cloud = loaded->cloud != nullptr;
  nlohmann::json extra = {{"model", absolute_path(src->model_path)},
                          {"dataset", absolute_path(src->dataset)},
                          {"split", a.split},
                          {"views", r->views.size()},
                          {"model_bytes", cloud ? file_size_or_zero(src->model_path) : model->file_bytes()},
                          {"model_file_bytes", file_size_or_zero(src->model_path)},
                          {"anchors", model->anchor_count},
                          {"mean_gaussians_per_view", s.mean_gaussians},
                          {"render_ms_median", r->render_ms_median},
                          {"fixed_point", a.fixed_point},
                          {"background", a.background.empty() ? src->background : a.background},
                          {"image_features", cloud ? "none (plain Gaussians)" : model::image_feature_mode_name(model->config.image_features)}};
  if (cloud) extra["gaussians"] = loaded->cloud->size();
  if (eo.lpips) extra["lpips_backbone"] = metrics::LpipsAlex::kLabel;
  std::string note;
  GS_RETURN_IF_ERROR(write_eval_files(s.out_dir, a.method, *r, extra, &note));
  s.note += note;
  s.result = std::move(r).value();
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace gs::jobs
