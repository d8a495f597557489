// SPDX-License-Identifier: MIT
// bench_train: end-to-end training-step timing on a COLMAP dataset (default
// ../shared/data/snowmiku_plush): untimed warm-up iterations, then median / mean / p90 iteration
// milliseconds with the anchor and Gaussian counts, the kernel ISA and the thread count. It times
// the library's training job (gs::jobs::TrainSession) with the job's own defaults, so it runs the
// configuration `hbgs train` runs for the same dataset, seed and iterations (warm-up + timed).
// --profile: the roofline per stage of the timed iterations (gs/stage_times.h; counting model in
// stage_work below and in docs/MODEL.md "Where a training iteration's time goes").
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
#include "gs/stage_times.h"
#include "peak/machine_peaks.h"

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

// The work one stage does per iteration under the profile's counting model: floating-point
// operations (an FMA counts 2; comparisons, selects and integer work count 0) and bytes read +
// written once each (cache reuse ignored: a lower bound on the traffic, an upper bound on the
// intensity). Per-item constants are estimates from the kernels' inner loops (see MODEL.md);
// stages without a model (anchor adjust, image-feature refresh, other) get 0.
struct StageWork {
  double flops = 0, bytes = 0;
};

struct ModelShapes {
  simd::MlpShape mlp[model::kMlpCount]{};
  bool image_mlp = false;
  int k = 0, feature_dim = 0;
};

// Per-item constants of the counting model.
constexpr double kSelectFlops = 50;        // camera transform (18), exp of the largest scale, disc test
constexpr double kDecodeFwdFlops = 40;     // per candidate Gaussian: offset, scale activation, quaternion normalise
constexpr double kProjectFlops = 150;      // per Gaussian: rotation from quaternion, 3D -> 2D covariance, conic, radius
constexpr double kProjectBwdFlops = 400;   // per Gaussian: the chain back through the same
constexpr double kRasterFwdFlops = 40;     // per evaluated pixel-splat pair: exponent (5), exp (20), blend (15)
constexpr double kRasterBwdFlops = 80;     // per pair: exponent and exp again, gradients of colour, alpha, conic, mean
constexpr double kLossFlopsPerPixel = 3 * (5 * 44 + 4 * 44 + 60);  // per pixel: 3 channels, SSIM blurs fwd (5 maps)
                                                                   // and bwd (4), 11 taps x 2 passes x 2, plus L1
constexpr double kReduceFlops = 9;         // per Gaussian-tile pair
constexpr double kDecodeBwdFlops = 60;     // per kept Gaussian
constexpr double kAdamFlops = 12;          // per parameter: two moments, bias correction, sqrt, divide, update
constexpr double kStatsFlops = 6;          // per kept Gaussian: gradient norm

double mlp_fwd_flops(const simd::MlpShape& s, double rows) {
  return 2 * rows * (double(s.in) * s.hidden + double(s.hidden) * s.out);
}
double mlp_params(const simd::MlpShape& s) { return double(s.in) * s.hidden + s.hidden + double(s.hidden) * s.out + s.out; }

