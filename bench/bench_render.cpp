// SPDX-License-Identifier: MIT
// bench_render: end-to-end timing of gs::Renderer forward and forward+backward on synthetic
// Gaussian scenes (or the views of a COLMAP dataset), for every kernel table and thread count,
// with the SIMD speed-up over the reference kernels and the 2-thread scaling. Prints a table and
// optionally writes JSON; --compare prints before/after ratios against an earlier JSON file.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/constants.h"
#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"
#if defined(GS_BENCH_HAVE_IO)
#include "gs/io/colmap.h"
#include "gs/io/ply.h"
#endif

namespace gs::bench {
namespace {

constexpr size_t kRefLimit = 100000;  // the ref table is skipped above this many Gaussians unless --all

// What one measurement renders: one parameter set seen from one or more cameras.
struct Workload {
  std::string label;  // "320x240" or the dataset name
  int max_width = 0, max_height = 0;
  size_t count = 0;
  GaussianParams params;
  std::vector<Camera> cameras;
};

struct Row {
  std::string label;
  int width = 0, height = 0;  // largest view
  size_t count = 0;
  int views = 1;
  std::string isa;
  int threads = 1;
  double visible = 0, isects = 0;  // per view
  Timing fwd, fwd_bwd;             // per view, ms
  double evals_per_s = 0;          // tile-pixel evaluations per second: isects * 256 / forward seconds
  double simd_fwd = 0, simd_fb = 0;    // ref median / this median, same threads (0: no ref row)
  double simd_fb_cpu = 0;              // same from process CPU time (robust on a busy machine at 1 thread)
  double scale_fwd = 0, scale_fb = 0;  // 1-thread median / this median, same ISA (0: 1-thread row or none)
};

struct Settings {
  int reps = 5;
  double max_seconds = 1.0;
  bool all = false;
  std::vector<const simd::KernelTable*> tables;
  std::vector<int> threads;
};

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "bench_render: %s\n", what.c_str());
  std::exit(1);
}

void check(const Status& s, const char* what) {
  if (!s.ok()) die(std::string(what) + ": " + s.to_string());
}

// Capacity from a dry forward of every view (inputs validated here, once): start from an estimate,
// retry with the reported intersection count (RenderStats is filled before the capacity check)
// plus 10% headroom.
RenderCapacity plan_capacity(const Workload& w, std::vector<float>& rgb) {
  RenderCapacity cap;
  cap.max_gaussians = std::max<size_t>(w.count, 1);
  cap.max_width = w.max_width;
  cap.max_height = w.max_height;
  cap.max_sh_degree = 0;
  cap.max_isects = std::max<size_t>(4 * w.count, 1 << 16);
  Renderer r;
  check(r.init(cap, nullptr), "init (dry run)");
  RenderOptions opt;
  for (const Camera& cam : w.cameras) {
    for (int attempt = 0;; ++attempt) {
      const Status s = r.forward(cam, w.params, opt, rgb.data());
      if (s.ok()) break;
      if (s.code() != StatusCode::kCapacityExceeded || attempt > 3) check(s, "dry forward");
      cap.max_isects = std::max(cap.max_isects, r.stats().isects + r.stats().isects / 10 + 1024);
      check(r.init(cap, nullptr), "init (dry run, larger capacity)");
    }
  }
  return cap;
}

struct Buffers {
  std::vector<float> rgb, v_rgb;
  std::vector<float> v_means, v_log_scales, v_quats, v_opacities, v_colors, v_means2d;
  GaussianGrads grads;

  Buffers(size_t pixels, size_t n) : rgb(3 * pixels), v_rgb(3 * pixels) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f);
    for (float& v : v_rgb) v = u(rng);
    v_means.resize(3 * n);
    v_log_scales.resize(3 * n);
    v_quats.resize(4 * n);
    v_opacities.resize(n);
    v_colors.resize(3 * n);
    v_means2d.resize(2 * n);
    grads = colored_gaussian_grads(v_means.data(), v_log_scales.data(), v_quats.data(), v_opacities.data(),
                                   v_colors.data(), v_means2d.data());
  }
};

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

std::string ratio(double v) { return v > 0 ? fmt("%.2fx", v) : std::string("-"); }

