// SPDX-License-Identifier: MIT
// Shared option wiring and printing for the ingest and capture subcommands.
#include "capture_cli.h"

#include <cstdio>
#include <iterator>
#include <vector>

#include "common.h"

namespace hbgs::cli {

void add_ingest_options(CLI::App* sub, std::string* out_dir, gs::capture::IngestOptions* o, bool out_required) {
  CLI::Option* out = sub->add_option("--out", *out_dir, "Dataset folder to write (images/, sparse/0/, ingest.json, colmap.log)");
  if (out_required) out->required();
  sub->add_option("--frames", o->select.target_count, "Frames to keep for structure from motion")
      ->capture_default_str()
      ->check(CLI::Range(2, 100000));
  sub->add_option("--blur-ratio", o->select.blur_ratio,
                  "Reject a frame whose sharpness is below this fraction of its neighbours' median")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option_function<std::string>(
         "--matcher", [o](const std::string& text) { o->colmap.matcher = *gs::capture::parse_matcher(text); },
         "COLMAP matching: sequential (video order, the default) or exhaustive")
      ->check(CLI::Validator(
          [](std::string& text) {
            const gs::Expected<gs::capture::Matcher> m = gs::capture::parse_matcher(text);
            return m.ok() ? std::string() : m.status().message();
          },
          "MATCHER"));
  std::vector<std::string> models(std::begin(gs::capture::kColmapCameraModels), std::end(gs::capture::kColmapCameraModels));
  sub->add_option("--camera-model", o->colmap.camera_model,
                  "COLMAP camera model of the one shared camera; the fisheye ones (OPENCV_FISHEYE, RADIAL_FISHEYE, "
                  "SIMPLE_RADIAL_FISHEYE, FOV) are kept distorted and undistorted by hbgs on load (hbgs train --fisheye-fov), "
                  "the others are undistorted to PINHOLE by COLMAP")
      ->capture_default_str()
      ->check(CLI::IsMember(models));
  sub->add_option("--colmap", o->colmap.colmap, "COLMAP program (name on PATH or path)")->capture_default_str();
  sub->add_option("--max-width", o->max_width, "Downscale kept frames wider than this (0: keep)")
      ->capture_default_str()
      ->check(CLI::Range(0, 16384));
  sub->add_option("--threads", o->colmap.threads, "COLMAP threads (0: all)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--sfm-check-runs", o->colmap.check_runs,
                  "Consistency check of COLMAP's reconstruction: map the same matches again with this many other seeds and "
                  "flag the views whose poses disagree (ingest.json colmap.consistency; 0: no check)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10));
  sub->add_option("--suspect-deg", o->colmap.suspect_rotation_deg,
                  "Consistency check: a view whose rotation differs by more than this (degrees) between reconstructions is suspect")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 180.0));
  sub->add_flag("--force", o->force, "Replace an existing dataset in --out");
  sub->add_flag("--keep-work", o->keep_work, "Keep OUT/work (raw frames, COLMAP database and models)");
}

void print_progress(const std::string& line) {
  std::printf("%s\n", line.c_str());
  std::fflush(stdout);
}

void print_ingest_summary(const gs::capture::IngestReport& r, const std::string& out, double seconds) {
  std::printf("hbgs: %d frames analysed, %d blurred, %d kept; COLMAP registered %d of %d (%d points); %.1f s\n",
              r.select.total, r.select.blurred, r.select.kept, r.colmap.registered, r.colmap.images, r.colmap.points,
              seconds);
  const gs::capture::SfmConsistency& c = r.colmap.consistency;
  if (c.suspect > 0) {
    std::printf("  %d suspect view(s): COLMAP's reconstructions with other seeds place them differently (ingest.json colmap.consistency):",
                c.suspect);
    for (const std::string& name : c.suspect_names()) std::printf(" %s", name.c_str());
    std::printf("\n");
  }
  std::printf("  train with: hbgs train %s --out RUN\n", out.c_str());
}

}  // namespace hbgs::cli
