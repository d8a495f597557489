// SPDX-License-Identifier: MIT
// `hbgs compact`: writes the compact model file of a trained model (run folder or model file),
// pruned and calibrated on its training views, and prints the sizes and the test PSNR of both.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/image.h"
#include "gs/jobs/compact.h"

namespace hbgs::cli {
namespace {

struct CompactCli {
  gs::jobs::CompactRunOptions options;
  bool no_prune = false, no_eval = false;
};

int run_compact(CompactCli& cli) {
  gs::jobs::CompactRunOptions& a = cli.options;
  a.compact.prune = !cli.no_prune;
  a.evaluate = !cli.no_eval;
  gs::jobs::CompactRunSummary s;
  if (gs::Status st = gs::jobs::compact_run(a, &s); !st.ok())
    return fail("compact", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  std::printf("hbgs compact: %s -> %s (%.1f s)\n", s.source.model_path.c_str(), a.out.c_str(), s.seconds);
  std::printf("  size: %.3f MB float, %.3f MB compact (%.1fx smaller)\n", double(s.float_bytes) / 1e6, double(s.compact_bytes) / 1e6,
              s.compact_bytes ? double(s.float_bytes) / double(s.compact_bytes) : 0.0);
  std::printf("  anchors: %zu -> %zu (%zu pruned: no Gaussian with opacity > 0 in any of %zu training views; %zu never visible)\n",
              s.stats.anchors_in, s.stats.anchors_out, s.stats.anchors_in - s.stats.anchors_out, s.stats.views,
              s.stats.never_visible);
  if (s.evaluated) {
    const auto& f = s.float_eval.views;
    const auto& c = s.compact_eval.views;
    size_t worst = 0;
    for (size_t i = 1; i < f.size(); ++i)
      if (f[i].psnr - c[i].psnr > f[worst].psnr - c[worst].psnr) worst = i;
    std::printf("  test PSNR (%zu views, 8-bit): float %.3f dB, compact %.3f dB (%+.3f dB); worst view %s %+.3f dB\n", f.size(),
                s.float_eval.psnr, s.compact_eval.psnr, s.compact_eval.psnr - s.float_eval.psnr,
                f.empty() ? "-" : f[worst].name.c_str(), f.empty() ? 0.0 : c[worst].psnr - f[worst].psnr);
  }
  return kExitOk;
}

}  // namespace

Command add_compact_command(CLI::App& parent) {
  auto args = std::make_shared<CompactCli>();
  gs::jobs::CompactRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand(
      "compact", "Write a compact model file (int8/fp16, entropy-coded, pruned, calibrated) of a trained model");
  sub->add_option("model", o->input, "Run folder (from hbgs train) or model file")->required();
  sub->add_option("--out", o->out, "Compact model file to write (e.g. model.hbgc)")->required();
  sub->add_option("--dataset", o->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--max-width", o->max_width, "Downscale views to at most this width (default: as trained)")
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--residual-bits", o->compact.residual_bits, "Sub-voxel bits of the anchor positions")
      ->capture_default_str()->check(CLI::Range(0, 12));
  sub->add_option("--offset-levels", o->compact.offset_levels,
                  "Offset precision: the rendered error of max |offset| / N steps per anchor (1..127)")
      ->capture_default_str()->check(CLI::Range(1, 127));
  sub->add_option("--feature-levels", o->compact.feature_levels,
                  "Feature precision: the first-layer error of max |channel| / N steps per channel (1..127)")
      ->capture_default_str()->check(CLI::Range(1, 127));
  sub->add_option("--image-levels", o->compact.image_levels, "Steps over each image feature channel's range (1..255)")
      ->capture_default_str()->check(CLI::Range(1, 255));
  sub->add_option("--log-scale-step", o->compact.log_scale_step, "Grid step of the anchor log-scales (natural log; 0: fp16)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  sub->add_flag("--no-prune", args->no_prune, "Keep anchors that no training view decodes a Gaussian from");
  sub->add_flag("--no-eval", args->no_eval, "Do not measure the test PSNR of the float and the compact model");
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  return {sub, [args] { return run_compact(*args); }};
}

}  // namespace hbgs::cli