void print_header() {
  std::printf("  %-7s %3s  %9s %9s  %9s %9s %9s  %7s %7s  %6s %6s  %9s %10s  %7s\n", "isa", "thr", "fwd med", "fwd min",
              "f+b med", "f+b min", "f+b cpu", "fwd/ref", "f+b/ref", "2T fwd", "2T f+b", "visible", "isects", "Gtpe/s");
}

void print_row(const Row& r) {
  std::printf("  %-7s %3d  %9.2f %9.2f  %9.2f %9.2f %9.2f  %7s %7s  %6s %6s  %9.0f %10.0f  %7.3f\n", r.isa.c_str(),
              r.threads, r.fwd.median_ms, r.fwd.min_ms, r.fwd_bwd.median_ms, r.fwd_bwd.min_ms, r.fwd_bwd.cpu_median_ms,
              ratio(r.simd_fwd).c_str(),
              ratio(r.simd_fb).c_str(), ratio(r.scale_fwd).c_str(), ratio(r.scale_fb).c_str(), r.visible, r.isects,
              r.evals_per_s * 1e-9);
  std::fflush(stdout);
}

// Runs every (table, threads) configuration on a workload; appends rows, prints as it goes.
void run_workload(const Workload& w, const Settings& st,
                  std::map<int, std::unique_ptr<platform::ThreadPool>>& pools, std::vector<Row>& rows,
                  std::vector<std::string>& skipped) {
  Buffers buf(size_t(w.max_width) * w.max_height, w.count);
  const uint64_t t_plan = platform::now_ns();
  const RenderCapacity cap = plan_capacity(w, buf.rgb);
  std::printf("\n== %s, %s Gaussians, %zu view%s (capacity %zu isects, arena %.1f MiB, planned in %.2f s)\n",
              w.label.c_str(), count_label(w.count).c_str(), w.cameras.size(), w.cameras.size() == 1 ? "" : "s",
              cap.max_isects, double(Renderer::plan_bytes(cap)) / (1 << 20), double(platform::now_ns() - t_plan) * 1e-9);
  print_header();
  const size_t first_row = rows.size();
  const RenderOptions opt = [] {
    RenderOptions o;
    o.validate_inputs = false;  // time the renderer, not the O(N) NaN scan
    return o;
  }();
  HarnessOptions ho;
  ho.warmup = 0;  // the statistics pass below warms up
  ho.reps = st.reps;
  ho.min_reps = std::min(st.reps, 2);
  ho.max_seconds = st.max_seconds;
  const double views = double(w.cameras.size());

  for (const simd::KernelTable* table : st.tables) {
    const bool is_ref = std::string(table->isa) == "ref";
    if (is_ref && w.count > kRefLimit && !st.all) {
      skipped.push_back(w.label + " " + count_label(w.count) + ": ref skipped (> " + count_label(kRefLimit) +
                        " Gaussians; --all to include)");
      std::printf("  %-7s       (skipped above %s Gaussians: very slow; pass --all to include)\n", "ref",
                  count_label(kRefLimit).c_str());
      continue;
    }
    for (int threads : st.threads) {
      platform::ThreadPool* pool = pools.at(threads).get();
      Renderer r;
      check(r.init(cap, pool, table), "init");
      Row row;
      row.label = w.label;
      row.width = w.max_width;
      row.height = w.max_height;
      row.count = w.count;
      row.views = int(w.cameras.size());
      row.isa = table->isa;
      row.threads = pool->num_threads();
      // One untimed forward+backward pass: the warm-up (first touch of the arena and gradient
      // buffers) and the statistics, which do not depend on timing.
      for (const Camera& cam : w.cameras) {
        check(r.forward(cam, w.params, opt, buf.rgb.data()), "forward");
        row.visible += double(r.stats().visible) / views;
        row.isects += double(r.stats().isects) / views;
        check(r.backward(buf.v_rgb.data(), &buf.grads), "backward");
      }
      // A repetition is one pass over the views; per view the forward is timed alone ("fwd") and
      // together with the backward that follows it ("f+b"), so both figures come from the same runs.
      std::vector<double> f_ms, fb_ms, f_cpu, fb_cpu;
      double spent = 0;
      for (int rep = 0; rep < std::max(ho.reps, 1); ++rep) {
        if (ho.max_seconds > 0 && rep >= ho.min_reps && spent >= ho.max_seconds) break;
        double pf = 0, pfb = 0, cf = 0, cfb = 0;
        for (const Camera& cam : w.cameras) {
          const double c0 = process_cpu_seconds();
          const uint64_t t0 = platform::now_ns();
          check(r.forward(cam, w.params, opt, buf.rgb.data()), "forward");
          const uint64_t t1 = platform::now_ns();
          const double c1 = process_cpu_seconds();
          check(r.backward(buf.v_rgb.data(), &buf.grads), "backward");
          const uint64_t t2 = platform::now_ns();
          const double c2 = process_cpu_seconds();
          pf += double(t1 - t0) * 1e-6;
          pfb += double(t2 - t0) * 1e-6;
          cf += (c1 - c0) * 1e3;
          cfb += (c2 - c0) * 1e3;
        }
        f_ms.push_back(pf);
        fb_ms.push_back(pfb);
        f_cpu.push_back(cf);
        fb_cpu.push_back(cfb);
        spent += pfb * 1e-3;
      }
      row.fwd = summarize(f_ms, f_cpu);
      row.fwd_bwd = summarize(fb_ms, fb_cpu);
      for (Timing* t : {&row.fwd, &row.fwd_bwd}) {
        t->cpu_median_ms /= views;
        t->min_ms /= views;
        t->median_ms /= views;
        t->mean_ms /= views;
        t->max_ms /= views;
      }
      row.evals_per_s = row.isects * 256.0 / (row.fwd.median_ms * 1e-3);
      for (size_t i = first_row; i < rows.size(); ++i) {
        const Row& o = rows[i];
        if (o.isa == "ref" && o.threads == row.threads && row.isa != "ref") {
          row.simd_fwd = o.fwd.median_ms / row.fwd.median_ms;
          row.simd_fb = o.fwd_bwd.median_ms / row.fwd_bwd.median_ms;
          if (row.fwd_bwd.cpu_median_ms > 0) row.simd_fb_cpu = o.fwd_bwd.cpu_median_ms / row.fwd_bwd.cpu_median_ms;
        }
        if (o.isa == row.isa && o.threads == 1 && row.threads > 1) {
          row.scale_fwd = o.fwd.median_ms / row.fwd.median_ms;
          row.scale_fb = o.fwd_bwd.median_ms / row.fwd_bwd.median_ms;
        }
      }
      rows.push_back(row);
      print_row(row);
    }
  }
}

