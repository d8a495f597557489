// SPDX-License-Identifier: MIT
// bench_train: end-to-end training-step timing on a COLMAP dataset (default
// ../shared/data/snowmiku_plush): untimed warm-up iterations, then median / mean / p90 iteration
// milliseconds with the anchor and Gaussian counts, the kernel ISA and the thread count. It times
// the library's training job (gs::jobs::TrainSession) with the job's own defaults, so it runs the
// configuration `hbgs train` runs for the same dataset, seed and iterations (warm-up + timed).
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/simd/kernel_table.h"

#ifndef GS_BENCH_DEFAULT_DATASET
#define GS_BENCH_DEFAULT_DATASET "../shared/data/snowmiku_plush"
#endif

namespace gs::bench {
namespace {

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "bench_train: %s\n", what.c_str());
  std::exit(1);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
  return v[i];
}

int run(int argc, char** argv) {
  CLI::App app{"bench_train: training iteration timings of the hybrid anchor model on a COLMAP dataset"};
  jobs::TrainRunOptions o;  // the job's defaults, as `hbgs train` has them
  o.dataset = GS_BENCH_DEFAULT_DATASET;
  std::string json_path;
  int iterations = 300, warmup = 20;
  app.add_option("--dataset", o.dataset, "COLMAP dataset with SfM points")->capture_default_str();
  app.add_option("--iterations", iterations, "timed iterations")->capture_default_str()->check(CLI::Range(1, 10000000));
  app.add_option("--warmup", warmup, "untimed iterations first")->capture_default_str()->check(CLI::Range(0, 10000000));
  app.add_option("--threads", o.threads, "worker threads (0: all CPUs)")->capture_default_str();
  app.add_option("--max-width", o.max_width, "downscale images to at most this width (0: as stored)")->capture_default_str();
  app.add_option("--isa", o.isa, "kernel table (default: the best for this CPU)");
  app.add_option("--image-features", o.image_features, "paper, visible or none")->capture_default_str()->check(CLI::IsMember({"paper", "visible", "none"}));
  app.add_option("--seed", o.seed, "model and view-order seed")->capture_default_str();
  app.add_option("--json", json_path, "write the results (and every iteration's loss) as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  if (!platform::is_directory(o.dataset)) {
    std::printf("bench_train: skipped: dataset %s not found (pass --dataset DIR)\n", o.dataset.c_str());
    return 0;
  }
  // The learning-rate schedules span warm-up + timed iterations, as a run of that length would.
  o.iterations = warmup + iterations;
  Expected<std::unique_ptr<jobs::TrainSession>> session = jobs::TrainSession::create(o, nullptr);
  if (!session.ok()) die(session.status().to_string());
  model::Trainer& trainer = (*session)->trainer();
  platform::ThreadPool& pool = (*session)->pool();
  const std::vector<const io::DatasetView*>& views = (*session)->train_views();
  const simd::KernelTable* kernels = &(*session)->kernels();
  const std::string& dataset = o.dataset;
  const std::string& features = o.image_features;

  std::vector<float> losses;
  std::vector<double> ms;
  double gaussians = 0, anchors = 0;
  size_t max_gaussians = 0, max_isects = 0;  // per iteration (what the renderer's plan must hold)
  double cpu0 = process_cpu_seconds();
  for (int i = 0; i < warmup + iterations; ++i) {
    if (i == warmup) cpu0 = process_cpu_seconds();
    model::IterationStats st;
    const uint64_t t0 = platform::now_ns();
    if (Status s = trainer.step(&st); !s.ok()) die("iteration " + std::to_string(i + 1) + ": " + s.to_string());
    losses.push_back(float(st.step.loss));
    if (i < warmup) continue;
    ms.push_back(double(platform::now_ns() - t0) * 1e-6);
    gaussians += double(st.step.gaussians);
    max_gaussians = std::max(max_gaussians, st.step.gaussians);
    max_isects = std::max(max_isects, st.isects);
    anchors = double(st.anchors);
  }
  const double cpu_ms = (process_cpu_seconds() - cpu0) * 1e3 / double(iterations);
  const Timing t = summarize(ms);
  const double p90 = percentile(ms, 0.9);
  const MachineInfo mi = machine_info();
  const int w = views.front()->camera.intr.width, h = views.front()->camera.intr.height;
  std::printf("bench_train: %s, %zu training views at %dx%d, image features %s\n", dataset.c_str(), views.size(), w, h,
              features.c_str());
  std::printf("  CPU %s, %s, load %.2f\n", mi.cpu_model.c_str(), format_mhz(mi).c_str(), load_average());
  std::printf("  ISA %s, %d threads, %d warm-up + %d timed iterations\n", kernels->isa, pool.num_threads(), warmup,
              iterations);
  std::printf("  iteration ms: median %.2f, mean %.2f, p90 %.2f, min %.2f, max %.2f (CPU %.2f ms per iteration)\n",
              t.median_ms, t.mean_ms, p90, t.min_ms, t.max_ms, cpu_ms);
  std::printf("  anchors %.0f at the end (rows %zu), %.0f neural Gaussians per iteration on average, at most %zu; at most "
              "%zu Gaussian-tile pairs\n",
              anchors, trainer.model().capacity(), gaussians / double(iterations), max_gaussians, max_isects);
  if (!json_path.empty()) {
    nlohmann::json j = {{"dataset", dataset},
                        {"views", views.size()},
                        {"width", w},
                        {"height", h},
                        {"image_features", features},
                        {"isa", kernels->isa},
                        {"threads", pool.num_threads()},
                        {"warmup", warmup},
                        {"iterations", iterations},
                        {"median_ms", t.median_ms},
                        {"mean_ms", t.mean_ms},
                        {"p90_ms", p90},
                        {"min_ms", t.min_ms},
                        {"max_ms", t.max_ms},
                        {"cpu_ms_per_iteration", cpu_ms},
                        {"anchors", anchors},
                        {"mean_gaussians", gaussians / double(iterations)},
                        {"max_gaussians", max_gaussians},
                        {"max_isects", max_isects},
                        {"rows", trainer.model().capacity()},
                        {"cpu_model", mi.cpu_model},
                        {"load_average", load_average()},
                        {"seed", o.seed},
                        {"losses", losses}};
    if (!write_output(json_path, j.dump(2) + "\n", "bench_train")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