StageWork stage_work(int stage, const StageTimes& t, const ModelShapes& sh) {
  const double n = double(std::max<uint64_t>(t.iterations, 1));
  const double M = double(t.anchors) / n, V = double(t.visible_anchors) / n, N = double(t.gaussians) / n;
  const double P = double(t.projected) / n, I = double(t.isects) / n, X = double(t.pixels) / n;
  const double S = double(t.splat_pixels) / n, A = double(t.adam_floats) / n;
  const double K = sh.k, F = sh.feature_dim, R = model::kImageRawDim;
  const simd::MlpShape& im = sh.mlp[model::kMlpImage];
  const double D = sh.mlp[model::kMlpOpacity].in;
  double dec_out = 0;
  for (int m = 0; m < 3; ++m) dec_out += sh.mlp[m].out;
  const double rec = 4.0 * 13;  // splat record bytes (simd::kSplatStride floats)
  StageWork w;
  switch (stage) {
    case kStageAnchorSelect: w = {kSelectFlops * M, 36 * M + 4 * V}; break;  // position + log-scale row, row index
    case kStageImageMlpFwd:
      if (sh.image_mlp) w = {mlp_fwd_flops(im, V), 4 * V * (2 * R + im.hidden + im.out) + 4 * mlp_params(im)};
      break;
    case kStageDecoderInput: w = {10 * V, 4 * V * (F + (sh.image_mlp ? im.out : 0) + 3 + D)}; break;
    case kStageDecoderMlpFwd:
      for (int m = 0; m < 3; ++m) {
        w.flops += mlp_fwd_flops(sh.mlp[m], V);
        w.bytes += 4 * V * (D + sh.mlp[m].hidden + sh.mlp[m].out) + 4 * mlp_params(sh.mlp[m]);
      }
      break;
    case kStageDecodeFwd: w = {kDecodeFwdFlops * V * K, 4 * V * (dec_out + 3 + 3 * K + 6) + 4 * N * 15}; break;
    case kStageProject: w = {kProjectFlops * N, 40 * N + P * (8 + 12 + 4 + 4 + rec + 16 + 8)}; break;
    case kStageBin: w = {0, 2 * P * 32 + I * (4 + 8)}; break;  // two passes over the projected, a count and a key per pair
    case kStageSortCopy: w = {0, I * (2 * 2 * 8 + 2 * rec)}; break;  // ~2 radix passes r+w, the record gathered and written
    case kStageRasterFwd: w = {kRasterFwdFlops * S, I * rec + X * 20}; break;
    case kStageLoss: w = {kLossFlopsPerPixel * X, X * 3 * 4 * 3 + N * 24}; break;  // image, target, v_image; volume term
    case kStageRasterBwd: w = {kRasterBwdFlops * S, 2 * I * rec + X * 20}; break;
    case kStageReduce: w = {kReduceFlops * I, I * (8 + 36) + N * 36 * 2}; break;
    case kStageProjectBwd: w = {kProjectBwdFlops * N, N * (40 + 36 + 40 + 20)}; break;
    case kStageDecodeBwd: w = {kDecodeBwdFlops * N, 4 * N * 15 + 4 * V * (2 * dec_out + 3 * K + 6)}; break;
    case kStageMlpBwd:
      for (int m = 0; m < 3; ++m) {
        w.flops += 2 * mlp_fwd_flops(sh.mlp[m], V);
        w.bytes += 4 * V * (2 * D + 2 * sh.mlp[m].hidden + 2 * sh.mlp[m].out) + 4 * 9 * mlp_params(sh.mlp[m]);
      }
      if (sh.image_mlp) {  // no input gradient: the first layer's weight gradient only
        w.flops += mlp_fwd_flops(im, V) + 2 * V * double(im.hidden) * im.out;
        w.bytes += 4 * V * (R + 2 * im.hidden + 2 * im.out) + 4 * 9 * mlp_params(im);
      }
      break;
    case kStageAdam: w = {kAdamFlops * A, 28 * A}; break;  // read p, g, m, v; write p, m, v
    case kStageStats: {
      const double share = double(t.stats_steps) / n;
      w = {share * (kStatsFlops * N + V * K), share * (N * 24 + V * (4 * K + 8))};
      break;
    }
    default: break;
  }
  return w;
}

