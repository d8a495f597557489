// SPDX-License-Identifier: MIT
// `hbgs render`: renders every selected view of a COLMAP dataset with gs::Renderer (Gaussians from
// a 3DGS PLY, or initialised from the dataset's SfM points), or of a trained model's dataset (a run
// folder or .hbgs file) with the model, and writes one PNG per view plus render.json with per-view
// timing and PSNR against the dataset's images.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "common.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/ply.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/scene_init.h"
#include "gs/simd/kernel_table.h"
#include "gs/jobs/run_folder.h"

namespace hbgs::cli {

using namespace gs::jobs;  // run folders and pose truth
namespace {

namespace fs = std::filesystem;

struct RenderArgs {
  std::string dataset, ply, out;
  std::string model_dataset;  // with a model input: overrides the dataset recorded in run.json
  int max_width = 0;
  bool max_width_given = false;
  int threads = 0;
  std::string isa;  // empty: the best table for this CPU
  std::string split = "all";
  std::string background = "0,0,0";
  bool quiet = false;
};

// Parses "r,g,b" with each component in [0, 1]; returns an error text or "".
std::string parse_background(const std::string& text, float rgb[3]) {
  std::istringstream in(text);
  std::string part;
  int n = 0;
  while (std::getline(in, part, ',')) {
    if (n == 3) return "expected three comma-separated values r,g,b";
    size_t used = 0;
    float v = 0;
    try {
      v = std::stof(part, &used);
    } catch (const std::exception&) {
      return "'" + part + "' is not a number";
    }
    if (used != part.size() || !std::isfinite(v) || v < 0.f || v > 1.f)
      return "'" + part + "' is not a number in [0, 1]";
    rgb[n++] = v;
  }
  return n == 3 ? "" : "expected three comma-separated values r,g,b";
}

// PSNR of two 8-bit RGB images of the same size, 10 log10(255^2 / MSE); +inf when identical.
double psnr_8bit(const gs::io::Image8& a, const gs::io::Image8& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels || a.pixels.size() != b.pixels.size() ||
      a.pixels.empty())
    return std::numeric_limits<double>::quiet_NaN();
  double sse = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const double d = double(a.pixels[i]) - double(b.pixels[i]);
    sse += d * d;
  }
  const double mse = sse / double(a.pixels.size());
  if (mse == 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::string psnr_text(double psnr, int decimals) {
  if (std::isnan(psnr)) return "n/a";
  if (std::isinf(psnr)) return "inf dB";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f dB", decimals, psnr);
  return buf;
}

std::string available_isas() {
  std::string names = "ref";
  const gs::simd::KernelTable* tables[16];
  const int n = gs::simd::available_simd_kernel_tables(tables, 16);
  for (int i = 0; i < n; ++i) names += std::string(", ") + tables[i]->isa;
  return names;
}

// Output name of a view, relative to the output folder: its image name (which may contain
// sub-folders) with the extension replaced by .png.
fs::path output_name(const std::string& image_name) {
  fs::path rel(image_name);
  rel.replace_extension(".png");
  return rel;
}

// Files this run created, removed again if the run fails part-way so no partial output remains.
class OutputGuard {
 public:
  explicit OutputGuard(fs::path dir, bool created_dir) : dir_(std::move(dir)), created_dir_(created_dir) {}
  ~OutputGuard() {
    if (committed_) return;
    std::error_code ec;
    for (const fs::path& p : files_) fs::remove(p, ec);
    if (created_dir_) fs::remove(dir_, ec);  // only if empty
  }
  void add(const fs::path& p) { files_.push_back(p); }
  void commit() { committed_ = true; }

 private:
  fs::path dir_;
  bool created_dir_;
  bool committed_ = false;
  std::vector<fs::path> files_;
};

struct ViewResult {
  std::string name, png;
  bool is_test = false;
  int width = 0, height = 0;
  double ms = 0;
  double psnr = 0;
  size_t visible = 0, isects = 0;
};

// Refuses an --out that is a file or the dataset's own images folder (PNGs would replace it).
std::string output_problem(const std::string& out, const std::string& dataset) {
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) return "output " + out + " exists and is not a directory";
  const fs::path images = fs::path(dataset) / "images";
  if (fs::exists(out, ec) && fs::exists(images, ec) && fs::equivalent(out, images, ec))
    return "output " + out + " is the dataset's images folder; choose another --out";
  return "";
}

// A run folder or .hbgs file: the model's views of its dataset, through gs::model::evaluate_views.
int run_render_model(const RenderArgs& a) {
  const char* cmd = "render";
  Stopwatch total;
  if (!a.ply.empty()) return fail(cmd, "--ply cannot be combined with a trained model (" + a.dataset + ")");
  if (!a.isa.empty()) return fail(cmd, "--isa applies to PLY / SfM-point rendering, not to a trained model");
  if (a.background != "0,0,0") return fail(cmd, "--background is not supported for a trained model");
  gs::Expected<ModelSource> src = resolve_model_source(a.dataset, a.model_dataset, a.max_width_given ? a.max_width : -1);
  if (!src.ok()) return fail(cmd, src.status().to_string());
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(src->model_path);
  if (!model.ok()) return fail(cmd, model.status().to_string());
  gs::Expected<std::unique_ptr<LoadedDataset>> data = load_dataset_split(src->dataset, src->max_width, a.split);
  if (!data.ok()) return fail(cmd, data.status().to_string());
  if (std::string err = output_problem(a.out, src->dataset); !err.empty()) return fail(cmd, err);

  const bool out_existed = gs::platform::is_directory(a.out);
  gs::platform::ThreadPool pool(a.threads);
  gs::model::EvalOptions eo;
  eo.render_dir = a.out;
  gs::Expected<gs::model::EvalResult> r = gs::model::evaluate_views(*model, (*data)->views, eo, &pool);
  if (!r.ok()) {
    std::error_code ec;
    if (!out_existed) fs::remove_all(a.out, ec);
    return fail(cmd, r.status().to_string());
  }

  nlohmann::json jv = nlohmann::json::array();
  std::vector<double> times;
  for (size_t i = 0; i < r->views.size(); ++i) {
    const gs::model::ViewMetrics& m = r->views[i];
    const gs::io::DatasetView& v = *(*data)->views[i];
    const std::string png = output_name(m.name).generic_string();
    times.push_back(m.render_ms);
    if (!a.quiet)
      std::fprintf(stderr, "[%zu/%zu] %s %.1f ms PSNR %s\n", i + 1, r->views.size(), png.c_str(), m.render_ms,
                   psnr_text(m.psnr, 1).c_str());
    jv.push_back({{"name", m.name},
                  {"png", png},
                  {"split", v.is_test ? "test" : "train"},
                  {"width", v.camera.intr.width},
                  {"height", v.camera.intr.height},
                  {"ms", m.render_ms},
                  {"psnr_db", std::isfinite(m.psnr) ? nlohmann::json(m.psnr) : nlohmann::json(nullptr)},
                  {"ssim", m.ssim},
                  {"gaussians", m.gaussians}});
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
                  {"median_ms", gs::median(times)},
                  {"mean_ms", mean_of(times)},
                  {"mean_psnr_db", r->psnr},
                  {"mean_ssim", r->ssim},
                  {"total_seconds", total.seconds()}};
  const fs::path json_path = fs::path(a.out) / "render.json";
  if (gs::Status st = gs::platform::write_file_atomic(json_path.string(), j.dump(2) + "\n"); !st.ok())
    return fail(cmd, st.to_string());
  std::printf("hbgs render: %zu views (split %s) of %s from the model %s (%zu anchors)\n", r->views.size(),
              a.split.c_str(), src->dataset.c_str(), src->model_path.c_str(), model->anchor_count);
  std::printf("  render: median %.2f ms, mean %.2f ms per view; %d threads\n", gs::median(times), mean_of(times),
              pool.num_threads());
  std::printf("  PSNR vs dataset images: mean %s, SSIM %.4f\n", psnr_text(r->psnr, 2).c_str(), r->ssim);
  std::printf("  images: %s/  (timings: %s)\n", a.out.c_str(), json_path.string().c_str());
  return kExitOk;
}

int run_render(const RenderArgs& a) {
  const char* cmd = "render";
  if (is_model_input(a.dataset)) return run_render_model(a);
  Stopwatch total;

  // 1. Everything that can be wrong with the inputs is checked before anything is written.
  if (!gs::platform::is_directory(a.dataset)) return fail(cmd, "dataset folder " + a.dataset + " not found");
  const gs::simd::KernelTable* kernels =
      a.isa.empty() ? &gs::simd::best_kernel_table() : gs::simd::kernel_table_by_name(a.isa.c_str());
  if (!kernels)
    return fail(cmd, "kernel ISA '" + a.isa + "' is not available in this build on this CPU (available: " +
                         available_isas() + ")");
  float background[3] = {0, 0, 0};
  if (std::string err = parse_background(a.background, background); !err.empty())
    return fail(cmd, "--background: " + err);
  if (std::string err = output_problem(a.out, a.dataset); !err.empty()) return fail(cmd, err);

  Stopwatch load_time;
  gs::Expected<std::unique_ptr<LoadedDataset>> loaded_dataset = load_dataset_split(a.dataset, a.max_width, a.split);
  if (!loaded_dataset.ok()) return fail(cmd, loaded_dataset.status().to_string());
  const gs::io::Dataset* dataset = &(*loaded_dataset)->dataset;
  const std::vector<const gs::io::DatasetView*>& views = (*loaded_dataset)->views;

  gs::GaussianCloud cloud;
  std::string source;
  if (!a.ply.empty()) {
    gs::Expected<gs::GaussianCloud> loaded = gs::io::read_splat_ply(a.ply);
    if (!loaded.ok()) return fail(cmd, loaded.status().to_string());
    cloud = std::move(loaded).value();
    source = a.ply;
  } else {
    const size_t n = dataset->points_xyz.size() / 3;
    if (n == 0) return fail(cmd, a.dataset + ": the dataset has no SfM points; pass --ply FILE");
    cloud = gs::gaussians_from_points(dataset->points_xyz.data(), dataset->points_rgb.data(), n);
    source = "sfm points";
  }
  if (cloud.size() == 0) return fail(cmd, source + ": no Gaussians to render");
  std::vector<float> opacity_storage;
  const gs::GaussianParams params = gs::activate(cloud, &opacity_storage);
  if (gs::Status st = gs::validate_gaussians(params); !st.ok()) return fail(cmd, source + ": " + st.to_string());

  int max_w = 0, max_h = 0;
  for (const gs::io::DatasetView* v : views) {
    if (gs::Status st = gs::validate_camera(v->camera); !st.ok())
      return fail(cmd, a.dataset + ": view " + v->name + ": " + st.to_string());
    max_w = std::max(max_w, v->camera.intr.width);
    max_h = std::max(max_h, v->camera.intr.height);
  }
  const double load_seconds = load_time.seconds();

  // 2. Plan the renderer once: each Gaussian covers at most every tile of the largest view, so
  // N * tiles is a hard bound; the usual 16 per Gaussian is far below it for real scenes.
  gs::platform::ThreadPool pool(a.threads);
  const size_t n = cloud.size();
  const size_t tiles = size_t((max_w + gs::simd::kTileSize - 1) / gs::simd::kTileSize) *
                       size_t((max_h + gs::simd::kTileSize - 1) / gs::simd::kTileSize);
  const size_t isect_bound = n * tiles;
  gs::RenderCapacity cap;
  cap.max_gaussians = n;
  cap.max_isects = std::min(isect_bound, std::max<size_t>(16 * n, tiles));
  cap.max_width = max_w;
  cap.max_height = max_h;
  cap.max_sh_degree = cloud.sh_degree;
  gs::Renderer renderer;
  if (gs::Status st = renderer.init(cap, &pool, kernels); !st.ok()) return fail(cmd, st.to_string());

  gs::RenderOptions ropt;
  for (int k = 0; k < 3; ++k) ropt.background[k] = background[k];
  ropt.validate_inputs = false;  // validated once above; the timings measure rendering only
  std::vector<float> rgb(size_t(max_w) * size_t(max_h) * 3);

  // 3. Render, write, compare.
  const fs::path out_dir(a.out);
  const bool out_existed = gs::platform::is_directory(a.out);
  if (gs::Status st = gs::platform::make_dirs(a.out); !st.ok()) return fail(cmd, st.to_string());
  OutputGuard guard(out_dir, !out_existed);

  std::vector<ViewResult> results;
  results.reserve(views.size());
  size_t reinits = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    const gs::io::DatasetView& v = *views[i];
    double ms = 0;
    for (;;) {
      Stopwatch frame;
      gs::Status st = renderer.forward(v.camera, params, ropt, rgb.data());
      ms = frame.ms();
      if (st.ok()) break;
      // A view with more Gaussian-tile pairs than planned: grow the plan (rare, so it happens
      // here instead of over-allocating for every view) and render the view again.
      const size_t needed = renderer.stats().isects;
      if (st.code() != gs::StatusCode::kCapacityExceeded || needed <= cap.max_isects || cap.max_isects >= isect_bound)
        return fail(cmd, "view " + v.name + ": " + st.to_string());
      while (cap.max_isects < needed) cap.max_isects = std::min(isect_bound, 2 * cap.max_isects);
      if (gs::Status re = renderer.init(cap, &pool, kernels); !re.ok())
        return fail(cmd, "view " + v.name + ": " + re.to_string());
      ++reinits;
    }
    const int w = v.camera.intr.width, h = v.camera.intr.height;
    const gs::io::Image8 img = gs::io::image_from_float_rgb(rgb.data(), w, h);
    const fs::path rel = output_name(v.name), png = out_dir / rel;
    if (png.has_parent_path() && png.parent_path() != out_dir)
      if (gs::Status st = gs::platform::make_dirs(png.parent_path().string()); !st.ok()) return fail(cmd, st.to_string());
    if (gs::Status st = gs::io::write_png(png.string(), img); !st.ok()) return fail(cmd, st.to_string());
    guard.add(png);

    ViewResult r;
    r.name = v.name;
    r.png = rel.generic_string();
    r.is_test = v.is_test;
    r.width = w;
    r.height = h;
    r.ms = ms;
    r.psnr = psnr_8bit(img, v.image);
    r.visible = renderer.stats().visible;
    r.isects = renderer.stats().isects;
    if (!a.quiet)
      std::fprintf(stderr, "[%zu/%zu] %s %.1f ms PSNR %s\n", i + 1, views.size(), r.png.c_str(), r.ms,
                   psnr_text(r.psnr, 1).c_str());
    results.push_back(std::move(r));
  }