void print_summary(const std::vector<Row>& rows, const std::string& best_isa) {
  std::printf("\nSummary (median ms per frame; best ISA = %s; simd = ref / %s at 1 thread (at 2 if only 2 ran);\n"
              "  simd cpu = the same from 1-thread f+b process CPU time; 2T = 1 thread / 2 threads)\n",
              best_isa.c_str(), best_isa.c_str());
  std::printf("  %-12s %6s  %9s %9s  %9s %9s  %9s %9s %9s  %9s %9s\n", "workload", "N", "fwd 1T", "fwd 2T", "f+b 1T",
              "f+b 2T", "simd fwd", "simd f+b", "simd cpu", "2T fwd", "2T f+b");
  std::vector<std::pair<std::string, size_t>> seen;
  for (const Row& r : rows) {
    const auto key = std::make_pair(r.label, r.count);
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) continue;
    seen.push_back(key);
    const Row *one = nullptr, *two = nullptr;
    for (const Row& o : rows)
      if (o.label == r.label && o.count == r.count && o.isa == best_isa) {
        if (o.threads == 1) one = &o;
        if (o.threads == 2) two = &o;
      }
    if (!one && !two) continue;
    auto ms = [](const Row* p, bool fb) { return p ? fmt("%.2f", fb ? p->fwd_bwd.median_ms : p->fwd.median_ms) : std::string("-"); };
    const Row* any = one ? one : two;
    std::printf("  %-12s %6s  %9s %9s  %9s %9s  %9s %9s %9s  %9s %9s\n", r.label.c_str(), count_label(r.count).c_str(),
                ms(one, false).c_str(), ms(two, false).c_str(), ms(one, true).c_str(), ms(two, true).c_str(),
                ratio(any->simd_fwd).c_str(), ratio(any->simd_fb).c_str(), ratio(one ? one->simd_fb_cpu : 0).c_str(),
                ratio(two ? two->scale_fwd : 0).c_str(), ratio(two ? two->scale_fb : 0).c_str());
  }
}

