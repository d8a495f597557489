// SPDX-License-Identifier: MIT
// `hbgs export`: bakes a trained model into plain Gaussians with SH colour and writes them in the
// splat format the output's extension names, then prints the size and the test PSNR of both.
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/image.h"
#include "gs/jobs/export.h"

namespace hbgs::cli {
namespace {

struct ExportCli {
  gs::jobs::ExportRunOptions options;
  bool no_eval = false;
  CLI::Option* spz_version = nullptr;
};

int run_export(ExportCli& cli) {
  gs::jobs::ExportRunOptions& a = cli.options;
  a.evaluate = !cli.no_eval;
  if (cli.spz_version->count() > 0) {
    gs::Expected<gs::io::SplatFormat> format = gs::io::splat_format_from_extension(a.out);
    if (format.ok() && *format != gs::io::SplatFormat::kSpz)
      return fail("export", "--spz-version applies to .spz output only (--out " + a.out + ")");
  }
  gs::jobs::ExportRunSummary s;
  if (gs::Status st = gs::jobs::export_run(a, &s); !st.ok())
    return fail("export", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  std::printf("hbgs export: %s -> %s (%s, %.1f s)\n", s.source.model_path.c_str(), a.out.c_str(), gs::io::splat_format_name(s.format),
              s.seconds);
  std::printf("  %zu Gaussians of %zu candidates (%zu seen by a training view), %.3f MB (%.1f bytes each)\n", s.gaussians,
              s.bake.candidates, s.bake.seen, double(s.bytes) / 1e6, s.gaussians ? double(s.bytes) / double(s.gaussians) : 0.0);
  if (s.bake.candidates > 0) {
    std::printf("  against the model's renders of the training views: fit %.2f dB (%.1f s)", s.bake.psnr_fit, s.bake.fit_seconds);
    if (a.distill_iterations > 0)
      std::printf(", after %d distillation steps %.2f dB (%.1f s)", a.distill_iterations, s.bake.psnr_distilled, s.bake.distill_seconds);
    std::printf("\n");
  }
  if (s.evaluated)
    std::printf("  test PSNR (%zu views, 8-bit): model %.3f dB, exported %.3f dB (%+.3f dB)\n", s.model_eval.views.size(),
                s.model_eval.psnr, s.baked_eval.psnr, s.baked_eval.psnr - s.model_eval.psnr);
  return kExitOk;
}

}  // namespace

Command add_export_command(CLI::App& parent) {
  auto args = std::make_shared<ExportCli>();
  gs::jobs::ExportRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand(
      "export", "Bake a trained model into plain Gaussians (SH colour) for splat viewers: 3DGS .ply, .compressed.ply, .splat, .spz");
  sub->add_option("model", o->input,
                  "Run folder (from hbgs train) or model file (.hbgs, .hbgc) to bake, or a splat file to convert")
      ->required();
  sub->add_option("--out", o->out, "File to write; its extension picks the format (.ply, .compressed.ply, .splat, .spz)")->required();
  args->spz_version = sub->add_option("--spz-version", o->write.spz.version,
                                      ".spz version: 4 (ZSTD, what current viewers and tools write) or 3 (gzip, for "
                                      "readers older than version 4, e.g. splat-transform 2)")
                          ->capture_default_str()
                          ->check(CLI::IsMember({2, 3, 4}));
  sub->add_option("--sh-degree", o->sh_degree, "Degree of the SH colour (0-3; .splat keeps 0)")->capture_default_str()->check(CLI::Range(0, 3));
  sub->add_option("--distill", o->distill_iterations,
                  "Steps fitting the Gaussians to the model's renders of the training views (0: the least-squares fit only)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000000));
  sub->add_option("--dataset", o->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--max-width", o->max_width, "Downscale views to at most this width (default: as trained)")
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_flag("--no-eval", args->no_eval, "Do not measure the test PSNR of the model and the exported Gaussians");
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  return {sub, [args] { return run_export(*args); }};
}

}  // namespace hbgs::cli
