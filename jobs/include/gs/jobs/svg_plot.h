// SPDX-License-Identifier: MIT
// The one SVG plotter of hbgs, hand-written (no external tools): one panel with linear or log10
// axes, grid lines and tick labels, polylines, markers with text labels and hover titles, and an
// optional legend. Enough for "figure against figure" plots (the run's PSNR-vs-time curve, the
// benchmarks' sweeps); not a plotting library. Every text that reaches the SVG (title, axis labels,
// series names, marker labels and titles) is XML-escaped, so names with & < > " are safe.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace gs::jobs::svg {

// printf-style formatting of one number.
std::string num(double v, const char* format = "%.1f");
// Escapes the characters XML gives a meaning to (& < > " ').
std::string escape(const std::string& s);
// Tick spacing of 1, 2 or 5 x 10^k giving about `target` ticks over range.
double nice_step(double range, int target);
// Tick label without trailing zeros ("0.001", "20", "1e+04" only for extreme values).
std::string tick_label(double v);

struct Axis {
  std::string label;
  bool log = false;
  double lo = 0, hi = 1;  // data range (set by fit(), or by hand)
  // Widens [lo, hi] to nice bounds over the finite values: whole decades for a log axis (values
  // <= 0 are dropped), multiples of the tick step for a linear one (which also includes zero when
  // `from_zero`).
  void fit(const std::vector<double>& values, bool from_zero = false);
  double frac(double v) const;  // 0 at lo, 1 at hi (clamped for a log axis at v <= 0)
  std::vector<double> ticks() const;
};

struct Series {
  std::string name, color;
  std::vector<double> x, y;         // points with a non-finite coordinate are left out
  std::vector<std::string> labels;  // optional text next to each marker
  std::vector<std::string> titles;  // optional hover text per marker
  bool line = true;
  double line_width = 1.5, line_opacity = 0.7;
  char marker = 'o';  // 'o' circle, 's' square, '^' triangle, 'd' diamond
  double marker_size = 4;  // circle radius; squares, triangles and diamonds scale with it
};

// Colour i of a fixed palette of 8.
const char* palette(size_t i);

// The canvas: size and the margins around the plotting area (the right one holds the legend).
struct Frame {
  double width = 760, height = 480, left = 76, right = 190, top = 46, bottom = 62;
  bool legend = true;
};

class Plot {
 public:
  Plot(std::string title, Axis x, Axis y, Frame frame = Frame{});
  void add(Series s);
  std::string render() const;

 private:
  std::string title_;
  Axis x_, y_;
  Frame frame_;
  std::vector<Series> series_;
};

}  // namespace gs::jobs::svg