nlohmann::json timing_json(const Timing& t) {
  return {{"reps", t.reps},        {"min", t.min_ms}, {"median", t.median_ms}, {"mean", t.mean_ms},
          {"max", t.max_ms}, {"cpu_median", t.cpu_median_ms}};
}

void compare_with(const std::string& path, const std::vector<Row>& rows) {
  std::ifstream f(path);
  if (!f) die("cannot open --compare file " + path);
  nlohmann::json base;
  try {
    f >> base;
  } catch (const std::exception& e) {
    die("cannot parse --compare file " + path + ": " + e.what());
  }
  std::printf("\nCompared with %s (ratio = before / after median; > 1 means faster now)\n", path.c_str());
  if (base.contains("cpu")) std::printf("  before: %s\n", base["cpu"].get<std::string>().c_str());
  std::printf("  %-12s %6s %-7s %3s  %9s %9s %7s  %9s %9s %7s\n", "workload", "N", "isa", "thr", "fwd bef", "fwd aft",
              "ratio", "f+b bef", "f+b aft", "ratio");
  for (const Row& r : rows) {
    for (const auto& b : base.value("results", nlohmann::json::array())) {
      if (b.value("label", "") != r.label || b.value("count", size_t(0)) != r.count || b.value("isa", "") != r.isa ||
          b.value("threads", 0) != r.threads)
        continue;
      const double bf = b["fwd_ms"]["median"].get<double>(), bb = b["fwd_bwd_ms"]["median"].get<double>();
      std::printf("  %-12s %6s %-7s %3d  %9.2f %9.2f %6.2fx  %9.2f %9.2f %6.2fx\n", r.label.c_str(),
                  count_label(r.count).c_str(), r.isa.c_str(), r.threads, bf, r.fwd.median_ms, bf / r.fwd.median_ms, bb,
                  r.fwd_bwd.median_ms, bb / r.fwd_bwd.median_ms);
    }
  }
}

