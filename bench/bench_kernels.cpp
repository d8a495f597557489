// SPDX-License-Identifier: MIT
// bench_kernels: microbenchmarks of the kernel tables in isolation, single-threaded: one 16x16
// tile of raster_fwd_tile / raster_bwd_tile with 64 and 512 splats a few pixels wide (ns per tile,
// splat-pixel evaluations per second), and project_fwd / project_bwd over 100k Gaussians
// (Gaussians per second). Prints a table and optionally writes JSON.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/ref.h"

namespace gs::bench {
namespace {

constexpr size_t kPad = 64;  // floats of slack after every buffer: kernels may over-read a vector's worth

// `count` packed splat records around a 16x16 tile at the image origin, sorted front to back:
// means uniform in [-4, 20]^2 px (some centred outside the tile but reaching in), per-axis sigma
// U(1, 3) px at a random angle plus the renderer's 0.3 px^2 dilation, opacity U(0.1, 0.9).
std::vector<float> tile_splats(int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  struct Rec {
    float v[simd::kSplatStride];
  };
  std::vector<Rec> recs(static_cast<size_t>(count));
  for (Rec& r : recs) {
    const double mx = -4 + 24 * u01(rng), my = -4 + 24 * u01(rng);
    const double s1 = 1 + 2 * u01(rng), s2 = 1 + 2 * u01(rng), th = 3.14159265358979 * u01(rng);
    const double c = std::cos(th), s = std::sin(th);
    const double xx = c * c * s1 * s1 + s * s * s2 * s2 + simd::kDilation;
    const double xy = c * s * (s1 * s1 - s2 * s2);
    const double yy = s * s * s1 * s1 + c * c * s2 * s2 + simd::kDilation;
    const double det = xx * yy - xy * xy;
    r.v[simd::kSplatMx] = float(mx);
    r.v[simd::kSplatMy] = float(my);
    r.v[simd::kSplatA] = float(yy / det);
    r.v[simd::kSplatB] = float(-xy / det);
    r.v[simd::kSplatC] = float(xx / det);
    r.v[simd::kSplatOpacity] = float(0.1 + 0.8 * u01(rng));
    r.v[simd::kSplatR] = float(u01(rng));
    r.v[simd::kSplatG] = float(u01(rng));
    r.v[simd::kSplatBlue] = float(u01(rng));
    r.v[simd::kSplatDepth] = float(2 + 8 * u01(rng));
    simd::splat_support(r.v + simd::kSplatA, r.v[simd::kSplatOpacity], r.v + simd::kSplatTwoTau);
  }
  std::sort(recs.begin(), recs.end(), [](const Rec& a, const Rec& b) { return a.v[simd::kSplatDepth] < b.v[simd::kSplatDepth]; });
  std::vector<float> out(size_t(count) * simd::kSplatStride + kPad, 0.0f);
  for (size_t i = 0; i < recs.size(); ++i) std::copy(recs[i].v, recs[i].v + simd::kSplatStride, &out[i * simd::kSplatStride]);
  return out;
}

// Splat-pixel pairs the reference forward walks over a tile: per pixel, splats are visited in order
// until the one that would push transmittance below 1e-4 (inclusive) or the end of the list.
double walked_fwd(const simd::RasterParams& rp, const float* splats, int count) {
  double total = 0;
  for (int y = 0; y < std::min(rp.height, simd::kTileSize); ++y)
    for (int x = 0; x < std::min(rp.width, simd::kTileSize); ++x) {
      float trans = 1.0f;
      int i = 0;
      for (; i < count; ++i) {
        simd::SplatEval<float> e;
        if (!simd::eval_splat_ref(splats + size_t(i) * simd::kSplatStride, float(x) + 0.5f, float(y) + 0.5f, &e)) continue;
        const float next = trans * (1.0f - e.alpha);
        if (next < simd::kTransmittanceMin) {
          ++i;
          break;
        }
        trans = next;
      }
      total += i;
    }
  return total;
}

struct TileRow {
  std::string isa;
  int count = 0;
  Timing fwd, bwd;
  double walked_fwd = 0, walked_bwd = 0;  // splat-pixel pairs per tile
};

struct ProjRow {
  std::string isa;
  size_t n = 0;
  Timing fwd, bwd;
};

int run(int argc, char** argv) {
  CLI::App app{"bench_kernels: per-table tile raster and projection microbenchmarks (single thread)"};
  int reps = 21;
  size_t project_n = 100000;
  std::string isa_s, json_path;
  app.add_option("--reps", reps, "timed repetitions per measurement")->capture_default_str();
  app.add_option("--project-count", project_n, "Gaussians for the projection benchmark")->capture_default_str();
  app.add_option("--isa", isa_s, "kernel tables to run, comma separated (default: all available)");
  app.add_option("--json", json_path, "write the results as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  std::vector<const simd::KernelTable*> tables;
  if (isa_s.empty()) {
    tables = all_kernel_tables();
  } else {
    for (const std::string& name : split_list(isa_s)) {
      const simd::KernelTable* t = simd::kernel_table_by_name(name.c_str());
      if (!t) {
        std::fprintf(stderr, "bench_kernels: kernel table '%s' is not available here\n", name.c_str());
        return 1;
      }
      tables.push_back(t);
    }
  }
  const MachineInfo mi = machine_info();
  std::printf("bench_kernels (single thread)\n");
  std::printf("  CPU:     %s, clock %s\n", mi.cpu_model.c_str(), format_mhz(mi).c_str());
  std::printf("  best:    %s\n", simd::best_kernel_table().isa);
  std::printf("  timing:  calls batched to >= 2 ms per repetition, %d reps, median and min per call; rates and\n"
              "           speed-ups use the min (the least disturbed repetition; microbenchmarks are sensitive to load)\n", reps);
  const double load0 = load_average();
  if (load0 >= 0)
    std::printf("  load:    %.2f (1-min average, %u hardware threads)%s\n", load0, mi.hw_threads,
                load0 > 0.75 * mi.hw_threads ? "; the machine is busy: prefer the min figures" : "");

  HarnessOptions ho;
  ho.warmup = 1;
  ho.reps = std::max(reps, 1);

  // --- one tile ---
  simd::RasterParams rp{};
  rp.width = simd::kTileSize;
  rp.height = simd::kTileSize;
  const size_t pixels = size_t(rp.width) * rp.height;
  std::vector<float> rgb(3 * pixels + kPad), final_T(pixels + kPad), v_rgb(3 * pixels + kPad);
  std::vector<int32_t> last(pixels + kPad);
  {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f);
    for (float& v : v_rgb) v = u(rng);
  }
  std::vector<TileRow> tile_rows;
  std::printf("\nTile raster: one 16x16 tile (256 px). walked = splat-pixel pairs the reference loop visits per tile\n"
              "(forward: up to the early stop; backward: up to each pixel's last contributor); Mev/s = walked / min time.\n");
  std::printf("  %-7s %6s  %10s %10s %9s %9s  %10s %10s %9s %9s\n", "isa", "splats", "fwd med ns", "min ns", "walked",
              "Mev/s", "bwd med ns", "min ns", "walked", "Mev/s");
  for (int count : {64, 512}) {
    const std::vector<float> splats = tile_splats(count, 100 + uint64_t(count));
    std::vector<float> v_splats(size_t(count) * simd::kSplatStride + kPad);
    const double wf = walked_fwd(rp, splats.data(), count);
    simd::ref_kernel_table().raster_fwd_tile(&rp, 0, 0, splats.data(), count, rgb.data(), final_T.data(), last.data(), nullptr);
    double wb = 0;
    for (size_t p = 0; p < pixels; ++p) wb += last[p];
    double ref_fwd = 0, ref_bwd = 0;
    for (const simd::KernelTable* t : tables) {
      TileRow row;
      row.isa = t->isa;
      row.count = count;
      row.walked_fwd = wf;
      row.walked_bwd = wb;
      row.fwd = measure_batched(
          [&] { t->raster_fwd_tile(&rp, 0, 0, splats.data(), count, rgb.data(), final_T.data(), last.data(), nullptr); }, ho);
      // The backward reads the forward's final T and last contributor: take them from this table.
      t->raster_fwd_tile(&rp, 0, 0, splats.data(), count, rgb.data(), final_T.data(), last.data(), nullptr);
      row.bwd = measure_batched(
          [&] { t->raster_bwd_tile(&rp, 0, 0, splats.data(), count, final_T.data(), last.data(), v_rgb.data(), v_splats.data()); }, ho);
      if (row.isa == "ref") ref_fwd = row.fwd.min_ms, ref_bwd = row.bwd.min_ms;
      const double fns = row.fwd.min_ms * 1e6, bns = row.bwd.min_ms * 1e6;
      std::printf("  %-7s %6d  %10.0f %10.0f %9.0f %9.1f  %10.0f %10.0f %9.0f %9.1f", row.isa.c_str(), count,
                  row.fwd.median_ms * 1e6, fns, wf, wf / fns * 1e3, row.bwd.median_ms * 1e6, bns, wb, wb / bns * 1e3);
      if (ref_fwd > 0 && row.isa != "ref")
        std::printf("   x%.2f fwd, x%.2f bwd vs ref", ref_fwd / row.fwd.min_ms, ref_bwd / row.bwd.min_ms);
      std::printf("\n");
      std::fflush(stdout);
      tile_rows.push_back(row);
    }
  }

  // --- projection ---
  const Camera cam = synthetic_camera(980, 545);
  const SyntheticScene scene = synthetic_scene(cam, project_n, 11);
  simd::ProjectParams pp{};
  for (int k = 0; k < 9; ++k) pp.R[k] = cam.pose.R[k];
  for (int k = 0; k < 3; ++k) pp.t[k] = cam.pose.t[k];
  pp.fx = cam.intr.fx;
  pp.fy = cam.intr.fy;
  pp.cx = cam.intr.cx;
  pp.cy = cam.intr.cy;
  pp.width = cam.intr.width;
  pp.height = cam.intr.height;
  simd::finish_project_params(&pp);
  const size_t n = project_n;
  std::vector<float> means2d(2 * n + kPad), conics(3 * n + kPad), depths(n + kPad);
  std::vector<int32_t> radii(n + kPad);
  std::vector<float> v_means2d(2 * n + kPad), v_conics(3 * n + kPad), v_means(3 * n + kPad), v_log_scales(3 * n + kPad),
      v_quats(4 * n + kPad);
  {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    for (float& v : v_means2d) v = u(rng);
    for (float& v : v_conics) v = u(rng);
  }
  std::vector<ProjRow> proj_rows;
  std::printf("\nProjection: %zu Gaussians (980x545 camera, synthetic scene), one call over all of them\n", n);
  std::printf("  %-7s  %10s %10s %10s  %10s %10s %10s\n", "isa", "fwd med ms", "min ms", "MG/s", "bwd med ms", "min ms",
              "MG/s");
  double ref_pf = 0, ref_pb = 0;
  HarnessOptions hp = ho;
  hp.max_seconds = 2.0;
  hp.min_reps = 3;
  for (const simd::KernelTable* t : tables) {
    ProjRow row;
    row.isa = t->isa;
    row.n = n;
    row.fwd = measure([&] {
      t->project_fwd(&pp, n, scene.means.data(), scene.log_scales.data(), scene.quats.data(), means2d.data(),
                     conics.data(), depths.data(), radii.data());
    }, hp);
    double v_pose[6] = {0, 0, 0, 0, 0, 0};
    row.bwd = measure([&] {
      t->project_bwd(&pp, n, scene.means.data(), scene.log_scales.data(), scene.quats.data(), radii.data(),
                     v_means2d.data(), v_conics.data(), nullptr, v_means.data(), v_log_scales.data(), v_quats.data(),
                     v_pose);
    }, hp);
    if (row.isa == "ref") ref_pf = row.fwd.min_ms, ref_pb = row.bwd.min_ms;
    std::printf("  %-7s  %10.3f %10.3f %10.1f  %10.3f %10.3f %10.1f", row.isa.c_str(), row.fwd.median_ms, row.fwd.min_ms,
                double(n) / row.fwd.min_ms * 1e-3, row.bwd.median_ms, row.bwd.min_ms, double(n) / row.bwd.min_ms * 1e-3);
    if (ref_pf > 0 && row.isa != "ref")
      std::printf("   x%.2f fwd, x%.2f bwd vs ref", ref_pf / row.fwd.min_ms, ref_pb / row.bwd.min_ms);
    std::printf("\n");
    std::fflush(stdout);
    proj_rows.push_back(row);
  }

  if (!json_path.empty()) {
    auto tj = [](const Timing& t) {
      return nlohmann::json{{"reps", t.reps}, {"min", t.min_ms}, {"median", t.median_ms}, {"mean", t.mean_ms}, {"max", t.max_ms}};
    };
    nlohmann::json j;
    j["tool"] = "bench_kernels";
    j["cpu"] = mi.cpu_model;
    j["cpu_mhz"] = mi.cpu_mhz;
    j["best_isa"] = simd::best_kernel_table().isa;
    j["load_average"] = load0;
    j["tile"] = nlohmann::json::array();
    for (const TileRow& r : tile_rows)
      j["tile"].push_back({{"isa", r.isa}, {"splats", r.count}, {"fwd_ms", tj(r.fwd)}, {"bwd_ms", tj(r.bwd)},
                           {"walked_fwd", r.walked_fwd}, {"walked_bwd", r.walked_bwd},
                           {"fwd_evals_per_s_at_min", r.walked_fwd / (r.fwd.min_ms * 1e-3)},
                           {"bwd_evals_per_s_at_min", r.walked_bwd / (r.bwd.min_ms * 1e-3)}});
    j["project"] = nlohmann::json::array();
    for (const ProjRow& r : proj_rows)
      j["project"].push_back({{"isa", r.isa}, {"count", r.n}, {"fwd_ms", tj(r.fwd)}, {"bwd_ms", tj(r.bwd)},
                              {"fwd_gaussians_per_s_at_min", double(r.n) / (r.fwd.min_ms * 1e-3)},
                              {"bwd_gaussians_per_s_at_min", double(r.n) / (r.bwd.min_ms * 1e-3)}});
    if (!write_output(json_path, j.dump(2) + "\n", "bench_kernels")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
