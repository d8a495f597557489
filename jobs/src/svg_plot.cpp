// SPDX-License-Identifier: MIT
// The one SVG plotter (gs/jobs/svg_plot.h).
#include "gs/jobs/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace gs::jobs::svg {
namespace {

std::string marker(char kind, double size, double x, double y, const std::string& color, const std::string& title) {
  const std::string fill = "fill=\"" + color + "\"";
  const double h = size * 1.25;  // triangle and diamond half-size
  if (kind == 's')
    return "<rect x=\"" + num(x - size) + "\" y=\"" + num(y - size) + "\" width=\"" + num(2 * size) + "\" height=\"" +
           num(2 * size) + "\" " + fill + ">" + title + "</rect>\n";
  if (kind == '^' || kind == 'd') {
    const std::string pts = kind == '^' ? num(x) + "," + num(y - h) + " " + num(x + h) + "," + num(y + size) + " " +
                                              num(x - h) + "," + num(y + size)
                                        : num(x) + "," + num(y - h) + " " + num(x + h) + "," + num(y) + " " + num(x) +
                                              "," + num(y + h) + " " + num(x - h) + "," + num(y);
    return "<polygon points=\"" + pts + "\" " + fill + ">" + title + "</polygon>\n";
  }
  return "<circle cx=\"" + num(x) + "\" cy=\"" + num(y) + "\" r=\"" + tick_label(size) + "\" " + fill + ">" + title +
         "</circle>\n";
}

}  // namespace

std::string num(double v, const char* format) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    if (c == '&') out += "&amp;";
    else if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '"') out += "&quot;";
    else if (c == '\'') out += "&apos;";
    else out += c;
  }
  return out;
}

double nice_step(double range, int target) {
  const double raw = std::max(range, 1e-12) / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10.0 * p;
}