#if defined(GS_BENCH_HAVE_IO)
// Mean distance of every point to its k nearest other points, through a hashed uniform grid
// (cells ~2 points on average over the robust extent) searched in growing Chebyshev shells until the
// shell radius covers the k-th best distance. Points whose neighbours lie beyond 16 shells (far
// outliers, usually a handful) fall back to a brute-force scan.
std::vector<float> mean_knn_distance(const std::vector<float>& xyz, int k) {
  const size_t n = xyz.size() / 3;
  std::vector<float> out(n, 0.0f);
  if (n < 2) {
    std::fill(out.begin(), out.end(), 0.01f);
    return out;
  }
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    std::vector<float> v(n);
    for (size_t i = 0; i < n; ++i) v[i] = xyz[3 * i + a];
    const size_t i0 = n / 50, i1 = n - 1 - n / 50;
    std::nth_element(v.begin(), v.begin() + i0, v.end());
    lo[a] = v[i0];
    std::nth_element(v.begin(), v.begin() + i1, v.end());
    hi[a] = v[i1];
  }
  const double vol = std::max(hi[0] - lo[0], 1e-6) * std::max(hi[1] - lo[1], 1e-6) * std::max(hi[2] - lo[2], 1e-6);
  const double cell = std::max(std::cbrt(vol * 2.0 / double(n)), 1e-9);
  auto cell_of = [&](size_t i, int a) {
    const double v = std::floor((xyz[3 * i + a] - lo[a]) / cell);
    return int64_t(std::max(-1e12, std::min(1e12, v)));  // far outliers share border cells; still exact distances
  };
  auto hash = [](int64_t x, int64_t y, int64_t z) {
    uint64_t h = uint64_t(x) * 0x9E3779B97F4A7C15ull ^ uint64_t(y) * 0xC2B2AE3D27D4EB4Full ^ uint64_t(z) * 0x165667B19E3779F9ull;
    return h ^ (h >> 29);
  };
  // Points sorted by cell hash. Cells that share a hash share a range, so a visit filters on the
  // exact cell: otherwise a point could be counted twice.
  std::vector<int64_t> cells(3 * n);
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) cells[3 * i + a] = cell_of(i, a);
  std::vector<std::pair<uint64_t, uint32_t>> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = {hash(cells[3 * i], cells[3 * i + 1], cells[3 * i + 2]), uint32_t(i)};
  std::sort(order.begin(), order.end());
  std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> ranges;
  for (size_t b = 0; b < n;) {
    size_t e = b;
    while (e < n && order[e].first == order[b].first) ++e;
    ranges[order[b].first] = {uint32_t(b), uint32_t(e)};
    b = e;
  }
  constexpr int kMaxShell = 16;
  std::vector<float> best;
  for (size_t i = 0; i < n; ++i) {
    best.clear();
    const int64_t* c = &cells[3 * i];
    const float* p = &xyz[3 * i];
    auto consider = [&](uint32_t j) {
      const float* q = &xyz[3 * size_t(j)];
      const float d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
      if (int(best.size()) < k) {
        best.push_back(d2);
        std::push_heap(best.begin(), best.end());
      } else if (d2 < best.front()) {
        std::pop_heap(best.begin(), best.end());
        best.back() = d2;
        std::push_heap(best.begin(), best.end());
      }
    };
    auto visit = [&](int64_t x, int64_t y, int64_t z) {
      const auto it = ranges.find(hash(x, y, z));
      if (it == ranges.end()) return;
      for (uint32_t s = it->second.first; s < it->second.second; ++s) {
        const uint32_t j = order[s].second;
        if (j != i && cells[3 * size_t(j)] == x && cells[3 * size_t(j) + 1] == y && cells[3 * size_t(j) + 2] == z)
          consider(j);
      }
    };
    bool complete = false;
    for (int r = 0; r <= kMaxShell && !complete; ++r) {
      for (int64_t dz = -r; dz <= r; ++dz)
        for (int64_t dy = -r; dy <= r; ++dy)
          for (int64_t dx = -r; dx <= r; ++dx)
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) == r) visit(c[0] + dx, c[1] + dy, c[2] + dz);
      // Every point within r * cell of p has been visited (p lies inside its own cell).
      complete = int(best.size()) == k && double(best.front()) <= (double(r) * cell) * (double(r) * cell);
    }
    if (!complete) {  // an outlier far from the rest: brute force over every point
      best.clear();
      for (size_t j = 0; j < n; ++j)
        if (j != i) consider(uint32_t(j));
    }
    double sum = 0;
    for (float d2 : best) sum += std::sqrt(double(d2));
    out[i] = float(sum / double(best.size()));
  }
  return out;
}

// A trained scene's Gaussians (a 3DGS .ply, for example `hbgs export RUN --out model.ply`) as colour
// input: opacity = sigmoid(logit), colour = the SH DC term (0.5 + C0 f_dc, clamped to [0, 1]), so
// the tile kernels see a trained model's splat sizes, opacities and overlap instead of SfM blobs.
void load_ply_gaussians(const std::string& path, ColoredGaussians& s) {
  Expected<GaussianCloud> cloud = io::read_splat_ply(path);
  if (!cloud.ok()) die("read_splat_ply(" + path + "): " + cloud.status().to_string());
  const GaussianCloud& c = cloud.value();
  const size_t n = c.size(), k = size_t(sh_coeff_count(c.sh_degree));
  if (n == 0) die(path + " holds no Gaussians");
  constexpr float kShC0 = float(gs::kShC0);
  s.means = c.means;
  s.log_scales = c.log_scales;
  s.quats = c.quats;
  s.opacities.resize(n);
  s.colors.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    s.opacities[i] = 1.0f / (1.0f + std::exp(-c.opacity_logits[i]));
    for (int ch = 0; ch < 3; ++ch)
      s.colors[3 * i + ch] = std::clamp(0.5f + kShC0 * c.sh[i * k * 3 + size_t(ch)], 0.0f, 1.0f);
  }
  std::printf("Gaussians from %s: %zu (SH degree %d, DC colour used)\n", path.c_str(), n, c.sh_degree);
}

