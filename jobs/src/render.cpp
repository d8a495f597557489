// SPDX-License-Identifier: MIT
// The rendering job (gs/jobs/render.h): a dataset with Gaussians from a splat file (3DGS PLY,
// compressed.ply, .splat, .spz: gs::io::read_gaussians) or SfM points through
// gs::Renderer, or a trained model's views through gs::model::evaluate_views.
#include "gs/jobs/render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <system_error>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/splat_formats.h"
#include "gs/jobs/run_folder.h"
#include "gs/metrics/image_metrics.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/scene_init.h"
#include "gs/simd/kernel_table.h"
#include "gs/stats.h"

namespace gs::jobs {
namespace {

namespace fs = std::filesystem;

// PSNR of the render against the view's image (gs::metrics::psnr_u8, +inf when identical), over
// the pixels that have a source when the view marks some without (io::DatasetView::valid); NaN
// when their sizes differ.
double view_psnr(const io::Image8& render, const io::DatasetView& view) {
  const io::Image8& photo = view.image;
  if (render.width != photo.width || render.height != photo.height || render.channels != 3 || photo.channels != 3 ||
      render.pixels.size() != photo.pixels.size() || render.pixels.empty())
    return std::numeric_limits<double>::quiet_NaN();
  if (view.valid.pixels.size() == size_t(render.width) * size_t(render.height))
    return metrics::psnr_u8_masked(render.pixels.data(), photo.pixels.data(), view.valid.pixels.data(), render.width, render.height);
  return metrics::psnr_u8(render.pixels.data(), photo.pixels.data(), render.width, render.height);
}

std::string available_isas() {
  std::string names = "ref";
  const simd::KernelTable* tables[16];
  const int n = simd::available_simd_kernel_tables(tables, 16);
  for (int i = 0; i < n; ++i) names += std::string(", ") + tables[i]->isa;
  return names;
}

// Files this run created, removed again if the run fails part-way so no partial output remains.
class OutputGuard {
 public:
  explicit OutputGuard(fs::path dir, bool created_dir) : dir_(std::move(dir)), created_dir_(created_dir) {}
  ~OutputGuard() {
    if (committed_) return;
    std::error_code ec;
    for (const fs::path& p : files_) fs::remove(p, ec);
    if (created_dir_) fs::remove_all(dir_, ec);  // made by this run: all of it is ours
  }
  void add(const fs::path& p) { files_.push_back(p); }
  void commit() { committed_ = true; }

