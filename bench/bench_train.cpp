// SPDX-License-Identifier: MIT
// bench_train: end-to-end training-step timing of gs::model::Trainer on a COLMAP dataset (default
// ../shared/data/snowmiku_plush): untimed warm-up iterations, then median / mean / p90 iteration
// milliseconds with the anchor and Gaussian counts, the kernel ISA and the thread count.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/io/colmap.h"
#include "gs/model/trainer.h"
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
  std::string dataset = GS_BENCH_DEFAULT_DATASET, isa_name, features = "paper", json_path;
  int iterations = 300, warmup = 20, threads = 0, max_width = 0;
  uint64_t seed = 0;
  app.add_option("--dataset", dataset, "COLMAP dataset with SfM points")->capture_default_str();
  app.add_option("--iterations", iterations, "timed iterations")->capture_default_str()->check(CLI::Range(1, 10000000));
  app.add_option("--warmup", warmup, "untimed iterations first")->capture_default_str()->check(CLI::Range(0, 10000000));
  app.add_option("--threads", threads, "worker threads (0: all CPUs)")->capture_default_str();
  app.add_option("--max-width", max_width, "downscale images to at most this width (0: as stored)")->capture_default_str();
  app.add_option("--isa", isa_name, "kernel table (default: the best for this CPU)");
  app.add_option("--image-features", features, "paper or none")->capture_default_str()->check(CLI::IsMember({"paper", "none"}));
  app.add_option("--seed", seed, "model and view-order seed")->capture_default_str();
  app.add_option("--json", json_path, "write the results as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  if (!platform::is_directory(dataset)) {
    std::printf("bench_train: skipped: dataset %s not found (pass --dataset DIR)\n", dataset.c_str());
    return 0;
  }
  const simd::KernelTable* kernels = isa_name.empty() ? &simd::best_kernel_table() : simd::kernel_table_by_name(isa_name.c_str());
  if (!kernels) die("kernel table '" + isa_name + "' is not compiled in or not supported by this CPU");
  io::DatasetOptions dopt;
  dopt.max_width = max_width;
  Expected<io::Dataset> ds = io::load_dataset(dataset, dopt);
  if (!ds.ok()) die(ds.status().to_string());
  std::vector<const io::DatasetView*> views;
  std::vector<const Camera*> cameras;
  for (const io::DatasetView& v : ds->views)
    if (!v.is_test) views.push_back(&v), cameras.push_back(&v.camera);
  model::ModelConfig config;
  config.image_features = *model::parse_image_feature_mode(features);
  Expected<model::HybridModel> m =
      model::create_model(config, ds->points_xyz.data(), ds->points_xyz.size() / 3, model::cameras_extent(cameras), seed);
  if (!m.ok()) die(m.status().to_string());
  model::TrainOptions topt;
  topt.iterations = topt.schedule_iterations = warmup + iterations;
  topt.seed = seed;
  platform::ThreadPool pool(threads);
  Expected<std::unique_ptr<model::Trainer>> trainer = model::Trainer::create(std::move(m).value(), views, topt, &pool, kernels);
  if (!trainer.ok()) die(trainer.status().to_string());

  std::vector<double> ms;
  double gaussians = 0, anchors = 0;
  double cpu0 = process_cpu_seconds();
  for (int i = 0; i < warmup + iterations; ++i) {
    if (i == warmup) cpu0 = process_cpu_seconds();
    model::IterationStats st;
    const uint64_t t0 = platform::now_ns();
    if (Status s = (*trainer)->step(&st); !s.ok()) die("iteration " + std::to_string(i + 1) + ": " + s.to_string());
    if (i < warmup) continue;
    ms.push_back(double(platform::now_ns() - t0) * 1e-6);
    gaussians += double(st.step.gaussians);
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
  std::printf("  anchors %.0f at the end, %.0f neural Gaussians per iteration on average\n", anchors,
              gaussians / double(iterations));
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
                        {"cpu_model", mi.cpu_model},
                        {"load_average", load_average()}};
    if (!write_output(json_path, j.dump(2) + "\n", "bench_train")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