int run(int argc, char** argv) {
  CLI::App app{"bench_train: training iteration timings of the hybrid anchor model on a COLMAP dataset"};
  jobs::TrainRunOptions o;  // the job's defaults, as `hbgs train` has them
  o.dataset = GS_BENCH_DEFAULT_DATASET;
  std::string json_path;
  int iterations = 300, warmup = 20;
  bool profile = false;
  app.add_option("--dataset", o.dataset, "COLMAP dataset with SfM points")->capture_default_str();
  app.add_option("--iterations", iterations, "timed iterations")->capture_default_str()->check(CLI::Range(1, 10000000));
  app.add_option("--warmup", warmup, "untimed iterations first")->capture_default_str()->check(CLI::Range(0, 10000000));
  app.add_option("--threads", o.threads, "worker threads (0: all CPUs)")->capture_default_str();
  app.add_option("--max-width", o.max_width, "downscale images to at most this width (0: as stored)")->capture_default_str();
  app.add_option("--isa", o.isa, "kernel table (default: the best for this CPU)");
  app.add_option("--image-features", o.image_features, "paper, visible or none")->capture_default_str()->check(CLI::IsMember({"paper", "visible", "none"}));
  app.add_option("--seed", o.seed, "model and view-order seed")->capture_default_str();
  app.add_option("--offsets", o.offsets,
                 "neural Gaussians per anchor (-1: the job's choice, 7 below 15000 iterations and 10 from there; "
                 "10 for comparisons with builds before that)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 64));
  app.add_flag("!--no-view-check", o.view_check,
               "train on every view as given (as before issue 26): no view held back by the check against the SfM points; "
               "for speed comparisons with builds that have no such check");
  app.add_flag("--profile", profile,
               "time every stage of the timed iterations and print the roofline table (FLOPs, bytes, the machine's "
               "measured FMA and copy peaks)");
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
  StageTimes times(/*count_pixels=*/true);
  double cpu0 = process_cpu_seconds();
  for (int i = 0; i < warmup + iterations; ++i) {
    if (i == warmup) {
      cpu0 = process_cpu_seconds();
      if (profile) trainer.set_stage_times(&times);
    }
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
  trainer.set_stage_times(nullptr);
  const double cpu_ms = (process_cpu_seconds() - cpu0) * 1e3 / double(iterations);
  const Timing t = summarize(ms);
  const double p90 = percentile(ms, 0.9);
  const MachineInfo mi = machine_info();
  const int w = views.front()->camera.intr.width, h = views.front()->camera.intr.height;
  std::printf("bench_train: %s, %zu training views at %dx%d, image features %s, %d offsets per anchor\n",
              dataset.c_str(), views.size(), w, h, features.c_str(), trainer.model().config.k);
  std::printf("  CPU %s, %s, load %.2f\n", mi.cpu_model.c_str(), format_mhz(mi).c_str(), load_average());
  std::printf("  ISA %s, %d threads, %d warm-up + %d timed iterations\n", kernels->isa, pool.num_threads(), warmup,
              iterations);
  std::printf("  iteration ms: median %.2f, mean %.2f, p90 %.2f, min %.2f, max %.2f (CPU %.2f ms per iteration)\n",
              t.median_ms, t.mean_ms, p90, t.min_ms, t.max_ms, cpu_ms);
  std::printf("  anchors %.0f at the end (rows %zu), %.0f neural Gaussians per iteration on average, at most %zu; at most "
              "%zu Gaussian-tile pairs\n",
              anchors, trainer.model().capacity(), gaussians / double(iterations), max_gaussians, max_isects);
  nlohmann::json profile_json;
  if (profile) {
    const MachinePeaks pk = measure_machine_peaks(kernels->isa, pool);
    ModelShapes shapes;
    const model::HybridModel& hm = trainer.model();
    for (int m = 0; m < model::kMlpCount; ++m) shapes.mlp[m] = hm.mlps[m].shape;
    shapes.image_mlp = !hm.mlps[model::kMlpImage].params.empty();
    shapes.k = hm.config.k;
    shapes.feature_dim = hm.config.feature_dim;
    const double n = double(times.iterations);
    std::printf("  peaks (%d threads): FMA %s %.1f GFLOP/s per core, %.1f on all threads; copy %.1f GB/s per core, %.1f "
                "on all threads (%zu MiB buffers)\n",
                pool.num_threads(), pk.fma_isa.c_str(), pk.fma_gflops_core, pk.fma_gflops_all, pk.copy_gbs_core,
                pk.copy_gbs_all, pk.copy_buffer_bytes >> 20);
    std::printf("  per iteration: %.0f anchors, %.0f visible, %.0f Gaussians (%.0f projected), %.0f tile pairs, %.0f "
                "pixels, %.0f pixel-splat pairs, %.0f Adam parameters\n",
                double(times.anchors) / n, double(times.visible_anchors) / n, double(times.gaussians) / n,
                double(times.projected) / n, double(times.isects) / n, double(times.pixels) / n,
                double(times.splat_pixels) / n, double(times.adam_floats) / n);
    std::printf("  profiled iteration %.2f ms (stages sum to it) + %.2f ms of profile counting\n",
                times.profiled_ms_per_iteration(), 1e-6 * double(times.overhead_ns) / n);
    std::printf("  %-15s %8s %6s %9s %9s %8s %7s %7s %7s\n", "stage", "ms", "%", "MFLOP", "MB", "GFLOP/s", "GB/s",
                "%FMA", "%copy");
    nlohmann::json stages = nlohmann::json::array();
    const double total_ms = times.profiled_ms_per_iteration();
    for (int s = 0; s < kStageCount; ++s) {
      const double ms = times.ms_per_iteration(s);
      const StageWork w = stage_work(s, times, shapes);
      const double gflops = ms > 0 ? w.flops / (ms * 1e6) : 0, gbs = ms > 0 ? w.bytes / (ms * 1e6) : 0;
      const double fma_frac = pk.fma_gflops_all > 0 ? gflops / pk.fma_gflops_all : 0;
      const double copy_frac = pk.copy_gbs_all > 0 ? gbs / pk.copy_gbs_all : 0;
      std::printf("  %-15s %8.3f %6.1f %9.2f %9.2f %8.2f %7.2f %7.2f %7.2f\n", stage_name(s), ms,
                  total_ms > 0 ? 100 * ms / total_ms : 0, w.flops * 1e-6, w.bytes * 1e-6, gflops, gbs, 100 * fma_frac,
                  100 * copy_frac);
      stages.push_back({{"stage", stage_name(s)},
                        {"ms", ms},
                        {"flops", w.flops},
                        {"bytes", w.bytes},
                        {"gflops", gflops},
                        {"gbs", gbs},
                        {"fma_peak_fraction", fma_frac},
                        {"copy_peak_fraction", copy_frac}});
    }
    profile_json = {{"stages", stages},
                    {"profiled_ms_per_iteration", total_ms},
                    {"overhead_ms_per_iteration", 1e-6 * double(times.overhead_ns) / n},
                    {"counts_per_iteration",
                     {{"anchors", double(times.anchors) / n},
                      {"visible_anchors", double(times.visible_anchors) / n},
                      {"gaussians", double(times.gaussians) / n},
                      {"projected", double(times.projected) / n},
                      {"isects", double(times.isects) / n},
                      {"pixels", double(times.pixels) / n},
                      {"splat_pixels", double(times.splat_pixels) / n},
                      {"adam_floats", double(times.adam_floats) / n},
                      {"stats_steps", double(times.stats_steps) / n},
                      {"adjust_steps", double(times.adjust_steps) / n},
                      {"refresh_steps", double(times.refresh_steps) / n}}},
                    {"peaks",
                     {{"fma_isa", pk.fma_isa},
                      {"fma_gflops_core", pk.fma_gflops_core},
                      {"fma_gflops_all", pk.fma_gflops_all},
                      {"copy_gbs_core", pk.copy_gbs_core},
                      {"copy_gbs_all", pk.copy_gbs_all},
                      {"copy_buffer_bytes", pk.copy_buffer_bytes}}}};
  }
  if (!json_path.empty()) {
    nlohmann::json j = {{"dataset", dataset},
                        {"views", views.size()},
                        {"width", w},
                        {"height", h},
                        {"image_features", features},
                        {"offsets", trainer.model().config.k},
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
    if (profile) j["profile"] = profile_json;
    if (!write_output(json_path, j.dump(2) + "\n", "bench_train")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