 private:
  fs::path dir_;
  bool created_dir_;
  bool committed_ = false;
  std::vector<fs::path> files_;
};

// render.json's entry of a view: what both inputs report (PSNR null when identical).
nlohmann::json view_json(const RenderedView& r) {
  return {{"name", r.name},
          {"png", r.png},
          {"split", r.is_test ? "test" : "train"},
          {"width", r.width},
          {"height", r.height},
          {"ms", r.ms},
          {"psnr_db", std::isfinite(r.psnr) ? nlohmann::json(r.psnr) : nlohmann::json(nullptr)}};
}

Status render_model(const RenderRunOptions& a, const std::function<void(const RenderedView&, size_t, size_t)>& progress,
                    RenderRunSummary* summary) {
  const double t0 = platform::now_seconds();
  if (!a.ply.empty()) return invalid_argument("--ply cannot be combined with a trained model (" + a.input + ")");
  if (!a.isa.empty()) return invalid_argument("--isa applies to PLY / SfM-point rendering, not to a trained model");
  Expected<ModelViews> loaded = load_model_views(a.input, a.model_dataset, a.max_width, a.split);
  if (!loaded.ok()) return loaded.status();
  const ModelSource* src = &loaded->source;
  Expected<model::Background> background = model_background(*src, a.background);
  if (!background.ok()) return background.status();
  const model::HybridModel* model = &loaded->model;
  const std::unique_ptr<LoadedDataset>* data = &loaded->data;
  GS_RETURN_IF_ERROR(check_output_outside_dataset(a.out, src->dataset));
  Expected<std::vector<std::string>> pngs = model::render_png_paths(a.out, (*data)->views);
  if (!pngs.ok()) return pngs.status();

  // A failure removes what this run wrote: the whole folder when it made it, else the PNGs of its
  // views (those it would have replaced), so no mix of old and new renders remains.
  const bool out_existed = platform::is_directory(a.out);
  OutputGuard guard(a.out, !out_existed);
  for (const std::string& png : *pngs) guard.add(png);
  platform::ThreadPool pool(a.threads);
  model::EvalOptions eo;
  eo.render_dir = a.out;
  std::copy(background->rgb, background->rgb + 3, eo.render.background);
  eo.render.fixed_point_raster = a.fixed_point;
  if (a.fixed_point) eo.render.int8_mlp = loaded->compact.get();  // int8 MLPs when the file is compact
  Expected<model::EvalResult> r = evaluate_loaded(*loaded, (*data)->views, eo, &pool);
  if (!r.ok()) return r.status();

  RenderRunSummary s;
  s.from_model = true;
  nlohmann::json jv = nlohmann::json::array();
  std::vector<double> times;
  for (size_t i = 0; i < r->views.size(); ++i) {
    const model::ViewMetrics& m = r->views[i];
    const io::DatasetView& v = *(*data)->views[i];
    RenderedView rv;
    rv.name = m.name;
    rv.png = fs::path((*pngs)[i]).lexically_relative(a.out).generic_string();
    rv.is_test = v.is_test;
    rv.width = v.camera.intr.width;
    rv.height = v.camera.intr.height;
    rv.ms = m.render_ms;
    rv.psnr = m.psnr;
    rv.ssim = m.ssim;
    rv.gaussians = m.gaussians;
    times.push_back(m.render_ms);
    nlohmann::json view = view_json(rv);
    view["ssim"] = m.ssim;
    view["gaussians"] = m.gaussians;
    jv.push_back(std::move(view));
    s.views.push_back(rv);
    if (progress) progress(s.views.back(), i + 1, r->views.size());
  }
  nlohmann::json j;
  j["model"] = absolute_path(src->model_path);
  j["dataset"] = absolute_path(src->dataset);
  j["split"] = a.split;
  j["max_width"] = src->max_width;
  j["anchors"] = model->anchor_count;
  j["threads"] = pool.num_threads();
  j["psnr_definition"] = "10*log10(255^2/MSE) over 8-bit RGB; null if identical";
  j["views"] = std::move(jv);
  j["summary"] = {{"views", r->views.size()},
                  {"median_ms", median(times)},
                  {"mean_ms", mean(times)},
                  {"mean_psnr_db", r->psnr},
                  {"mean_ssim", r->ssim},
                  {"total_seconds", platform::now_seconds() - t0}};
  const fs::path json_path = fs::path(a.out) / "render.json";
  GS_RETURN_IF_ERROR(platform::write_file_atomic(json_path.string(), j.dump(2) + "\n"));
  guard.commit();
  s.dataset = src->dataset;
  s.source = src->model_path;
  s.json_path = json_path.string();
  s.anchors = model->anchor_count;
  s.threads = pool.num_threads();
  s.median_ms = median(times);
  s.mean_ms = mean(times);
  s.mean_psnr = r->psnr;
  s.mean_ssim = r->ssim;
  s.total_seconds = platform::now_seconds() - t0;
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

// A dataset's views with the Gaussians to render them with (a splat file or its SfM points), and
// the renderer plan's bounds: everything render_run checks before it writes anything.
struct SplatScene {
  std::unique_ptr<LoadedDataset> data;
  std::vector<std::string> pngs;  // [views] output paths
  const simd::KernelTable* kernels = nullptr;
  float background[3] = {0, 0, 0};
  GaussianCloud cloud;
  std::string source;  // the splat file, or "sfm points"
  std::vector<float> opacity_storage;
  GaussianParams params;  // activated cloud (points into cloud and opacity_storage)
  int max_w = 0, max_h = 0;
  double load_seconds = 0;
};

// 1. Everything that can be wrong with the inputs, checked before anything is written.
Status load_splat_scene(const RenderRunOptions& a, SplatScene* scene) {
  GS_RETURN_IF_ERROR(check_dataset_path(a.input));
  scene->kernels = a.isa.empty() ? &simd::best_kernel_table() : simd::kernel_table_by_name(a.isa.c_str());
  if (!scene->kernels)
    return invalid_argument("kernel ISA '" + a.isa + "' is not available in this build on this CPU (available: " +
                            available_isas() + ")");
  Expected<model::Background> parsed_background = model::parse_background(a.background.empty() ? "black" : a.background);
  if (!parsed_background.ok()) return Status(parsed_background.status().code(), "--background: " + parsed_background.status().message());
  if (parsed_background->random) return invalid_argument("--background random is for training; give a colour to render with");
  std::copy(parsed_background->rgb, parsed_background->rgb + 3, scene->background);
  GS_RETURN_IF_ERROR(check_output_outside_dataset(a.out, a.input));

  const double load_t0 = platform::now_seconds();
  Expected<std::unique_ptr<LoadedDataset>> loaded_dataset = load_dataset_split(a.input, std::max(0, a.max_width), a.split);
  if (!loaded_dataset.ok()) return loaded_dataset.status();
  scene->data = std::move(loaded_dataset).value();
  const io::Dataset* dataset = &scene->data->dataset;
  const std::vector<const io::DatasetView*>& views = scene->data->views;
  Expected<std::vector<std::string>> pngs = model::render_png_paths(a.out, views);
  if (!pngs.ok()) return pngs.status();
  scene->pngs = std::move(pngs).value();

  if (!a.ply.empty()) {
    Expected<GaussianCloud> loaded = io::read_gaussians(a.ply);
    if (!loaded.ok()) return loaded.status();
    scene->cloud = std::move(loaded).value();
    cloud_to_frame(dataset->frame, &scene->cloud);  // the file is in the user's frame, the cameras in the scene frame
    scene->source = a.ply;
  } else {
    const size_t n = dataset->points_xyz.size() / 3;
    if (n == 0) return invalid_argument(a.input + ": the dataset has no SfM points; pass --ply FILE");
    scene->cloud = gaussians_from_points(dataset->points_xyz.data(), dataset->points_rgb.data(), n);
    scene->source = "sfm points";
  }
  if (scene->cloud.size() == 0) return invalid_argument(scene->source + ": no Gaussians to render");
  scene->params = activate(scene->cloud, &scene->opacity_storage);
  if (Status st = validate_gaussians(scene->params); !st.ok()) return Status(st.code(), scene->source + ": " + st.message());

  for (const io::DatasetView* v : views) {
    if (Status st = validate_camera(v->camera); !st.ok())
      return Status(st.code(), a.input + ": view " + v->name + ": " + st.message());
    scene->max_w = std::max(scene->max_w, v->camera.intr.width);
    scene->max_h = std::max(scene->max_h, v->camera.intr.height);
  }
  scene->load_seconds = platform::now_seconds() - load_t0;
  return Status::Ok();
}

// 2. The renderer planned once: each Gaussian covers at most every tile of the largest view, so
// N * tiles is a hard bound; the usual 16 per Gaussian is far below it for real scenes.
struct SplatRenderer {
  Renderer renderer;
  RenderCapacity cap;
  size_t isect_bound = 0;
  size_t reinits = 0;  // plans grown for a view with more Gaussian-tile pairs than planned
};
Status plan_splat_renderer(const SplatScene& scene, platform::ThreadPool* pool, SplatRenderer* r) {
  const size_t n = scene.cloud.size();
  const size_t tiles = size_t((scene.max_w + simd::kTileSize - 1) / simd::kTileSize) *
                       size_t((scene.max_h + simd::kTileSize - 1) / simd::kTileSize);
  r->isect_bound = n * tiles;
  r->cap.max_gaussians = n;
  r->cap.max_isects = std::min(r->isect_bound, std::max<size_t>(16 * n, tiles));
  r->cap.max_width = scene.max_w;
  r->cap.max_height = scene.max_h;
  r->cap.max_sh_degree = scene.cloud.sh_degree;
  return r->renderer.init(r->cap, pool, scene.kernels);
}

// Renders one view into rgb, growing the plan (rare, so it happens here instead of
// over-allocating for every view) and rendering again when the view needs more Gaussian-tile pairs.
Status render_splat_view(const SplatScene& scene, const io::DatasetView& v, const RenderOptions& ropt, platform::ThreadPool* pool,
                         SplatRenderer* r, float* rgb, double* ms) {
  for (;;) {
    const double f0 = platform::now_seconds();
    Status st = r->renderer.forward(v.camera, scene.params, ropt, rgb);
    *ms = 1e3 * (platform::now_seconds() - f0);
    if (st.ok()) return Status::Ok();
    const size_t needed = r->renderer.stats().isects;
    if (st.code() != StatusCode::kCapacityExceeded || needed <= r->cap.max_isects || r->cap.max_isects >= r->isect_bound)
      return Status(st.code(), "view " + v.name + ": " + st.message());
    while (r->cap.max_isects < needed) r->cap.max_isects = std::min(r->isect_bound, 2 * r->cap.max_isects);
    if (Status re = r->renderer.init(r->cap, pool, scene.kernels); !re.ok())
      return Status(re.code(), "view " + v.name + ": " + re.message());
    ++r->reinits;
  }
}

// 4. render.json of a splat render.
nlohmann::json splat_render_json(const RenderRunOptions& a, const SplatScene& scene, const SplatRenderer& r, int threads,
                                 const std::vector<RenderedView>& results, const std::vector<size_t>& isects,
                                 double median_ms, double mean_ms, double mean_psnr, double total_seconds) {
  auto number_or_null = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["dataset"] = a.input;
  j["gaussians_source"] = a.ply.empty() ? nlohmann::json("sfm_points") : nlohmann::json(a.ply);
  j["gaussians"] = scene.cloud.size();
  j["sh_degree"] = scene.cloud.sh_degree;
  j["isa"] = r.renderer.isa();
  j["threads"] = threads;
  j["split"] = a.split;
  j["max_width"] = std::max(0, a.max_width);
  j["background"] = {scene.background[0], scene.background[1], scene.background[2]};
  j["max_isects"] = r.cap.max_isects;
  j["capacity_reinits"] = r.reinits;
  j["psnr_definition"] = "10*log10(255^2/MSE) over 8-bit RGB; null if identical";
  nlohmann::json jv = nlohmann::json::array();
  for (size_t i = 0; i < results.size(); ++i) {
    const RenderedView& rv = results[i];
    nlohmann::json view = view_json(rv);
    view["visible"] = rv.gaussians;
    view["isects"] = isects[i];
    jv.push_back(std::move(view));
  }
  j["views"] = std::move(jv);
  j["summary"] = {{"views", results.size()},
                  {"median_ms", median_ms},
                  {"mean_ms", mean_ms},
                  {"mean_psnr_db", number_or_null(mean_psnr)},
                  {"load_seconds", scene.load_seconds},
                  {"total_seconds", total_seconds}};
  return j;
}

// A dataset's views with Gaussians from a splat file or its SfM points, through gs::Renderer.
Status render_splats(const RenderRunOptions& a, const std::function<void(const RenderedView&, size_t, size_t)>& progress,
                     RenderRunSummary* summary) {
  const double t0 = platform::now_seconds();
  SplatScene scene;
  GS_RETURN_IF_ERROR(load_splat_scene(a, &scene));
  const std::vector<const io::DatasetView*>& views = scene.data->views;
  platform::ThreadPool pool(a.threads);
  SplatRenderer r;
  GS_RETURN_IF_ERROR(plan_splat_renderer(scene, &pool, &r));
  RenderOptions ropt;
  ropt.fixed_point = a.fixed_point;
  for (int k = 0; k < 3; ++k) ropt.background[k] = scene.background[k];
  ropt.validate_inputs = false;  // validated once above; the timings measure rendering only
  std::vector<float> rgb(size_t(scene.max_w) * size_t(scene.max_h) * 3);

  // 3. Render, write, compare.
  const fs::path out_dir(a.out);
  const bool out_existed = platform::is_directory(a.out);
  GS_RETURN_IF_ERROR(platform::make_dirs(a.out));
  OutputGuard guard(out_dir, !out_existed);
  std::vector<RenderedView> results;
  results.reserve(views.size());
  std::vector<size_t> isects;
  for (size_t i = 0; i < views.size(); ++i) {
    const io::DatasetView& v = *views[i];
    double ms = 0;
    GS_RETURN_IF_ERROR(render_splat_view(scene, v, ropt, &pool, &r, rgb.data(), &ms));
    const int w = v.camera.intr.width, h = v.camera.intr.height;
    const io::Image8 img = io::image_from_float_rgb(rgb.data(), w, h);
    const fs::path png = scene.pngs[i], rel = png.lexically_relative(out_dir);
    if (png.has_parent_path() && png.parent_path() != out_dir)
      GS_RETURN_IF_ERROR(platform::make_dirs(png.parent_path().string()));
    GS_RETURN_IF_ERROR(io::write_png(png.string(), img));
    guard.add(png);

    RenderedView rv;
    rv.name = v.name;
    rv.png = rel.generic_string();
    rv.is_test = v.is_test;
    rv.width = w;
    rv.height = h;
    rv.ms = ms;
    rv.psnr = view_psnr(img, v);
    rv.gaussians = r.renderer.stats().visible;
    isects.push_back(r.renderer.stats().isects);
    results.push_back(std::move(rv));
    if (progress) progress(results.back(), i + 1, views.size());
  }

  // 4. Summary: render.json (atomic).
  std::vector<double> times, psnrs;
  for (const RenderedView& rv : results) {
    times.push_back(rv.ms);
    if (std::isfinite(rv.psnr)) psnrs.push_back(rv.psnr);
  }
  const double median_ms = median(times), mean_ms = mean(times);
  const double mean_psnr = psnrs.empty() ? std::numeric_limits<double>::quiet_NaN() : mean(psnrs);
  const nlohmann::json j = splat_render_json(a, scene, r, pool.num_threads(), results, isects, median_ms, mean_ms, mean_psnr,
                                             platform::now_seconds() - t0);
  const fs::path json_path = out_dir / "render.json";
  GS_RETURN_IF_ERROR(platform::write_file_atomic(json_path.string(), j.dump(2) + "\n"));
  guard.commit();

  RenderRunSummary s;
  s.dataset = a.input;
  s.source = a.ply.empty() ? "sfm points" : a.ply;
  s.isa = r.renderer.isa();
  s.json_path = json_path.string();
  s.views = std::move(results);
  s.gaussians = scene.cloud.size();
  s.max_width = scene.max_w;
  s.max_height = scene.max_h;
  s.threads = pool.num_threads();
  s.median_ms = median_ms;
  s.mean_ms = mean_ms;
  s.mean_psnr = mean_psnr;
  s.load_seconds = scene.load_seconds;
  s.total_seconds = platform::now_seconds() - t0;
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace

Status render_run(const RenderRunOptions& a, const std::function<void(const RenderedView&, size_t, size_t)>& progress,
                  RenderRunSummary* summary) {
  if (a.split != "all" && a.split != "train" && a.split != "test")
    return invalid_argument("--split: '" + a.split + "' is not one of all, train, test");
  if (a.out.empty()) return invalid_argument("no output folder given (--out)");
  if (is_model_input(a.input)) return render_model(a, progress, summary);
  return render_splats(a, progress, summary);
}

}  // namespace gs::jobs
