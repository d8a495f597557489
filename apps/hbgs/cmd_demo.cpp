// SPDX-License-Identifier: MIT
// `hbgs demo`: the whole pipeline in a few minutes: generates the built-in ray-traced scene (as
// `hbgs synth`), trains on it (as `hbgs train`), evaluates the test views and writes report.md and
// the report page report.html (as `hbgs report`).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "common.h"
#include "gs/metrics/lpips.h"
#include "gs/platform/file.h"
#include "gs/jobs/train.h"

#ifdef HBGS_HAVE_SYNTH
#include "hbgs/synth.h"
#endif

namespace hbgs::cli {
namespace {

namespace fs = std::filesystem;

// About a minute on two cores for the whole demo (2026-12-07, a 2-core AMD EPYC VM with AVX-512: 53 s,
// of which 44 s train the 3,000 iterations; 7 offsets per anchor, half resolution for the first half).
constexpr int kDemoIterations = 3000;

struct DemoArgs {
  std::string out = "out/demo";
  int iterations = kDemoIterations;
  int threads = 0;
  std::string lpips_weights;
  bool quiet = false;
};

#ifdef HBGS_HAVE_SYNTH

std::string fixed(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string report_markdown(const gs::jobs::TrainRunSummary& s, const std::string& scene, double total_seconds, bool page) {
  const gs::model::EvalResult& e = s.final_eval;
  const std::string method = "ours_" + std::to_string(s.iterations);
  std::string md = "# hbgs demo\n\n";
  md += "The built-in ray-traced scene (`scene/`, a COLMAP dataset) trained for " + std::to_string(s.iterations) +
        " iterations on " + std::to_string(s.train_views) + " views and evaluated on " + std::to_string(s.test_views) +
        " held-out views (every 8th by name). Image features: " + s.image_features + "; kernels " + s.isa + ", " +
        std::to_string(s.threads) + " threads.\n\n";
  md += "| figure | value |\n|---|---|\n";
  md += "| test PSNR | " + fixed("%.2f dB", e.psnr) + " |\n";
  md += "| test SSIM | " + fixed("%.4f", e.ssim) + " |\n";
  md += std::string("| test ") + gs::metrics::LpipsAlex::kLabel + " | " +
        (e.lpips >= 0 ? fixed("%.4f", e.lpips) : std::string("not computed (no weights)")) + " |\n";
  md += "| training time (evaluation excluded) | " + fixed("%.1f s", s.train_seconds) + " |\n";
  md += "| median iteration | " + fixed("%.1f ms", s.median_iteration_ms) + " |\n";
  md += "| model file | " + fixed("%.2f MB", double(s.model_file_bytes) / 1e6) + " |\n";
  md += "| anchors | " + std::to_string(s.anchors) + " |\n";
  md += "| neural Gaussians per test view | " + fixed("%.0f", s.mean_gaussians) + " |\n";
  md += "| test render (median) | " + fixed("%.1f ms", e.render_ms_median) + " |\n";
  md += "| whole demo | " + fixed("%.1f s", total_seconds) + " |\n\n";
  md += "![test PSNR against training time](run/psnr_vs_time.svg)\n\n";
  if (page)
    md += "`report.html` is the report page: these figures, the plot, the test renders beside the ground truth and a 3D "
          "viewer of the model (WebGL; open it in a browser, it works offline).\n\n";
  md += "Files: `run/model.hbgs` (the model), `run/results.json` and `run/per_view.json` (3DGS schema, method `" +
        method + "`), `run/test/" + method + "/renders/` (test renders), `run/psnr_vs_time.csv`, `run/checkpoint.bin`.\n\n";
  md += "Again by hand, from this folder:\n\n```sh\nhbgs eval run            # results into run/eval/\nhbgs render run --out renders --split all\n"
        "hbgs train " + scene + " --out run --iterations " + std::to_string(2 * s.iterations) +
        " --resume   # train further\n```\n";
  return md;
}

// The report page (hbgs report) beside report.md: about 20 s for the built-in scene on two cores,
// mostly the bake's distillation. One call, so that the demo can drop it. A failure is reported
// and the demo goes on (the page is an extra; report.md has the figures).
int write_report_page(const fs::path& root, int threads) {
  gs::jobs::ReportRunOptions r;
  r.run = (root / "run").string();
  r.out = (root / "report.html").string();
  r.threads = threads;
  std::printf("\n");
  return run_report(r);
}

int run_demo(const DemoArgs& a) {
  const char* cmd = "demo";
  Stopwatch total;
  const fs::path root(a.out), scene = root / "scene";
  std::error_code ec;
  if (fs::exists(root, ec) && !fs::is_directory(root, ec)) return fail(cmd, a.out + " exists and is not a directory");
  if (fs::exists(scene / "sparse" / "0" / "cameras.txt", ec) && fs::is_directory(scene / "images", ec)) {
    std::printf("hbgs demo: reusing the scene in %s (delete it to generate it again)\n", scene.string().c_str());
  } else {
    hbgs::synth::SynthOptions o;
    o.threads = a.threads;
    o.verbose = !a.quiet;
    gs::Expected<hbgs::synth::SynthSummary> made = hbgs::synth::generate_scene(o, scene.string());
    if (!made.ok()) return fail(cmd, made.status().to_string());
    std::printf("hbgs demo: generated the scene in %s: %d views of %dx%d, %d points, %.1f s\n", scene.string().c_str(),
                made->num_views, o.width, o.height, made->num_points, made->seconds);
  }
  std::fflush(stdout);

  gs::jobs::TrainRunOptions t;
  t.dataset = scene.string();
  t.out = (root / "run").string();
  t.iterations = a.iterations;
  t.threads = a.threads;
  t.force = true;
  t.save_at = "";
  t.eval_every = std::max(50, a.iterations / 20);
  t.checkpoint_every = 0;
  t.lpips_weights = a.lpips_weights;
  gs::jobs::TrainRunSummary s;
  if (int rc = run_train(t, a.quiet, &s); rc != kExitOk) return rc;

  const bool page_written = write_report_page(root, a.threads) == kExitOk;
  const std::string report = (root / "report.md").string();
  if (gs::Status st = gs::platform::write_file_atomic(report, report_markdown(s, "scene", total.seconds(), page_written)); !st.ok())
    return fail(cmd, st.to_string());
  std::printf("\nhbgs demo: done in %.1f s\n", total.seconds());
  std::printf("  test PSNR %.2f dB, SSIM %.4f, %s %s\n", s.final_eval.psnr, s.final_eval.ssim,
              gs::metrics::LpipsAlex::kLabel,
              s.final_eval.lpips >= 0 ? fixed("%.4f", s.final_eval.lpips).c_str() : "not computed (no weights)");
  std::printf("  training %.1f s for %d iterations, model %.2f MB, %zu anchors\n", s.train_seconds, s.iterations,
              double(s.model_file_bytes) / 1e6, s.anchors);
  std::printf("  report: %s  (renders: %s/run/test/ours_%d/renders/, plot: %s/run/psnr_vs_time.svg)\n",
              report.c_str(), a.out.c_str(), s.iterations, a.out.c_str());
  if (page_written) std::printf("  report page: %s (open it in a browser: works offline)\n", (root / "report.html").string().c_str());
  return kExitOk;
}

#else

int run_demo(const DemoArgs&) { return fail("demo", "hbgs was built without Embree; the demo scene is unavailable"); }

#endif

}  // namespace

Command add_demo_command(CLI::App& parent) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* sub = parent.add_subcommand("demo", "Generate the built-in scene, train on it, evaluate and write report.md and report.html");
  sub->add_option("--out", args->out, "Demo folder (scene/, run/, report.md, report.html)")->capture_default_str();
  sub->add_option("--iterations", args->iterations, "Training iterations")->capture_default_str()->check(CLI::Range(1, 100000000));
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--lpips-weights", args->lpips_weights, "LPIPS-Alex weights folder (default: ../shared/data/lpips_alex if present)");
  sub->add_flag("-q,--quiet", args->quiet, "No progress output, only the summary");
  return {sub, [args] { return run_demo(*args); }};
}

}  // namespace hbgs::cli
