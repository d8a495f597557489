// SPDX-License-Identifier: MIT
// `hbgs render`: the flags of gs::jobs::render_run (gs/jobs/render.h), its per-view lines and its
// summary: every selected view of a COLMAP dataset (Gaussians from a splat file or the SfM
// points) or of a trained model's dataset to PNGs, with render.json (per-view timing and PSNR).
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/image.h"
#include "gs/jobs/render.h"

namespace hbgs::cli {
namespace {

struct RenderArgs {
  gs::jobs::RenderRunOptions options;
  int max_width = 0;  // --max-width as given (options.max_width is -1 when it is not)
  bool quiet = false;
};

std::string psnr_text(double psnr, int decimals) {
  if (std::isnan(psnr)) return "n/a";
  if (std::isinf(psnr)) return "inf dB";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f dB", decimals, psnr);
  return buf;
}

int run_render(RenderArgs& args) {
  const gs::jobs::RenderRunOptions& a = args.options;
  auto progress = [&](const gs::jobs::RenderedView& v, size_t k, size_t n) {
    if (!args.quiet) std::fprintf(stderr, "[%zu/%zu] %s %.1f ms PSNR %s\n", k, n, v.png.c_str(), v.ms, psnr_text(v.psnr, 1).c_str());
  };
  gs::jobs::RenderRunSummary s;
  if (gs::Status st = gs::jobs::render_run(a, progress, &s); !st.ok())
    return fail("render", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  if (s.from_model) {
    std::printf("hbgs render: %zu views (split %s) of %s from the model %s (%zu anchors)\n", s.views.size(), a.split.c_str(),
                s.dataset.c_str(), s.source.c_str(), s.anchors);
    std::printf("  render: median %.2f ms, mean %.2f ms per view; %d threads\n", s.median_ms, s.mean_ms, s.threads);
    std::printf("  PSNR vs dataset images: mean %s, SSIM %.4f\n", psnr_text(s.mean_psnr, 2).c_str(), s.mean_ssim);
  } else {
    std::printf("hbgs render: %zu views (split %s), %zu Gaussians (%s), %dx%d max\n", s.views.size(), a.split.c_str(),
                s.gaussians, a.ply.empty() ? "from SfM points" : a.ply.c_str(), s.max_width, s.max_height);
    std::printf("  render: median %.2f ms, mean %.2f ms per view; ISA %s, %d threads\n", s.median_ms, s.mean_ms, s.isa.c_str(),
                s.threads);
    std::printf("  PSNR vs dataset images: mean %s\n", psnr_text(s.mean_psnr, 2).c_str());
    std::printf("  load %.2f s, total %.2f s\n", s.load_seconds, s.total_seconds);
  }
  std::printf("  images: %s/  (timings: %s)\n", a.out.c_str(), s.json_path.c_str());
  return kExitOk;
}

}  // namespace

Command add_render_command(CLI::App& parent) {
  auto args = std::make_shared<RenderArgs>();
  gs::jobs::RenderRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand(
      "render", "Render every view of a COLMAP dataset (or of a trained model's dataset) to PNGs, with timings and PSNR");
  sub->add_option("dataset", o->input,
                  "Dataset: a COLMAP folder (images/ and sparse/0/), a NeRF-style folder or transforms .json file, or a run "
                  "folder / .hbgs model from hbgs train")
      ->required();
  sub->add_option("--dataset", o->model_dataset, "With a trained model: its dataset (default: from the run's run.json)");
  sub->add_option("--ply,--gaussians", o->ply,
                  "Splat file with the Gaussians: 3DGS .ply, PlayCanvas .compressed.ply, antimatter15 .splat or Niantic "
                  ".spz (default: initialise from the SfM points)");
  sub->add_option("--out", o->out, "Output folder for <image>.png and render.json")->required();
  CLI::Option* max_width = sub->add_option("--max-width", args->max_width,
                                            "Downscale views to at most this width (0: full size; a model: as trained)")
                               ->capture_default_str()
                               ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--isa", o->isa, "Kernel variant (default: the best for this CPU)")
      ->check(CLI::IsMember({"ref", "sse2", "avx2", "avx512", "neon64", "neon"}));
  sub->add_option("--split", o->split, "Views to render (test: every 8th by name, as in 3DGS)")
      ->capture_default_str()
      ->check(CLI::IsMember({"all", "train", "test"}));
  sub->add_option("--background", o->background,
                  "Background: black, white or r,g,b in [0, 1] (default: black for a dataset, the run's training "
                  "background for a model)")
      ->check(background_validator());
  sub->add_flag("--fixed-point", o->fixed_point, "Blend with the on-device fixed-point kernel (int16; colours clamped to [0, 1])");
  sub->add_flag("-q,--quiet", args->quiet, "No per-view progress lines");
  return {sub, [args, max_width] {
            args->options.max_width = max_width->count() > 0 ? args->max_width : -1;
            return run_render(*args);
          }};
}

}  // namespace hbgs::cli
