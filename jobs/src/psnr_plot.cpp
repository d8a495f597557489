// SPDX-License-Identifier: MIT
// The PSNR-vs-time plot of a training run: a hand-written SVG line chart (no plotting library).
#include "psnr_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace gs::jobs {
namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// Tick spacing of 1, 2 or 5 x 10^k giving about `target` ticks over range.
double nice_step(double range, int target) {
  const double raw = std::max(range, 1e-9) / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10.0 * p;
}

}  // namespace

// Hand-written SVG line plot of test PSNR against training seconds.
std::string psnr_svg(const std::vector<PsnrRow>& rows, const std::string& title) {
  const double W = 720, H = 440, left = 70, right = 24, top = 44, bottom = 62;
  const double pw = W - left - right, ph = H - top - bottom;
  double xmax = 1, ymin = 1e9, ymax = -1e9;
  for (const PsnrRow& r : rows) {
    xmax = std::max(xmax, r.seconds);
    if (std::isfinite(r.psnr)) ymin = std::min(ymin, r.psnr), ymax = std::max(ymax, r.psnr);
  }
  if (ymin > ymax) ymin = 0, ymax = 40;
  const double ystep = nice_step(std::max(ymax - ymin, 1.0), 6);
  ymin = std::floor(ymin / ystep) * ystep;
  ymax = std::max(std::ceil(ymax / ystep) * ystep, ymin + ystep);
  const double xstep = nice_step(xmax, 6);
  xmax = std::ceil(xmax / xstep) * xstep;
  auto X = [&](double x) { return left + pw * x / xmax; };
  auto Y = [&](double y) { return top + ph * (1 - (y - ymin) / (ymax - ymin)); };

  std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"720\" height=\"440\" viewBox=\"0 0 720 440\" "
                  "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"720\" height=\"440\" fill=\"white\"/>\n";
  s += "<text x=\"360\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">" + title + "</text>\n";
  for (double y = ymin; y <= ymax + 1e-9; y += ystep) {
    const std::string py = fmt("%.1f", Y(y));
    s += "<line x1=\"" + fmt("%.1f", left) + "\" x2=\"" + fmt("%.1f", left + pw) + "\" y1=\"" + py + "\" y2=\"" + py +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + fmt("%.1f", left - 6) + "\" y=\"" + py +
         "\" text-anchor=\"end\" dominant-baseline=\"middle\">" + fmt(ystep < 1 ? "%.1f" : "%.0f", y) + "</text>\n";
  }
  for (double x = 0; x <= xmax + 1e-9; x += xstep) {
    const std::string px = fmt("%.1f", X(x));
    s += "<line x1=\"" + px + "\" x2=\"" + px + "\" y1=\"" + fmt("%.1f", top) + "\" y2=\"" + fmt("%.1f", top + ph) +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + px + "\" y=\"" + fmt("%.1f", top + ph + 18) +
         "\" text-anchor=\"middle\">" + fmt(xstep < 1 ? "%.1f" : "%.0f", x) + "</text>\n";
  }
  s += "<rect x=\"" + fmt("%.1f", left) + "\" y=\"" + fmt("%.1f", top) + "\" width=\"" + fmt("%.1f", pw) +
       "\" height=\"" + fmt("%.1f", ph) + "\" fill=\"none\" stroke=\"black\"/>\n";
  s += "<text x=\"" + fmt("%.1f", left + pw / 2) + "\" y=\"" + fmt("%.1f", H - 16) +
       "\" text-anchor=\"middle\">training time (s, evaluation excluded)</text>\n";
  s += "<text transform=\"translate(18 " + fmt("%.1f", top + ph / 2) +
       ") rotate(-90)\" text-anchor=\"middle\">test PSNR (dB)</text>\n";
  std::string points;
  for (const PsnrRow& r : rows)
    if (std::isfinite(r.psnr)) points += fmt("%.1f", X(r.seconds)) + "," + fmt("%.1f", Y(r.psnr)) + " ";
  s += "<polyline fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"2\" points=\"" + points + "\"/>\n";
  for (const PsnrRow& r : rows)
    if (std::isfinite(r.psnr))
      s += "<circle cx=\"" + fmt("%.1f", X(r.seconds)) + "\" cy=\"" + fmt("%.1f", Y(r.psnr)) +
           "\" r=\"2.5\" fill=\"#1f77b4\"><title>iteration " + std::to_string(r.iteration) + ": " +
           fmt("%.2f", r.psnr) + " dB at " + fmt("%.1f", r.seconds) + " s</title></circle>\n";
  return s + "</svg>\n";
}

}  // namespace gs::jobs
