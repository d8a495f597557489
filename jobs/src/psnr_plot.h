// SPDX-License-Identifier: MIT
// The PSNR-vs-time curve of a training run (psnr_vs_time.csv rows) and its SVG plot.
#pragma once

#include <string>
#include <vector>

namespace gs::jobs {

// One point of the curve: test PSNR after `iteration`, reached after `seconds` of training (wall
// clock of the training steps only; evaluation and file writing excluded).
struct PsnrRow {
  int iteration = 0;
  double seconds = 0, psnr = 0;
};

// A 720x440 SVG line plot of test PSNR (dB) against training seconds (gs/jobs/svg_plot.h); the
// title is escaped, rows without a finite PSNR are left out.
std::string psnr_svg(const std::vector<PsnrRow>& rows, const std::string& title);

}  // namespace gs::jobs