  // 4. Summary: render.json (atomic) and a few lines on stdout.
  std::vector<double> times, psnrs;
  for (const ViewResult& r : results) {
    times.push_back(r.ms);
    if (std::isfinite(r.psnr)) psnrs.push_back(r.psnr);
  }
  const double median_ms = gs::median(times), mean_ms = mean_of(times);
  const double mean_psnr = psnrs.empty() ? std::numeric_limits<double>::quiet_NaN() : mean_of(psnrs);
  auto number_or_null = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };

  nlohmann::json j;
  j["dataset"] = a.dataset;
  j["gaussians_source"] = a.ply.empty() ? nlohmann::json("sfm_points") : nlohmann::json(a.ply);
  j["gaussians"] = n;
  j["sh_degree"] = cloud.sh_degree;
  j["isa"] = renderer.isa();
  j["threads"] = pool.num_threads();
  j["split"] = a.split;
  j["max_width"] = a.max_width;
  j["background"] = {background[0], background[1], background[2]};
  j["max_isects"] = cap.max_isects;
  j["capacity_reinits"] = reinits;
  j["psnr_definition"] = "10*log10(255^2/MSE) over 8-bit RGB; null if identical";
  nlohmann::json jv = nlohmann::json::array();
  for (const ViewResult& r : results)
    jv.push_back({{"name", r.name},
                  {"png", r.png},
                  {"split", r.is_test ? "test" : "train"},
                  {"width", r.width},
                  {"height", r.height},
                  {"ms", r.ms},
                  {"psnr_db", number_or_null(r.psnr)},
                  {"visible", r.visible},
                  {"isects", r.isects}});
  j["views"] = std::move(jv);
  j["summary"] = {{"views", results.size()},
                  {"median_ms", median_ms},
                  {"mean_ms", mean_ms},
                  {"mean_psnr_db", number_or_null(mean_psnr)},
                  {"load_seconds", load_seconds},
                  {"total_seconds", total.seconds()}};
  const fs::path json_path = out_dir / "render.json";
  if (gs::Status st = gs::platform::write_file_atomic(json_path.string(), j.dump(2) + "\n"); !st.ok())
    return fail(cmd, st.to_string());
  guard.commit();

  std::printf("hbgs render: %zu views (split %s), %zu Gaussians (%s), %dx%d max\n", results.size(), a.split.c_str(), n,
              a.ply.empty() ? "from SfM points" : a.ply.c_str(), max_w, max_h);
  std::printf("  render: median %.2f ms, mean %.2f ms per view; ISA %s, %d threads\n", median_ms, mean_ms,
              renderer.isa(), pool.num_threads());
  std::printf("  PSNR vs dataset images: mean %s\n", psnr_text(mean_psnr, 2).c_str());
  std::printf("  load %.2f s, total %.2f s\n", load_seconds, total.seconds());
  std::printf("  images: %s/  (timings: %s)\n", out_dir.string().c_str(), json_path.string().c_str());
  return kExitOk;
}

}  // namespace

