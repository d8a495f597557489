// SPDX-License-Identifier: MIT
// A small hand-written SVG plot for the benchmarks (no external tools): one panel with linear or
// log10 axes, grid lines and tick labels, polylines, markers with text labels and hover titles,
// and a legend. Enough for "figure against figure" plots; not a plotting library.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace gs::bench::svg {

inline std::string num(double v, const char* format = "%.1f") {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// Escapes the characters XML gives a meaning to.
inline std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '&') out += "&amp;";
    else if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

// Tick spacing of 1, 2 or 5 x 10^k giving about `target` ticks over range.
inline double nice_step(double range, int target) {
  const double raw = std::max(range, 1e-12) / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10.0 * p;
}

// Tick label without trailing zeros ("0.001", "20", "1e+04" only for extreme values).
inline std::string tick_label(double v) {
  if (v == 0) return "0";
  const double a = std::fabs(v);
  if (a >= 1e5 || a < 1e-4) return num(v, "%.0e");
  std::string s = num(v, "%.4f");
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

struct Axis {
  std::string label;
  bool log = false;
  double lo = 0, hi = 1;  // data range (set by fit(), or by hand)
  // Widens [lo, hi] to nice bounds: whole decades for a log axis (values <= 0 are dropped),
  // multiples of the tick step for a linear one (which also includes zero when `from_zero`).
  void fit(const std::vector<double>& values, bool from_zero = false) {
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
  double frac(double v) const {  // 0 at lo, 1 at hi (clamped for a log axis at v <= 0)
    if (log) return (std::log10(std::max(v, lo * 1e-3)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
    return (v - lo) / (hi - lo);
  }
  std::vector<double> ticks() const {
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
};

struct Series {
  std::string name, color;
  std::vector<double> x, y;
  std::vector<std::string> labels;  // optional text next to each marker
  std::vector<std::string> titles;  // optional hover text per marker
  bool line = true;
  char marker = 'o';  // 'o' circle, 's' square, '^' triangle, 'd' diamond
};

inline const char* palette(size_t i) {
  static const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  return colors[i % 8];
}

class Plot {
 public:
  Plot(std::string title, Axis x, Axis y) : title_(std::move(title)), x_(std::move(x)), y_(std::move(y)) {}
  void add(Series s) { series_.push_back(std::move(s)); }

  std::string render() const {
    const double W = 760, H = 480, left = 76, right = 190, top = 46, bottom = 62;
    const double pw = W - left - right, ph = H - top - bottom;
    auto X = [&](double v) { return left + pw * std::clamp(x_.frac(v), -0.02, 1.02); };
    auto Y = [&](double v) { return top + ph * (1 - std::clamp(y_.frac(v), -0.02, 1.02)); };
    std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W, "%.0f") + "\" height=\"" +
                    num(H, "%.0f") + "\" viewBox=\"0 0 " + num(W, "%.0f") + " " + num(H, "%.0f") +
                    "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    s += "<text x=\"" + num(left + pw / 2) + "\" y=\"26\" text-anchor=\"middle\" font-size=\"15\">" + escape(title_) +
         "</text>\n";
    for (double t : y_.ticks()) {
      const std::string py = num(Y(t));
      s += "<line x1=\"" + num(left) + "\" x2=\"" + num(left + pw) + "\" y1=\"" + py + "\" y2=\"" + py +
           "\" stroke=\"#ddd\"/>\n<text x=\"" + num(left - 6) + "\" y=\"" + py +
           "\" text-anchor=\"end\" dominant-baseline=\"middle\">" + tick_label(t) + "</text>\n";
    }
    for (double t : x_.ticks()) {
      const std::string px = num(X(t));
      s += "<line x1=\"" + px + "\" x2=\"" + px + "\" y1=\"" + num(top) + "\" y2=\"" + num(top + ph) +
           "\" stroke=\"#ddd\"/>\n<text x=\"" + px + "\" y=\"" + num(top + ph + 18) + "\" text-anchor=\"middle\">" +
           tick_label(t) + "</text>\n";
    }
    s += "<rect x=\"" + num(left) + "\" y=\"" + num(top) + "\" width=\"" + num(pw) + "\" height=\"" + num(ph) +
         "\" fill=\"none\" stroke=\"black\"/>\n";
    s += "<text x=\"" + num(left + pw / 2) + "\" y=\"" + num(H - 16) + "\" text-anchor=\"middle\">" + escape(x_.label) +
         "</text>\n";
    s += "<text transform=\"translate(18 " + num(top + ph / 2) + ") rotate(-90)\" text-anchor=\"middle\">" +
         escape(y_.label) + "</text>\n";
    for (size_t k = 0; k < series_.size(); ++k) {
      const Series& se = series_[k];
      if (se.line && se.x.size() > 1) {
        std::string pts;
        for (size_t i = 0; i < se.x.size(); ++i) pts += num(X(se.x[i])) + "," + num(Y(se.y[i])) + " ";
        s += "<polyline fill=\"none\" stroke=\"" + se.color + "\" stroke-width=\"1.5\" stroke-opacity=\"0.7\" points=\"" +
             pts + "\"/>\n";
      }
      for (size_t i = 0; i < se.x.size(); ++i) {
        const double px = X(se.x[i]), py = Y(se.y[i]);
        const std::string title = i < se.titles.size() ? "<title>" + escape(se.titles[i]) + "</title>" : "";
        s += marker(se.marker, px, py, se.color, title);
        if (i < se.labels.size() && !se.labels[i].empty())
          s += "<text x=\"" + num(px + 6) + "\" y=\"" + num(py - 6) + "\" font-size=\"10\" fill=\"" + se.color + "\">" +
               escape(se.labels[i]) + "</text>\n";
      }
      const double ly = top + 10 + 20 * double(k), lx = left + pw + 16;
      s += marker(se.marker, lx + 8, ly, se.color, "");
      if (se.line)
        s += "<line x1=\"" + num(lx) + "\" x2=\"" + num(lx + 16) + "\" y1=\"" + num(ly) + "\" y2=\"" + num(ly) +
             "\" stroke=\"" + se.color + "\" stroke-width=\"1.5\"/>\n";
      s += "<text x=\"" + num(lx + 24) + "\" y=\"" + num(ly) + "\" dominant-baseline=\"middle\">" + escape(se.name) +
           "</text>\n";
    }
    return s + "</svg>\n";
  }

 private:
  static std::string marker(char kind, double x, double y, const std::string& color, const std::string& title) {
    const std::string fill = "fill=\"" + color + "\"";
    if (kind == 's')
      return "<rect x=\"" + num(x - 4) + "\" y=\"" + num(y - 4) + "\" width=\"8\" height=\"8\" " + fill + ">" + title +
             "</rect>\n";
    if (kind == '^' || kind == 'd') {
      const std::string pts = kind == '^' ? num(x) + "," + num(y - 5) + " " + num(x + 5) + "," + num(y + 4) + " " +
                                                num(x - 5) + "," + num(y + 4)
                                          : num(x) + "," + num(y - 5) + " " + num(x + 5) + "," + num(y) + " " + num(x) +
                                                "," + num(y + 5) + " " + num(x - 5) + "," + num(y);
      return "<polygon points=\"" + pts + "\" " + fill + ">" + title + "</polygon>\n";
    }
    return "<circle cx=\"" + num(x) + "\" cy=\"" + num(y) + "\" r=\"4\" " + fill + ">" + title + "</circle>\n";
  }

  std::string title_;
  Axis x_, y_;
  std::vector<Series> series_;
};

}  // namespace gs::bench::svg