Workload dataset_workload(const std::string& dir, const std::string& ply, int max_width, int max_views,
                          ColoredGaussians& s) {
  io::DatasetOptions dopt;
  dopt.max_width = max_width;
  dopt.llffhold = 0;
  const uint64_t t0 = platform::now_ns();
  Expected<io::Dataset> ds = io::load_dataset(dir, dopt);
  if (!ds.ok()) die("load_dataset(" + dir + "): " + ds.status().to_string());
  const io::Dataset& d = ds.value();
  if (d.views.empty()) die("dataset " + dir + " has no views");
  Workload w;
  const size_t nv = max_views > 0 ? std::min(d.views.size(), size_t(max_views)) : d.views.size();
  // Spread the chosen views over the whole capture rather than taking the first few.
  for (size_t v = 0; v < nv; ++v) {
    const io::DatasetView& view = d.views[v * d.views.size() / nv];
    w.cameras.push_back(view.camera);
    w.max_width = std::max(w.max_width, view.camera.intr.width);
    w.max_height = std::max(w.max_height, view.camera.intr.height);
  }
  std::string name = dir;
  while (name.size() > 1 && name.back() == '/') name.pop_back();
  const size_t slash = name.find_last_of('/');
  w.label = slash == std::string::npos ? name : name.substr(slash + 1);
  if (!ply.empty()) {
    load_ply_gaussians(ply, s);
    w.label += "+ply";
    w.count = s.opacities.size();
    w.params = s.params();
    return w;
  }
  const size_t n = d.points_xyz.size() / 3;
  if (n == 0) die("dataset " + dir + " has no SfM points");
  const double t_load = double(platform::now_ns() - t0) * 1e-9;
  const uint64_t t1 = platform::now_ns();
  const std::vector<float> dist = mean_knn_distance(d.points_xyz, 3);
  std::printf("Dataset %s: %zu views, %zu SfM points (loaded in %.2f s, 3-NN scales in %.2f s)\n", dir.c_str(),
              d.views.size(), n, t_load, double(platform::now_ns() - t1) * 1e-9);
  // Isotropic scale = mean distance to the 3 nearest points, floored so coincident points stay valid.
  std::vector<float> sorted = dist;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const float floor_scale = std::max(1e-3f * sorted[sorted.size() / 2], 1e-7f);
  s.means = d.points_xyz;
  s.log_scales.resize(3 * n);
  s.quats.assign(4 * n, 0.0f);
  s.opacities.assign(n, 0.8f);
  s.colors.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    const float ls = std::log(std::max(dist[i], floor_scale));
    for (int k = 0; k < 3; ++k) {
      s.log_scales[3 * i + k] = ls;
      s.colors[3 * i + k] = float(d.points_rgb[3 * i + k]) / 255.0f;
    }
    s.quats[4 * i] = 1.0f;
  }
  w.count = n;
  w.params = s.params();
  return w;
}
#endif