Command add_render_command(CLI::App& parent) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* sub = parent.add_subcommand(
      "render", "Render every view of a COLMAP dataset (or of a trained model's dataset) to PNGs, with timings and PSNR");
  sub->add_option("dataset", args->dataset,
                  "COLMAP dataset folder (images/ and sparse/0/), or a run folder / .hbgs model from hbgs train")
      ->required();
  sub->add_option("--dataset", args->model_dataset, "With a trained model: its dataset (default: from the run's run.json)");
  sub->add_option("--ply", args->ply, "3DGS PLY with the Gaussians (default: initialise from the SfM points)");
  sub->add_option("--out", args->out, "Output folder for <image>.png and render.json")->required();
  CLI::Option* max_width = sub->add_option("--max-width", args->max_width,
                                            "Downscale views to at most this width (0: full size; a model: as trained)")
                               ->capture_default_str()
                               ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--isa", args->isa, "Kernel variant (default: the best for this CPU)")
      ->check(CLI::IsMember({"ref", "sse2", "avx2", "avx512", "neon64", "neon"}));
  sub->add_option("--split", args->split, "Views to render (test: every 8th by name, as in 3DGS)")
      ->capture_default_str()
      ->check(CLI::IsMember({"all", "train", "test"}));
  sub->add_option("--background", args->background, "Background colour r,g,b in [0, 1]")
      ->capture_default_str()
      ->check(CLI::Validator(
          [](std::string& s) {
            float rgb[3];
            return parse_background(s, rgb);
          },
          "R,G,B"));
  sub->add_flag("-q,--quiet", args->quiet, "No per-view progress lines");
  return {sub, [args, max_width] {
            args->max_width_given = max_width->count() > 0;
            return run_render(*args);
          }};
}

}  // namespace hbgs::cli
