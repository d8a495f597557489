// SPDX-License-Identifier: MIT
// The report page of a training run (`hbgs report RUN`): one self-contained HTML file,
// RUN/report.html by default, that works offline (nothing is fetched: images are data URIs, the
// script and style are inline). It holds
//   - the run's metrics from results.json: every evaluated iteration (PSNR, SSIM, LPIPS, masked
//     metrics when the dataset has masks, anchors, Gaussians per view, model bytes, timings) and
//     the options from run.json;
//   - the test PSNR against training time (RUN/psnr_vs_time.svg);
//   - test renders beside the ground truth (the run's PNGs of its last full evaluation, else
//     rendered now; a masked view's photo composited on the run's background), for up to
//     `views` test views spread over the split, with their per-view metrics;
//   - an interactive WebGL 2 viewer (jobs/report/viewer.js, embedded at build time) of the model
//     baked into plain Gaussians (the export job's bake, gs/jobs/export.h, SH degree 0) stored in
//     the antimatter15 .splat layout (32 bytes a splat, base64), capped at `max_splats` (the
//     largest contributions kept: opacity x the area of the two largest axes), with the dataset
//     cameras (intrinsics, world-to-camera poses). `report.html#view=NAME` opens a dataset camera
//     at its exact pixel size; the page's test compares a screenshot of it with hbgs's render.
// The page is written atomically. The run folder is only read (no lock: train writes its files
// atomically too).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/model/bake.h"
#include "gs/status.h"

namespace gs::jobs {

struct ReportRunOptions {
  std::string run;                // run folder (from hbgs train)
  std::string out;                // "" : RUN/report.html
  std::string dataset;            // "" : the one in the run's run.json
  int max_splats = 200000;        // the viewer's splats at most (6.4 MB of .splat, 8.5 MB as base64)
  // The bake's distillation steps (gs/model/bake.h). Fewer than hbgs export's 1,000: at SH degree 0
  // the built-in scene (3,000 iterations) gets 28.42 dB with none, 29.05 with 300 (17 s on two
  // cores), 29.08 with 1,000 (57 s).
  int distill_iterations = 300;
  int views = 6;                  // test views shown as render beside ground truth (0: none)
  int threads = 0;                // 0: all CPUs
  uint64_t seed = 0;              // the bake's camera order
};

struct ReportRunSummary {
  std::string path;               // the page written
  uint64_t bytes = 0;             // its size
  uint64_t splat_bytes = 0;       // of the embedded .splat data (before base64)
  size_t baked = 0, splats = 0;   // Gaussians baked, and embedded (splats < baked when capped)
  model::BakeStats bake;
  std::vector<std::string> shown_views;  // the test views with render and ground truth, by name
  size_t test_views = 0, cameras = 0;
  // Test PSNR (dB, 8-bit renders) of the embedded splats as hbgs renders them, and the model's
  // at the last evaluated iteration (results.json; < 0 when missing).
  double splats_psnr = -1, model_psnr = -1;
  int iteration = -1;             // the last evaluated iteration ("ours_<it>"; -1: none)
  double seconds = 0;
};

Status report_run(const ReportRunOptions& options, ReportRunSummary* summary);

}  // namespace gs::jobs
