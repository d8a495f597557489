// SPDX-License-Identifier: MIT
// Shared option wiring and printing for the ingest and capture subcommands.
#include "capture_cli.h"

#include <cstdio>

#include "common.h"

namespace hbgs::cli {

void add_ingest_options(CLI::App* sub, IngestCommonArgs* a, bool out_required) {
  CLI::Option* out = sub->add_option("--out", a->out, "Dataset folder to write (images/, sparse/0/, ingest.json, colmap.log)");
  if (out_required) out->required();
  sub->add_option("--frames", a->frames, "Frames to keep for structure from motion")
      ->capture_default_str()
      ->check(CLI::Range(2, 100000));
  sub->add_option("--blur-ratio", a->blur_ratio,
                  "Reject a frame whose sharpness is below this fraction of its neighbours' median")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--matcher", a->matcher, "COLMAP matching: sequential (video order) or exhaustive")
      ->capture_default_str();
  sub->add_option("--colmap", a->colmap, "COLMAP program (name on PATH or path)")->capture_default_str();
  sub->add_option("--max-width", a->max_width, "Downscale kept frames wider than this (0: keep)")
      ->capture_default_str()
      ->check(CLI::Range(0, 16384));
  sub->add_option("--threads", a->threads, "COLMAP threads (0: all)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_flag("--force", a->force, "Replace an existing dataset in --out");
  sub->add_flag("--keep-work", a->keep_work, "Keep OUT/work (raw frames, COLMAP database and models)");
}

int ingest_options_from(const IngestCommonArgs& a, const char* cmd, gs::capture::IngestOptions* o) {
  gs::Expected<gs::capture::Matcher> m = gs::capture::parse_matcher(a.matcher);
  if (!m.ok()) {
    fail(cmd, m.status().message());
    return kExitUsage;
  }
  o->select.target_count = a.frames;
  o->select.blur_ratio = a.blur_ratio;
  o->colmap.matcher = *m;
  o->colmap.colmap = a.colmap;
  o->colmap.threads = a.threads;
  o->max_width = a.max_width;
  o->force = a.force;
  o->keep_work = a.keep_work;
  return kExitOk;
}

void print_progress(const std::string& line) {
  std::printf("%s\n", line.c_str());
  std::fflush(stdout);
}

void print_ingest_summary(const gs::capture::IngestReport& r, const std::string& out, double seconds) {
  std::printf("hbgs: %d frames analysed, %d blurred, %d kept; COLMAP registered %d of %d (%d points); %.1f s\n",
              r.select.total, r.select.blurred, r.select.kept, r.colmap.registered, r.colmap.images, r.colmap.points,
              seconds);
  std::printf("  train with: hbgs train %s --out RUN\n", out.c_str());
}

}  // namespace hbgs::cli
