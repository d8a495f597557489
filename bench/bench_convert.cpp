// SPDX-License-Identifier: MIT
// bench_convert: camera pixel-format conversion, single-threaded: YUYV and NV12 frames of 640x480
// and 1920x1080 to RGB24 through the reference and every SIMD kernel table. Reports ms per frame
// (median and min of the repetitions) and Mpixel/s at the minimum, plus the speed-up over the
// reference; optionally writes JSON. Input bytes are random (every code path, clamping included).
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/simd/kernel_table.h"

namespace gs::bench {
namespace {

struct Row {
  std::string format, isa;
  int width = 0, height = 0;
  Timing t;
};

int run(int argc, char** argv) {
  CLI::App app{"bench_convert: YUYV / NV12 to RGB24 per kernel table"};
  std::string json_path;
  int reps = 15;
  app.add_option("--json", json_path, "also write the figures as JSON to this file");
  app.add_option("--reps", reps, "timed repetitions per case")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  const MachineInfo mi = machine_info();
  const double load0 = load_average();
  std::printf("bench_convert: %s, %s, load average %.2f, best table %s\n", mi.cpu_model.c_str(), format_mhz(mi).c_str(),
              load0, simd::best_kernel_table().isa);
  const auto tables = all_kernel_tables();
  HarnessOptions ho;
  ho.warmup = 2;
  ho.reps = reps;
  ho.min_reps = 3;
  ho.max_seconds = 1.5;

  std::vector<Row> rows;
  std::printf("  %-5s %-10s %-7s %10s %10s %10s %9s\n", "fmt", "size", "isa", "med ms", "min ms", "Mpx/s", "vs ref");
  const int sizes[2][2] = {{640, 480}, {1920, 1080}};
  for (const auto& s : sizes) {
    const int w = s[0], h = s[1];
    std::mt19937_64 rng(uint64_t(w) * 7 + uint64_t(h));
    // Unpadded planes, as V4L2 drivers usually deliver them at these widths.
    std::vector<uint8_t> yuyv(size_t(w) * size_t(h) * 2), y(size_t(w) * size_t(h)), uv(size_t(w) * size_t(h / 2));
    for (auto* v : {&yuyv, &y, &uv})
      for (uint8_t& b : *v) b = uint8_t(rng() >> 56);
    std::vector<uint8_t> rgb(size_t(w) * size_t(h) * 3);
    for (const char* fmt : {"yuyv", "nv12"}) {
      const bool is_yuyv = fmt[0] == 'y';
      double ref_min = 0;
      for (const simd::KernelTable* t : tables) {
        Row r;
        r.format = fmt;
        r.isa = t->isa;
        r.width = w;
        r.height = h;
        r.t = is_yuyv ? measure([&] { t->yuyv_to_rgb(w, h, yuyv.data(), 2 * w, rgb.data(), 3 * w); }, ho)
                      : measure([&] { t->nv12_to_rgb(w, h, y.data(), w, uv.data(), w, rgb.data(), 3 * w); }, ho);
        if (r.isa == "ref") ref_min = r.t.min_ms;
        const std::string size = std::to_string(w) + "x" + std::to_string(h);
        std::printf("  %-5s %-10s %-7s %10.3f %10.3f %10.1f", fmt, size.c_str(), r.isa.c_str(), r.t.median_ms, r.t.min_ms,
                    double(w) * h / (r.t.min_ms * 1e3));
        if (ref_min > 0 && r.isa != "ref") std::printf("   x%.2f", ref_min / r.t.min_ms);
        std::printf("\n");
        std::fflush(stdout);
        rows.push_back(r);
      }
    }
  }

  if (!json_path.empty()) {
    nlohmann::json j;
    j["tool"] = "bench_convert";
    j["cpu"] = mi.cpu_model;
    j["cpu_mhz"] = mi.cpu_mhz;
    j["best_isa"] = simd::best_kernel_table().isa;
    j["load_average"] = load0;
    j["rows"] = nlohmann::json::array();
    for (const Row& r : rows)
      j["rows"].push_back({{"format", r.format}, {"isa", r.isa}, {"width", r.width}, {"height", r.height},
                           {"reps", r.t.reps}, {"median_ms", r.t.median_ms}, {"min_ms", r.t.min_ms},
                           {"mpixel_per_s_at_min", double(r.width) * r.height / (r.t.min_ms * 1e3)}});
    if (!write_output(json_path, j.dump(2) + "\n", "bench_convert")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
