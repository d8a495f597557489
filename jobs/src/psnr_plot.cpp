// SPDX-License-Identifier: MIT
// The PSNR-vs-time plot of a training run, drawn by the one SVG plotter (gs/jobs/svg_plot.h).
#include "psnr_plot.h"

#include "gs/jobs/svg_plot.h"

namespace gs::jobs {

std::string psnr_svg(const std::vector<PsnrRow>& rows, const std::string& title) {
  svg::Series curve;
  curve.name = "test PSNR";
  curve.color = svg::palette(0);
  curve.line_width = 2;
  curve.line_opacity = 1;
  curve.marker_size = 2.5;
  for (const PsnrRow& r : rows) {  // rows without a finite PSNR are left out by the plotter
    curve.x.push_back(r.seconds);
    curve.y.push_back(r.psnr);
    curve.titles.push_back("iteration " + std::to_string(r.iteration) + ": " + svg::num(r.psnr, "%.2f") + " dB at " +
                           svg::num(r.seconds, "%.1f") + " s");
  }
  svg::Axis x{"training time (s, evaluation excluded)"}, y{"test PSNR (dB)"};
  x.fit(curve.x, true);
  y.fit(curve.y);
  svg::Frame frame;
  frame.width = 720, frame.height = 440, frame.left = 70, frame.right = 24, frame.top = 44, frame.bottom = 62;
  frame.legend = false;
  svg::Plot plot(title, x, y, frame);
  plot.add(std::move(curve));
  return plot.render();
}

}  // namespace gs::jobs
