// SPDX-License-Identifier: MIT
// The one SVG plotter (gs/jobs/svg_plot.h) and the run's PSNR-vs-time files: the plot is
// well-formed XML whatever the names hold (a dataset called "Fish & Chips <2>" gave invalid SVG
// before), non-finite points are left out, the axes fit their data, and a non-finite PSNR goes
// through progress.json as null (it was written as 0 dB).
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <limits>
#include <string>
#include <vector>

#include <unistd.h>

#include "../../jobs/src/psnr_plot.h"
#include "../../jobs/src/train_progress.h"
#include "gs/jobs/run_folder.h"
#include "gs/jobs/svg_plot.h"

namespace gs::jobs {
namespace {

// A small XML well-formedness check: tags nest and close, attribute values are quoted, '<' appears
// only as markup, and every '&' starts an entity. Returns "" when fine, else what is wrong.
std::string xml_problem(const std::string& s) {
  std::vector<std::string> open;
  auto entity_ok = [&](size_t i) {
    for (const char* e : {"&amp;", "&lt;", "&gt;", "&quot;", "&apos;"})
      if (s.compare(i, std::char_traits<char>::length(e), e) == 0) return true;
    return false;
  };
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '&' && !entity_ok(i)) return "bare & at " + std::to_string(i);
    if (s[i] != '<') continue;
    const size_t start = i;
    char quote = 0;
    for (++i; i < s.size(); ++i) {
      if (quote) {
        if (s[i] == quote) quote = 0;
        else if (s[i] == '<') return "< inside an attribute at " + std::to_string(i);
        else if (s[i] == '&' && !entity_ok(i)) return "bare & in an attribute at " + std::to_string(i);
      } else if (s[i] == '"' || s[i] == '\'') {
        quote = s[i];
      } else if (s[i] == '<') {
        return "< inside a tag at " + std::to_string(i);
      } else if (s[i] == '>') {
        break;
      }
    }
    if (i >= s.size()) return "unterminated tag at " + std::to_string(start);
    std::string tag = s.substr(start + 1, i - start - 1);
    const bool closing = !tag.empty() && tag[0] == '/', empty = !tag.empty() && tag.back() == '/';
    const std::string name = tag.substr(closing ? 1 : 0, tag.find_first_of(" \t\n/", closing ? 1 : 0) - (closing ? 1 : 0));
    if (name.empty()) return "tag without a name at " + std::to_string(start);
    if (closing) {
      if (open.empty() || open.back() != name) return "</" + name + "> does not close <" + (open.empty() ? "" : open.back()) + ">";
      open.pop_back();
    } else if (!empty) {
      open.push_back(name);
    }
  }
  return open.empty() ? "" : "<" + open.back() + "> is never closed";
}

size_t count(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

TEST_CASE("the checker itself: it refuses what is not XML") {
  CHECK(xml_problem("<svg><text>a &amp; b</text></svg>").empty());
  CHECK_FALSE(xml_problem("<svg><text>Fish & Chips</text></svg>").empty());
  CHECK_FALSE(xml_problem("<svg><text>a < b</text></svg>").empty());
  CHECK_FALSE(xml_problem("<svg><text>a</svg></text>").empty());
  CHECK_FALSE(xml_problem("<svg><text x=\"1\">a</text>").empty());
}

TEST_CASE("psnr plot: a dataset name with & and < stays well-formed SVG, escaped") {
  const std::vector<PsnrRow> rows = {{0, 0.0, 12.5}, {500, 30.2, 24.25}, {1000, 61.0, 27.0}};
  const std::string svg = psnr_svg(rows, "Test PSNR vs training time: Fish & Chips <2>");
  CHECK(xml_problem(svg) == "");
  CHECK(svg.find("Fish &amp; Chips &lt;2&gt;") != std::string::npos);
  CHECK(count(svg, "<circle") == 3);
  CHECK(svg.find("iteration 500: 24.25 dB at 30.2 s") != std::string::npos);
}

TEST_CASE("psnr plot: rows without a finite PSNR are left out, not drawn at NaN") {
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<PsnrRow> rows = {{0, 0.0, 10.0}, {100, 5.0, inf}, {200, 9.0, std::nan("")}, {300, 14.0, 20.0}};
  const std::string svg = psnr_svg(rows, "t");
  CHECK(xml_problem(svg) == "");
  CHECK(count(svg, "<circle") == 2);
  for (const char* bad : {"nan", "inf"})  // as a number: in a coordinate list, an attribute or a title
    for (const std::string& around : {std::string("\"") + bad, bad + std::string("\""), bad + std::string(","),
                                      std::string(",") + bad, std::string(" ") + bad, std::string(": ") + bad})
      CHECK(svg.find(around) == std::string::npos);
  // No rows at all: still a valid, empty plot.
  CHECK(xml_problem(psnr_svg({}, "empty")) == "");
}

TEST_CASE("progress.json: a non-finite PSNR is written as null and read back as not a number") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("hbgs_test_progress_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  Progress p;
  p.iteration = 300;
  p.rows = {{100, 1.5, 21.25}, {200, 3.0, std::numeric_limits<double>::infinity()}, {300, 4.5, 23.5}};
  REQUIRE(save_progress_to((dir / kProgressFile).string(), p).ok());
  std::ifstream in(dir / kProgressFile);
  std::stringstream text;
  text << in.rdbuf();
  CHECK(text.str().find("[200,3.0,null]") != std::string::npos);
  const Progress back = load_progress(dir.string(), 300, [](const std::string&) {});
  REQUIRE(back.rows.size() == 3);
  CHECK(back.rows[0].psnr == 21.25);
  CHECK(std::isnan(back.rows[1].psnr));
  CHECK(back.rows[2].psnr == 23.5);
  fs::remove_all(dir);
}

TEST_CASE("svg plot: legend and labels escaped, axes fit the data") {
  svg::Axis x{"time & cost (ms)"}, y{"error (deg, log)", true};
  x.fit({3.0, 47.0}, true);
  CHECK(x.lo == 0);
  CHECK(x.hi == 50);
  y.fit({0.02, 0.9, -1.0});  // the non-positive value is dropped on a log axis
  CHECK(y.lo == doctest::Approx(0.01));
  CHECK(y.hi == doctest::Approx(1.0));
  const std::vector<double> ticks = x.ticks();
  REQUIRE(ticks.size() == 6);
  CHECK(ticks[1] == doctest::Approx(10.0));
  svg::Plot plot("R&D <sweep>", x, y);
  svg::Series a;
  a.name = "solver \"A\" & co";
  a.color = svg::palette(1);
  a.marker = 's';
  a.x = {3, 20, 47};
  a.y = {0.9, 0.1, 0.02};
  a.labels = {"<1>", "2", "3"};
  a.titles = {"a&b", "c", "d"};
  plot.add(a);
  const std::string svg = plot.render();
  CHECK(xml_problem(svg) == "");
  CHECK(svg.find("R&amp;D &lt;sweep&gt;") != std::string::npos);
  CHECK(svg.find("solver &quot;A&quot; &amp; co") != std::string::npos);
  CHECK(svg.find("time &amp; cost (ms)") != std::string::npos);
  CHECK(count(svg, "<rect") == 2 + 3 + 1);  // background, frame, 3 markers, 1 in the legend
  CHECK(svg::tick_label(0.5) == "0.5");
  CHECK(svg::tick_label(20.0) == "20");
  CHECK(svg::escape("a'b") == "a&apos;b");
}

}  // namespace
}  // namespace gs::jobs