std::string tick_label(double v) {
  if (v == 0) return "0";
  const double a = std::fabs(v);
  if (a >= 1e5 || a < 1e-4) return num(v, "%.0e");
  std::string s = num(v, "%.4f");
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

void Axis::fit(const std::vector<double>& values, bool from_zero) {
  double a = HUGE_VAL, b = -HUGE_VAL;
  for (double v : values)
    if (std::isfinite(v) && (!log || v > 0)) a = std::min(a, v), b = std::max(b, v);
  if (!(a <= b)) a = log ? 0.1 : 0, b = log ? 10 : 1;
  if (log) {
    lo = std::pow(10.0, std::floor(std::log10(a)));
    hi = std::pow(10.0, std::ceil(std::log10(b)));
    if (hi <= lo) hi = lo * 10;
  } else {
    if (from_zero) a = std::min(a, 0.0);
    if (b <= a) b = a + 1;
    const double step = nice_step(b - a, 6);
    lo = std::floor(a / step) * step;
    hi = std::ceil(b / step) * step;
    if (hi <= lo) hi = lo + step;
  }
}

double Axis::frac(double v) const {
  if (log) return (std::log10(std::max(v, lo * 1e-3)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
  return (v - lo) / (hi - lo);
}

std::vector<double> Axis::ticks() const {
  std::vector<double> t;
  if (log) {
    const int decades = int(std::lround(std::log10(hi / lo)));
    for (int d = 0; d <= decades; ++d) {
      const double base = lo * std::pow(10.0, d);
      t.push_back(base);
      if (decades <= 3 && d < decades) t.push_back(2 * base), t.push_back(5 * base);
    }
  } else {
    const double step = nice_step(hi - lo, 6);
    for (double v = lo; v <= hi + 1e-9 * step; v += step) t.push_back(std::fabs(v) < 1e-12 * step ? 0 : v);
  }
  return t;
}

const char* palette(size_t i) {
  static const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  return colors[i % 8];
}

Plot::Plot(std::string title, Axis x, Axis y, Frame frame)
    : title_(std::move(title)), x_(std::move(x)), y_(std::move(y)), frame_(frame) {}

void Plot::add(Series s) { series_.push_back(std::move(s)); }

std::string Plot::render() const {
  const Frame& f = frame_;
  const double pw = f.width - f.left - f.right, ph = f.height - f.top - f.bottom;
  auto X = [&](double v) { return f.left + pw * std::clamp(x_.frac(v), -0.02, 1.02); };
  auto Y = [&](double v) { return f.top + ph * (1 - std::clamp(y_.frac(v), -0.02, 1.02)); };
  const std::string w = num(f.width, "%.0f"), h = num(f.height, "%.0f");
  std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + w + "\" height=\"" + h + "\" viewBox=\"0 0 " + w +
                  " " + h + "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s += "<text x=\"" + num(f.left + pw / 2) + "\" y=\"" + num(f.top - 20) + "\" text-anchor=\"middle\" font-size=\"15\">" +
       escape(title_) + "</text>\n";
  for (double t : y_.ticks()) {
    const std::string py = num(Y(t));
    s += "<line x1=\"" + num(f.left) + "\" x2=\"" + num(f.left + pw) + "\" y1=\"" + py + "\" y2=\"" + py +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + num(f.left - 6) + "\" y=\"" + py +
         "\" text-anchor=\"end\" dominant-baseline=\"middle\">" + tick_label(t) + "</text>\n";
  }
  for (double t : x_.ticks()) {
    const std::string px = num(X(t));
    s += "<line x1=\"" + px + "\" x2=\"" + px + "\" y1=\"" + num(f.top) + "\" y2=\"" + num(f.top + ph) +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + px + "\" y=\"" + num(f.top + ph + 18) + "\" text-anchor=\"middle\">" +
         tick_label(t) + "</text>\n";
  }
  s += "<rect x=\"" + num(f.left) + "\" y=\"" + num(f.top) + "\" width=\"" + num(pw) + "\" height=\"" + num(ph) +
       "\" fill=\"none\" stroke=\"black\"/>\n";
  s += "<text x=\"" + num(f.left + pw / 2) + "\" y=\"" + num(f.height - 16) + "\" text-anchor=\"middle\">" +
       escape(x_.label) + "</text>\n";
  s += "<text transform=\"translate(18 " + num(f.top + ph / 2) + ") rotate(-90)\" text-anchor=\"middle\">" +
       escape(y_.label) + "</text>\n";
  for (size_t k = 0; k < series_.size(); ++k) {
    const Series& se = series_[k];
    const std::string color = escape(se.color);
    std::vector<size_t> shown;  // points with finite coordinates
    for (size_t i = 0; i < se.x.size() && i < se.y.size(); ++i)
      if (std::isfinite(se.x[i]) && std::isfinite(se.y[i])) shown.push_back(i);
    if (se.line && shown.size() > 1) {
      std::string pts;
      for (size_t i : shown) pts += num(X(se.x[i])) + "," + num(Y(se.y[i])) + " ";
      s += "<polyline fill=\"none\" stroke=\"" + color + "\" stroke-width=\"" + tick_label(se.line_width) +
           "\" stroke-opacity=\"" + tick_label(se.line_opacity) + "\" points=\"" + pts + "\"/>\n";
    }
    for (size_t i : shown) {
      const double px = X(se.x[i]), py = Y(se.y[i]);
      const std::string title = i < se.titles.size() ? "<title>" + escape(se.titles[i]) + "</title>" : "";
      s += marker(se.marker, se.marker_size, px, py, color, title);
      if (i < se.labels.size() && !se.labels[i].empty())
        s += "<text x=\"" + num(px + 6) + "\" y=\"" + num(py - 6) + "\" font-size=\"10\" fill=\"" + color + "\">" +
             escape(se.labels[i]) + "</text>\n";
    }
    if (!f.legend) continue;
    const double ly = f.top + 10 + 20 * double(k), lx = f.left + pw + 16;
    s += marker(se.marker, se.marker_size, lx + 8, ly, color, "");
    if (se.line)
      s += "<line x1=\"" + num(lx) + "\" x2=\"" + num(lx + 16) + "\" y1=\"" + num(ly) + "\" y2=\"" + num(ly) +
           "\" stroke=\"" + color + "\" stroke-width=\"" + tick_label(se.line_width) + "\"/>\n";
    s += "<text x=\"" + num(lx + 24) + "\" y=\"" + num(ly) + "\" dominant-baseline=\"middle\">" + escape(se.name) +
         "</text>\n";
  }
  return s + "</svg>\n";
}

}  // namespace gs::jobs::svg