int run(int argc, char** argv) {
  CLI::App app{"bench_render: gs::Renderer forward and forward+backward timings"};
  std::string sizes_s = "320x240,980x545", counts_s = "10k,100k,1M", isa_s, threads_s = "1,2", json_path,
              compare_path, dataset_dir, ply_path;
  int reps = 5, max_width = 0, max_views = 8;
  double max_seconds = 1.0;
  uint64_t seed = 1;
  bool quick = false, all = false;
  app.add_option("--sizes", sizes_s, "image sizes WxH, comma separated")->capture_default_str();
  app.add_option("--counts", counts_s, "Gaussian counts (10000, 100k, 1M), comma separated")->capture_default_str();
  app.add_option("--reps", reps, "timed forward+backward repetitions per configuration (after 1 untimed pass)")->capture_default_str();
  app.add_option("--max-seconds", max_seconds,
                 "stop adding repetitions once a configuration has been timed this long (at least 2 reps; 0: no limit)")
      ->capture_default_str();
  app.add_option("--isa", isa_s, "kernel tables to run, comma separated (default: all available)");
  app.add_option("--threads", threads_s, "thread counts, comma separated")->capture_default_str();
  app.add_option("--seed", seed, "scene seed")->capture_default_str();
  app.add_flag("--quick", quick, "fast subset: 320x240, 10k and 100k Gaussians, 3 reps");
  app.add_flag("--all", all, "also run the ref kernels above 100k Gaussians (very slow)");
  app.add_option("--json", json_path, "write the results as JSON to this file");
  app.add_option("--compare", compare_path, "print before/after ratios against an earlier --json file");
  app.add_option("--dataset", dataset_dir, "render the views of a COLMAP dataset instead of synthetic scenes");
  app.add_option("--ply", ply_path,
                 "--dataset: render these Gaussians (a 3DGS .ply, e.g. from hbgs export) instead of the SfM points");
  app.add_option("--max-width", max_width, "--dataset: downscale images to at most this width (0: as stored)");
  app.add_option("--max-views", max_views, "--dataset: views per pass, spread over the capture (0: all)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (!ply_path.empty() && dataset_dir.empty()) die("--ply needs --dataset (the views to render it from)");

  if (quick) {
    if (app.count("--sizes") == 0) sizes_s = "320x240";
    if (app.count("--counts") == 0) counts_s = "10k,100k";
    if (app.count("--reps") == 0) reps = 3;
  }
  Settings st;
  st.reps = std::max(reps, 1);
  st.max_seconds = max_seconds;
  st.all = all;
  std::vector<std::pair<int, int>> sizes;
  std::vector<size_t> counts;
  try {
    for (const std::string& s : split_list(sizes_s)) {
      int w, h;
      parse_size(s, &w, &h);
      sizes.emplace_back(w, h);
    }
    for (const std::string& s : split_list(counts_s)) counts.push_back(parse_count(s));
    for (const std::string& s : split_list(threads_s)) {
      const int t = std::stoi(s);
      if (t < 1 || t > 256) throw std::invalid_argument("thread count out of range: " + s);
      st.threads.push_back(t);
    }
  } catch (const std::exception& e) {
    die(e.what());
  }
  const std::vector<const simd::KernelTable*> available = all_kernel_tables();
  if (isa_s.empty()) {
    st.tables = available;
  } else {
    for (const std::string& name : split_list(isa_s)) {
      const simd::KernelTable* t = simd::kernel_table_by_name(name.c_str());
      if (!t) die("kernel table '" + name + "' is not compiled in or not supported by this CPU");
      st.tables.push_back(t);
    }
  }
  if (st.tables.empty() || st.threads.empty()) die("nothing to run");

  std::map<int, std::unique_ptr<platform::ThreadPool>> pools;
  for (int t : st.threads)
    if (!pools.count(t)) pools[t] = std::make_unique<platform::ThreadPool>(t);

  const MachineInfo mi = machine_info();
  const std::string best_isa = simd::best_kernel_table().isa;
  std::string table_names, thread_names;
  for (const auto* t : st.tables) table_names += std::string(table_names.empty() ? "" : ", ") + t->isa;
  for (int t : st.threads)
    thread_names += std::string(thread_names.empty() ? "" : ", ") + std::to_string(t) + " (pool has " +
                    std::to_string(pools[t]->num_threads()) + ")";
  std::printf("bench_render\n");
  std::printf("  CPU:          %s, %u hardware threads, clock %s\n", mi.cpu_model.c_str(), mi.hw_threads,
              format_mhz(mi).c_str());
  std::printf("  kernels:      %s (best for this CPU: %s)\n", table_names.c_str(), best_isa.c_str());
  std::printf("  threads:      %s\n", thread_names.c_str());
  std::printf("  timing:       per configuration 1 untimed forward+backward, then up to %d timed forward+backward\n"
              "                repetitions (at least %d; no new one after %.1f s); min and median ms per frame\n",
              st.reps, std::min(st.reps, 2), st.max_seconds);
  std::printf("  options:      colour input (no SH), no depth image, input validation off, all gradients requested\n");
  if (dataset_dir.empty())
    std::printf("  scene:        seed %llu; Gaussians uniform in the frustum at depth 2..10, projected sigma 0.5-2.5 px,\n"
                "                random rotations, opacity U(0.1,0.9); camera fx = 0.8 W\n",
                (unsigned long long)seed);
  else if (!ply_path.empty())
    std::printf("  scene:        the Gaussians of %s (colour = SH DC term); times are per view\n", ply_path.c_str());
  else
    std::printf("  scene:        one Gaussian per SfM point: isotropic scale = mean distance to the 3 nearest points,\n"
                "                identity rotation, opacity 0.8, colour = point RGB; times are per view\n");
  std::printf("  columns:      fwd = forward; f+b = forward + backward; x/ref = ref median / this median (same threads);\n"
              "                f+b cpu = process CPU ms (all threads) of a median repetition;\n"
              "                2T = 1-thread median / 2-thread median (same ISA); visible = Gaussians with radius > 0;\n"
              "                isects = Gaussian-tile intersections; Gtpe/s = tile-pixel evaluations per second, defined\n"
              "                as isects * 256 / forward seconds (every intersection visits its tile's 16x16 pixels), in 1e9/s\n");
  if (!st.all) std::printf("  note:         ref is skipped above %s Gaussians (very slow); --all includes it\n", count_label(kRefLimit).c_str());

  const double load0 = load_average();
  if (load0 > 0) std::printf("  load:         %.2f (1-min average) at start%s\n", load0,
                             load0 > 0.75 * mi.hw_threads ? "; the machine is busy: wall times are inflated, compare min/cpu" : "");

  std::vector<Row> rows;
  std::vector<std::string> skipped;
  const uint64_t t_start = platform::now_ns();
  if (!dataset_dir.empty()) {
#if defined(GS_BENCH_HAVE_IO)
    ColoredGaussians ds;
    const Workload w = dataset_workload(dataset_dir, ply_path, max_width, max_views, ds);
    run_workload(w, st, pools, rows, skipped);
#else
    (void)max_width;
    (void)max_views;
    (void)ply_path;
    die("--dataset needs gs_io, which this build does not have");
#endif
  } else {
    for (const auto& [width, height] : sizes) {
      for (size_t n : counts) {
        const SyntheticScene scene = synthetic_scene(synthetic_camera(width, height), n, seed + n);
        Workload w;
        w.label = std::to_string(width) + "x" + std::to_string(height);
        w.max_width = width;
        w.max_height = height;
        w.count = n;
        w.params = scene.params();
        w.cameras = {scene.camera};
        run_workload(w, st, pools, rows, skipped);
      }
    }
  }
  print_summary(rows, best_isa);
  for (const std::string& s : skipped) std::printf("  note: %s\n", s.c_str());
  const double load1 = load_average();
  std::printf("\nTotal %.1f s; load average %.2f at start, %.2f at end (%u hardware threads)\n",
              double(platform::now_ns() - t_start) * 1e-9, load0, load1, mi.hw_threads);

  if (!compare_path.empty()) compare_with(compare_path, rows);
  if (!json_path.empty()) {
    nlohmann::json j;
    j["tool"] = "bench_render";
    j["cpu"] = mi.cpu_model;
    j["cpu_mhz"] = mi.cpu_mhz;
    j["cpu_max_mhz"] = mi.max_mhz;
    j["hardware_threads"] = mi.hw_threads;
    j["best_isa"] = best_isa;
    j["seed"] = seed;
    j["reps"] = st.reps;
    j["time"] = double(std::time(nullptr));
    j["load_average"] = {load0, load1};
    j["definitions"] = {
        {"fwd_ms", "median/min/mean/max wall time of Renderer::forward per frame, ms"},
        {"fwd_bwd_ms", "wall time of Renderer::forward followed by Renderer::backward per frame, ms"},
        {"tile_pixel_evals_per_s", "isects * 256 / forward seconds (median)"},
        {"speedup_vs_ref", "ref median / this median at the same thread count"},
        {"scaling_vs_1_thread", "1-thread median / this median for the same ISA"}};
    nlohmann::json res = nlohmann::json::array();
    for (const Row& r : rows) {
      res.push_back({{"label", r.label},
                     {"width", r.width},
                     {"height", r.height},
                     {"count", r.count},
                     {"views", r.views},
                     {"isa", r.isa},
                     {"threads", r.threads},
                     {"visible", r.visible},
                     {"isects", r.isects},
                     {"fwd_ms", timing_json(r.fwd)},
                     {"fwd_bwd_ms", timing_json(r.fwd_bwd)},
                     {"tile_pixel_evals_per_s", r.evals_per_s},
                     {"speedup_vs_ref", {{"fwd", r.simd_fwd}, {"fwd_bwd", r.simd_fb}, {"fwd_bwd_cpu", r.simd_fb_cpu}}},
                     {"scaling_vs_1_thread", {{"fwd", r.scale_fwd}, {"fwd_bwd", r.scale_fb}}}});
    }
    j["results"] = res;
    j["skipped"] = skipped;
    if (!write_output(json_path, j.dump(2) + "\n", "bench_render")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
