// SPDX-License-Identifier: MIT
// `hbgs eval`: evaluates a trained model (a run folder or a .hbgs file) on its dataset's test
// views: PSNR, SSIM and LPIPS-Alex into results.json / per_view.json, optionally with renders.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "common.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "model_run.h"

namespace hbgs::cli {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::string input, dataset, out, lpips_weights, method = "ours", split = "test";
  int max_width = -1;
  int threads = 0;
  bool renders = false, quiet = false;
};

int run_eval(const EvalArgs& a) {
  const char* cmd = "eval";
  if (!gs::platform::file_exists(a.input)) return fail(cmd, a.input + " not found");
  if (!is_model_input(a.input))
    return fail(cmd, a.input + " is neither a run folder (with run.json or model.hbgs) nor a .hbgs model file");
  gs::Expected<ModelSource> src = resolve_model_source(a.input, a.dataset, a.max_width);
  if (!src.ok()) return fail(cmd, src.status().to_string());
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(src->model_path);
  if (!model.ok()) return fail(cmd, model.status().to_string());
  gs::Expected<std::unique_ptr<LoadedDataset>> data = load_dataset_split(src->dataset, src->max_width, a.split);
  if (!data.ok()) return fail(cmd, data.status().to_string());
  gs::Expected<std::unique_ptr<gs::metrics::LpipsAlex>> lpips = load_lpips(a.lpips_weights, a.threads, a.quiet);
  if (!lpips.ok()) return fail(cmd, lpips.status().to_string());

  const std::string out = a.out.empty() ? (fs::path(src->run_dir) / "eval").string() : a.out;
  gs::platform::ThreadPool pool(a.threads);
  gs::model::EvalOptions eo;
  eo.lpips = lpips->get();
  if (a.renders) eo.render_dir = (fs::path(out) / a.split / a.method / "renders").string();
  Stopwatch time;
  gs::Expected<gs::model::EvalResult> r = gs::model::evaluate_views(*model, (*data)->views, eo, &pool);
  if (!r.ok()) return fail(cmd, r.status().to_string());
  double gaussians = 0;
  for (const gs::model::ViewMetrics& v : r->views) gaussians += double(v.gaussians);
  nlohmann::json extra = {{"model", absolute_path(src->model_path)},
                          {"dataset", absolute_path(src->dataset)},
                          {"split", a.split},
                          {"views", r->views.size()},
                          {"model_bytes", model->file_bytes()},
                          {"model_file_bytes", file_size_or_zero(src->model_path)},
                          {"anchors", model->anchor_count},
                          {"mean_gaussians_per_view", gaussians / double(r->views.size())},
                          {"render_ms_median", r->render_ms_median},
                          {"image_features", gs::model::image_feature_mode_name(model->config.image_features)}};
  if (eo.lpips) extra["lpips_backbone"] = gs::metrics::LpipsAlex::kLabel;
  if (gs::Status st = write_eval_files(out, a.method, *r, json_members(extra.dump())); !st.ok())
    return fail(cmd, st.to_string());

  std::printf("hbgs eval: %s on %zu %s views of %s (%.1f s)\n", src->model_path.c_str(), r->views.size(), a.split.c_str(),
              src->dataset.c_str(), time.seconds());
  std::printf("  PSNR %.2f dB, SSIM %.4f", r->psnr, r->ssim);
  if (r->lpips >= 0) std::printf(", %s %.4f", gs::metrics::LpipsAlex::kLabel, r->lpips);
  std::printf("; %zu anchors, %.0f Gaussians per view, render median %.1f ms\n", model->anchor_count,
              gaussians / double(r->views.size()), r->render_ms_median);
  std::printf("  results: %s/%s, %s/%s%s\n", out.c_str(), kResultsJson, out.c_str(), kPerViewJson,
              a.renders ? (", renders in " + eo.render_dir + "/").c_str() : "");
  return kExitOk;
}

}  // namespace

Command add_eval_command(CLI::App& parent) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* sub = parent.add_subcommand("eval", "Evaluate a trained model on its dataset's test views (PSNR, SSIM, LPIPS-Alex)");
  sub->add_option("model", args->input, "Run folder (from hbgs train) or .hbgs model file")->required();
  sub->add_option("--dataset", args->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--out", args->out, "Folder for results.json and per_view.json (default: <run>/eval)");
  sub->add_option("--max-width", args->max_width, "Downscale views to at most this width (default: as trained)")
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--split", args->split, "Views to evaluate")->capture_default_str()->check(CLI::IsMember({"test", "train", "all"}));
  sub->add_option("--method", args->method, "Method key in the JSON files")->capture_default_str();
  sub->add_option("--lpips-weights", args->lpips_weights, "LPIPS-Alex weights folder (default: ../shared/data/lpips_alex if present)");
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_flag("--renders", args->renders, "Also write the renders to <out>/<split>/<method>/renders/");
  sub->add_flag("-q,--quiet", args->quiet, "Only the summary");
  return {sub, [args] { return run_eval(*args); }};
}

}  // namespace hbgs::cli
