// SPDX-License-Identifier: MIT
// `hbgs eval`: evaluates a trained model (a run folder or a .hbgs file) on its dataset's test
// views: PSNR, SSIM and LPIPS-Alex into results.json / per_view.json, optionally with renders.
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/image.h"
#include "gs/jobs/evaluate.h"

namespace hbgs::cli {
namespace {

struct EvalCli {
  gs::jobs::EvaluateRunOptions options;
  bool quiet = false;
};

int run_eval(const EvalCli& cli) {
  const gs::jobs::EvaluateRunOptions& a = cli.options;
  gs::jobs::EvaluateRunSummary s;
  if (gs::Status st = gs::jobs::evaluate_run(a, &s); !st.ok())
    return fail("eval", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  if (!cli.quiet && !s.note.empty()) std::fprintf(stderr, "note: %s\n", s.note.c_str());
  const gs::model::EvalResult& r = s.result;
  std::printf("hbgs eval: %s on %zu %s views of %s (%.1f s)\n", s.source.model_path.c_str(), r.views.size(), a.split.c_str(),
              s.source.dataset.c_str(), s.seconds);
  std::printf("  PSNR %.2f dB, SSIM %.4f", r.psnr, r.ssim);
  if (r.lpips >= 0) std::printf(", %s %.4f", gs::metrics::LpipsAlex::kLabel, r.lpips);
  std::printf("; %zu anchors, %.0f Gaussians per view, render median %.1f ms\n", s.anchors, s.mean_gaussians, r.render_ms_median);
  std::printf("  results: %s/%s, %s/%s%s\n", s.out_dir.c_str(), gs::jobs::kResultsJson, s.out_dir.c_str(), gs::jobs::kPerViewJson,
              a.renders ? (", renders in " + s.render_dir + "/").c_str() : "");
  return kExitOk;
}

}  // namespace

Command add_eval_command(CLI::App& parent) {
  auto args = std::make_shared<EvalCli>();
  gs::jobs::EvaluateRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand("eval", "Evaluate a trained model on its dataset's test views (PSNR, SSIM, LPIPS-Alex)");
  sub->add_option("model", o->input, "Run folder (from hbgs train), .hbgs model file or .hbgc compact model file")->required();
  sub->add_option("--dataset", o->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--out", o->out, "Folder for results.json and per_view.json (default: <run>/eval)");
  sub->add_option("--max-width", o->max_width, "Downscale views to at most this width (default: as trained)")
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--fisheye-fov", o->fisheye_fov,
                  "Fisheye cameras' pinhole field of view, degrees (default: as trained; 0: automatic, see hbgs train)")
      ->check(CLI::Range(0.0, 170.0));
  sub->add_option("--split", o->split, "Views to evaluate")->capture_default_str()->check(CLI::IsMember({"test", "train", "all"}));
  sub->add_option("--method", o->method, "Method key in the JSON files")->capture_default_str();
  sub->add_option("--lpips-weights", o->lpips_weights, "LPIPS-Alex weights folder (default: ../shared/data/lpips_alex if present)");
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_flag("--renders", o->renders, "Also write the renders to <out>/<split>/<method>/renders/");
  sub->add_option("--background", o->background,
                  "Background to render on and composite masked views on: black, white or r,g,b (default: the run's "
                  "training background)")
      ->check(background_validator());
  sub->add_flag("--composite-renders", o->composite_renders,
                "Composite each render through its view's mask on the background before the metrics, as the photo is "
                "(a model trained on the whole photos, judged inside the masks of a masked dataset given by --dataset)");
  sub->add_flag("--fixed-point", o->fixed_point, "Render with the on-device fixed-point blending (int16 tile kernel)");
  sub->add_flag("-q,--quiet", args->quiet, "Only the summary");
  return {sub, [args] { return run_eval(*args); }};
}

}  // namespace hbgs::cli
