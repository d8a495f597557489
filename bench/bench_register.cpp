// SPDX-License-Identifier: MIT
// bench_register: speed against accuracy of test-view registration (gs::pose::Registrar) on a
// trained model. Every test view is registered from its dataset pose perturbed by the kFixed
// protocol (an exact rotation of D degrees about a random axis and a camera-centre shift of
// D/100 of the scene radius, seeded per view), for D in --init-errors, each solver (lm, adam) and
// iteration budget (small, default), at --downscale. Success: final rotation error < 1 deg and
// translation error < 1 % of the scene radius (largest distance of a training camera centre from
// their mean). The model is a run folder / .hbgs file, or trained here first (--train-iterations)
// so that one command produces the plots from scratch.
// Outputs (--out DIR): register_sweep.csv (one row per view and setting), register_summary.csv
// (one row per setting), time_vs_error.svg and success_vs_init.svg; --json: the summary as JSON.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "gs/io/colmap.h"
#include "gs/jobs/svg_plot.h"
#include "gs/model/trainer.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/model/register.h"

#ifndef GS_BENCH_DEFAULT_DATASET
#define GS_BENCH_DEFAULT_DATASET "../shared/data/snowmiku_plush"
#endif

namespace gs::bench {
namespace {

namespace fs = std::filesystem;
namespace svg = gs::jobs::svg;

[[noreturn]] void die(const std::string& what) {
  std::fprintf(stderr, "bench_register: %s\n", what.c_str());
  std::exit(1);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Process CPU time (all threads), ms: with the machine shared, CPU ms / threads is the wall time a
// free machine would show (when the work parallelises), which a loaded machine's wall time is not.
double cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return 1e3 * (double(u.ru_utime.tv_sec) + double(u.ru_stime.tv_sec)) + 1e-3 * (double(u.ru_utime.tv_usec) + double(u.ru_stime.tv_usec));
}

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / double(v.size());
}

double centre_distance(const Pose& a, const Pose& b) {
  double ca[3], cb[3];
  pose::centre(a, ca);
  pose::centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

// One solver and iteration budget.
struct Setting {
  std::string solver, budget;
  pose::RegisterOptions::Solver kind;
  int lm_iterations, adam_iterations;  // per level
  int keyframe_iterations, keyframes;  // kKeyframe: LM steps per level per keyframe, keyframes
};

struct Row {  // one view under one setting and start error
  size_t setting = 0;
  double init_deg = 0, init_frac = 0;
  std::string view;
  double rot = 0, frac = 0, ms = 0, cpu = 0;
  bool success = false, converged = false;
  std::string verdict;
  int iterations = 0;
  double initial_rmse = 0, final_rmse = 0, explained = 0, coverage = 0;
};

struct Aggregate {
  size_t setting = 0;
  double init_deg = 0, init_frac = 0;
  size_t views = 0;
  double rot_median = 0, frac_median = 0, success_rate = 0, converged_rate = 0, agreement_rate = 0, cpu_median = 0,
         ms_median = 0, ms_mean = 0,
         iterations_median = 0;
};

std::string f(const char* format, double v) { return svg::num(v, format); }

int run(int argc, char** argv) {
  CLI::App app{"bench_register: registration time against accuracy over start errors, solvers and budgets"};
  std::string model_path, dataset, out_dir, json_path, save_model_path;
  std::string init_list = "1,2,5,10,20", solver_list = "keyframe,lm,adam", budget_list = "small,default";
  int max_width = -1, train_iterations = 0, downscale = 4, threads = 0;
  uint64_t seed = 0;
  app.add_option("--model", model_path, "run folder (from hbgs train) or .hbgs model file");
  app.add_option("--dataset", dataset, "COLMAP dataset (default: the run's, else " GS_BENCH_DEFAULT_DATASET ")");
  app.add_option("--max-width", max_width, "downscale images to at most this width (default: as the run, else 0: as stored)");
  app.add_option("--train-iterations", train_iterations, "without --model: train a model for this many iterations first")
      ->check(CLI::Range(0, 10000000));
  app.add_option("--save-model", save_model_path, "with --train-iterations: also save the trained model here (.hbgs)");
  app.add_option("--downscale", downscale, "resolution divisor of the finest registration level")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--init-errors", init_list, "start rotation errors in degrees (translation: deg/100 of the radius)")
      ->capture_default_str();
  app.add_option("--solvers", solver_list, "keyframe, lm and/or adam")->capture_default_str();
  app.add_option("--budgets", budget_list, "small (keyframe 2 x 5 / LM 5 / Adam 25 iterations per level) and/or default (3 x 15 / 20 / 100)")
      ->capture_default_str();
  app.add_option("--seed", seed, "pose-noise seed (and the training seed)")->capture_default_str();
  app.add_option("--threads", threads, "worker threads (0: all CPUs)")->capture_default_str();
  int keyframes = 0, keyframe_iterations = 0, keyframe_downscale = 0, polish = -1;
  double min_decrease = -1;
  int render_polish = -1, polish_downscale = 0;
  bool fixed_point = false;
  double huber = -1;
  int polish_level = 0;
  app.add_option("--polish-level", polish_level, "image level divisor of the render polish (0: the finest)");
  app.add_option("--huber", huber, "Huber delta of the residual norm (-1: default)");
  app.add_flag("--fixed-point", fixed_point, "forward-only renders with the fixed-point rasteriser (RegisterOptions::fixed_point)");
  app.add_option("--polish-downscale", polish_downscale, "render polish divisor (0: finest/4)");
  app.add_option("--render-polish", render_polish, "anti-aliased render LM steps at the end below full resolution (-1: default)");
  app.add_option("--keyframes", keyframes, "keyframe solver: keyframes (0: the budget's)");
  app.add_option("--keyframe-iterations", keyframe_iterations, "keyframe solver: LM steps per level (0: the budget's)");
  app.add_option("--keyframe-downscale", keyframe_downscale, "keyframe render divisor (0: finest/2)");
  app.add_option("--polish", polish, "renderer LM polish steps at the finest level (-1: default)");
  app.add_option("--min-decrease", min_decrease, "relative cost decrease that ends a level (-1: default)");
  app.add_option("--out", out_dir, "folder for the CSV files and SVG plots");
  app.add_option("--json", json_path, "write the summary as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  // Settings from the lists.
  std::vector<double> inits;
  std::vector<Setting> settings;
  try {
    for (const std::string& s : split_list(init_list)) {
      const double d = std::stod(s);
      if (!(d > 0 && d < 180)) throw std::invalid_argument("start error " + s + " out of (0, 180) degrees");
      inits.push_back(d);
    }
    for (const std::string& so : split_list(solver_list)) {
      if (so != "keyframe" && so != "lm" && so != "adam")
        throw std::invalid_argument("solver '" + so + "' is not keyframe, lm or adam");
      for (const std::string& b : split_list(budget_list)) {
        if (b != "small" && b != "default") throw std::invalid_argument("budget '" + b + "' is not small or default");
        const bool small = b == "small";
        const pose::RegisterOptions::Solver kind = so == "lm"         ? pose::RegisterOptions::kGaussNewton
                                                    : so == "adam"     ? pose::RegisterOptions::kAdam
                                                                       : pose::RegisterOptions::kKeyframe;
        settings.push_back({so, b, kind, small ? 5 : 20, small ? 25 : 100, small ? 5 : 15, small ? 2 : 3});
      }
    }
  } catch (const std::exception& e) {
    die(e.what());
  }
  if (inits.empty() || settings.empty()) die("nothing to sweep (empty --init-errors, --solvers or --budgets)");
  if (model_path.empty() && train_iterations == 0) die("pass --model RUN_OR_MODEL, or --train-iterations N to train one");

  // The model's run.json names its dataset and image width.
  if (!model_path.empty()) {
    if (!platform::file_exists(model_path)) die("model " + model_path + " not found");
    fs::path run_dir = fs::path(model_path);
    if (platform::is_directory(model_path)) model_path = (run_dir / "model.hbgs").string();
    else run_dir = run_dir.parent_path();
    const std::string run_json = (run_dir / "run.json").string();
    if (platform::file_exists(run_json)) {
      Expected<std::string> text = platform::read_text_file(run_json);
      if (!text.ok()) die(text.status().to_string());
      const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
      if (j.is_discarded()) die(run_json + ": not valid JSON");
      if (dataset.empty()) dataset = j.value("dataset", std::string());
      if (max_width < 0) max_width = j.value("max_width", 0);
    }
  }
  if (dataset.empty()) dataset = GS_BENCH_DEFAULT_DATASET;
  if (max_width < 0) max_width = 0;
  if (!platform::is_directory(dataset)) {
    std::printf("bench_register: skipped: dataset %s not found (pass --dataset DIR)\n", dataset.c_str());
    return 0;
  }

  io::DatasetOptions dopt;
  dopt.max_width = max_width;
  Expected<io::Dataset> ds = io::load_dataset(dataset, dopt);
  if (!ds.ok()) die(ds.status().to_string());
  std::vector<const io::DatasetView*> train_views, test_views;
  std::vector<const Camera*> train_cameras;
  std::vector<Pose> truth, train_poses;
  std::vector<size_t> test_index;
  int max_w = 0, max_h = 0;
  for (size_t i = 0; i < ds->views.size(); ++i) {
    const io::DatasetView& v = ds->views[i];
    truth.push_back(v.camera.pose);
    if (v.is_test) {
      test_views.push_back(&v), test_index.push_back(i);
      max_w = std::max(max_w, v.camera.intr.width), max_h = std::max(max_h, v.camera.intr.height);
    } else {
      train_views.push_back(&v), train_cameras.push_back(&v.camera), train_poses.push_back(v.camera.pose);
    }
  }
  if (test_views.empty()) die(dataset + ": no test views");
  double centre[3], radius = 1;
  pose::scene_frame(train_poses.data(), train_poses.size(), centre, &radius);

  platform::ThreadPool pool(threads);
  model::HybridModel model;
  double train_seconds = 0;
  if (!model_path.empty()) {
    Expected<model::HybridModel> m = model::load_model(model_path);
    if (!m.ok()) die(m.status().to_string());
    model = std::move(m).value();
  } else {
    Expected<model::HybridModel> m = model::create_model(model::ModelConfig{}, ds->points_xyz.data(),
                                                         ds->points_xyz.size() / 3, model::cameras_extent(train_cameras), seed);
    if (!m.ok()) die(m.status().to_string());
    model::TrainOptions topt;
    topt.iterations = topt.schedule_iterations = train_iterations;
    topt.seed = seed;
    Expected<std::unique_ptr<model::Trainer>> trainer = model::Trainer::create(std::move(m).value(), train_views, topt, &pool);
    if (!trainer.ok()) die(trainer.status().to_string());
    const double t0 = platform::now_seconds();
    double psnr = 0;
    for (int i = 1; i <= train_iterations; ++i) {
      model::IterationStats st;
      if (Status s = (*trainer)->step(&st); !s.ok()) die("training iteration " + std::to_string(i) + ": " + s.to_string());
      psnr = i == 1 ? st.psnr : 0.98 * psnr + 0.02 * st.psnr;
      if (i % 100 == 0 || i == train_iterations)
        std::fprintf(stderr, "bench_register: training %d/%d, train PSNR ~%.2f dB, %zu anchors, %.0f s\n", i,
                     train_iterations, psnr, st.anchors, platform::now_seconds() - t0);
    }
    train_seconds = platform::now_seconds() - t0;
    model = (*trainer)->model();
    if (!save_model_path.empty()) {
      if (fs::path(save_model_path).has_parent_path())
        if (Status st = platform::make_dirs(fs::path(save_model_path).parent_path().string()); !st.ok()) die(st.to_string());
      if (Status st = model::save_model(model, save_model_path); !st.ok()) die(st.to_string());
      std::printf("Wrote %s\n", save_model_path.c_str());
    }
  }

  // One registrar, re-configured (not re-planned) per setting.
  pose::RegisterOptions ropt;
  ropt.finest_downscale = downscale;
  Expected<std::unique_ptr<pose::Registrar>> reg = pose::Registrar::create(model, max_w, max_h, ropt, &pool);
  if (!reg.ok()) die(reg.status().to_string());
  pose::Registrar& r = **reg;
  {  // warm-up (untimed): first touches of the planned memory
    pose::RegisterResult res;
    if (Status st = r.register_view(test_views[0]->image.pixels.data(), test_views[0]->camera.intr, truth[test_index[0]], &res);
        !st.ok())
      die(st.to_string());
  }

  std::vector<Row> rows;
  std::vector<Aggregate> aggs;
  const double t_sweep = platform::now_seconds();
  for (size_t si = 0; si < settings.size(); ++si) {
    const Setting& s = settings[si];
    pose::RegisterOptions& o = r.mutable_options();
    o.solver = s.kind;
    o.max_iterations_per_level = s.lm_iterations;
    o.adam_iterations_per_level = s.adam_iterations;
    o.keyframe_iterations = s.keyframe_iterations;
    o.keyframes = s.keyframes;
    if (keyframes > 0) o.keyframes = keyframes;
    if (keyframe_iterations > 0) o.keyframe_iterations = keyframe_iterations;
    o.keyframe_downscale = keyframe_downscale;
    o.polish_downscale = polish_downscale;
    o.fixed_point = fixed_point;
    if (huber > 0) o.huber_delta = float(huber);
    o.polish_level_downscale = polish_level;
    if (polish >= 0) o.polish_iterations = polish;
    if (render_polish >= 0) o.render_polish_iterations = render_polish;
    if (min_decrease >= 0) o.min_relative_decrease = min_decrease;
    for (double deg : inits) {
      pose::PoseNoise noise;
      noise.kind = pose::PoseNoise::kFixed;
      noise.rotation_deg = deg;
      noise.translation_frac = deg / 100.0;
      noise.seed = seed;
      std::vector<Pose> start = truth;
      pose::perturb_poses(noise, centre, radius, start.data(), start.size());
      Aggregate ag;
      ag.setting = si, ag.init_deg = deg, ag.init_frac = noise.translation_frac, ag.views = test_views.size();
      std::vector<double> rot, frac, ms, its, cpu;
      size_t ok = 0, conv = 0, agree = 0;
      for (size_t k = 0; k < test_views.size(); ++k) {
        const io::DatasetView& v = *test_views[k];
        const size_t i = test_index[k];
        pose::RegisterResult res;
        const double cpu0 = cpu_ms();
        if (Status st = r.register_view(v.image.pixels.data(), v.camera.intr, start[i], &res); !st.ok())
          die(v.name + ": " + st.to_string());
        const double cpu1 = cpu_ms();
        Row row;
        row.setting = si, row.init_deg = deg, row.init_frac = noise.translation_frac, row.view = v.name;
        row.rot = pose::rotation_error_deg(res.pose, truth[i]);
        row.frac = centre_distance(res.pose, truth[i]) / radius;
        row.ms = res.milliseconds;
        row.cpu = cpu1 - cpu0;
        row.success = row.rot < 1.0 && row.frac < 0.01;
        row.converged = res.converged();
        row.verdict = pose::verdict_name(res.verdict);
        row.iterations = res.iterations;
        row.initial_rmse = res.initial_rmse, row.final_rmse = res.final_rmse;
        row.explained = res.explained, row.coverage = res.coverage;
        rot.push_back(row.rot), frac.push_back(row.frac), ms.push_back(row.ms), its.push_back(row.iterations);
        ok += row.success, conv += row.converged, agree += row.success == row.converged;
        cpu.push_back(row.cpu);
        rows.push_back(row);
      }
      ag.rot_median = median(rot), ag.frac_median = median(frac), ag.ms_median = median(ms), ag.ms_mean = mean(ms);
      ag.iterations_median = median(its);
      ag.success_rate = double(ok) / double(ag.views), ag.converged_rate = double(conv) / double(ag.views);
      ag.agreement_rate = double(agree) / double(ag.views), ag.cpu_median = median(cpu);
      std::fprintf(stderr, "bench_register: %s/%s from %g deg: median %.3f deg, success %.0f%%, median %.0f ms\n",
                   s.solver.c_str(), s.budget.c_str(), deg, ag.rot_median, 100 * ag.success_rate, ag.ms_median);
      aggs.push_back(ag);
    }
  }
  const double sweep_seconds = platform::now_seconds() - t_sweep;

  // Table.
  const MachineInfo mi = machine_info();
  const int w = test_views[0]->camera.intr.width, h = test_views[0]->camera.intr.height;
  std::printf("bench_register: %s, %zu test views at %dx%d (registered at 1/%d), %zu anchors, scene radius %.4g\n",
              dataset.c_str(), test_views.size(), w, h, downscale, model.anchor_count, radius);
  std::printf("  model: %s\n", model_path.empty() ? ("trained here, " + std::to_string(train_iterations) + " iterations (" +
                                                      f("%.0f", train_seconds) + " s)").c_str()
                                                  : model_path.c_str());
  std::printf("  CPU %s, %s, load %.2f, %d threads; sweep %.1f s\n", mi.cpu_model.c_str(), format_mhz(mi).c_str(),
              load_average(), pool.num_threads(), sweep_seconds);
  // (agree: the verdict is `converged` exactly when the view succeeded; cpu/thr: median process CPU
  // ms per view over the threads, the wall time of a free machine when the work parallelises.)
  std::printf("  %-6s %-8s %8s %8s | %12s %12s %8s %9s %7s %9s %8s %9s %6s\n", "solver", "budget", "init deg", "init r",
              "med rot deg", "med trans %r", "success", "converged", "agree", "med ms", "mean ms", "cpu/thr", "iters");
  for (const Aggregate& a : aggs) {
    const Setting& s = settings[a.setting];
    std::printf("  %-6s %-8s %8g %8g | %12.4f %12.3f %7.0f%% %8.0f%% %6.0f%% %9.1f %8.1f %9.1f %6.0f\n", s.solver.c_str(),
                s.budget.c_str(), a.init_deg, a.init_frac, a.rot_median, 100 * a.frac_median, 100 * a.success_rate,
                100 * a.converged_rate, 100 * a.agreement_rate, a.ms_median, a.ms_mean,
                a.cpu_median / double(pool.num_threads()), a.iterations_median);
  }

  // Files.
  if (!out_dir.empty()) {
    if (Status st = platform::make_dirs(out_dir); !st.ok()) die(st.to_string());
    std::string csv = "solver,budget,init_deg,init_frac,view,final_rot_deg,final_trans_frac,success,verdict,ms,iterations,initial_rmse,final_rmse,explained,coverage,cpu_ms\n";
    for (const Row& x : rows)
      csv += settings[x.setting].solver + "," + settings[x.setting].budget + "," + f("%g", x.init_deg) + "," +
             f("%g", x.init_frac) + "," + x.view + "," + f("%.6g", x.rot) + "," + f("%.6g", x.frac) + "," +
             (x.success ? "1" : "0") + "," + x.verdict + "," + f("%.2f", x.ms) + "," + std::to_string(x.iterations) + "," +
             f("%.5g", x.initial_rmse) + "," + f("%.5g", x.final_rmse) + "," + f("%.5g", x.explained) + "," +
             f("%.5g", x.coverage) + "," + f("%.2f", x.cpu) + "\n";
    std::string agg_csv =
        "solver,budget,init_deg,init_frac,views,median_final_rot_deg,median_final_trans_frac,success_rate,"
        "converged_rate,median_ms,mean_ms,median_iterations,agreement_rate,median_cpu_ms\n";
    for (const Aggregate& a : aggs)
      agg_csv += settings[a.setting].solver + "," + settings[a.setting].budget + "," + f("%g", a.init_deg) + "," +
                 f("%g", a.init_frac) + "," + std::to_string(a.views) + "," + f("%.6g", a.rot_median) + "," +
                 f("%.6g", a.frac_median) + "," + f("%.4f", a.success_rate) + "," + f("%.4f", a.converged_rate) + "," +
                 f("%.2f", a.ms_median) + "," + f("%.2f", a.ms_mean) + "," + f("%g", a.iterations_median) + "," +
                 f("%.4f", a.agreement_rate) + "," + f("%.2f", a.cpu_median) + "\n";

    const std::string where = fs::path(dataset).filename().string() + ", " + std::to_string(test_views.size()) +
                              " test views, 1/" + std::to_string(downscale) + " resolution";
    std::vector<double> xs, ys, inits_x;
    for (const Aggregate& a : aggs) xs.push_back(a.ms_median), ys.push_back(std::max(a.rot_median, 1e-4));
    svg::Axis ax{"median time per view (ms)"}, ay{"median final rotation error (deg, log)", true};
    ax.fit(xs, true);
    ay.fit(ys);
    svg::Plot time_plot("Registration: time against error (" + where + ")", ax, ay);
    svg::Axis bx{"initial rotation error (deg, log; translation deg/100 of the radius)", true};
    bx.fit(inits);
    svg::Axis by{"success rate (< 1 deg and < 1% of the radius)"};
    by.lo = 0, by.hi = 1;
    svg::Plot success_plot("Registration: success against start error (" + where + ")", bx, by);
    const char markers[] = {'o', 's', '^', 'd'};
    for (size_t si = 0; si < settings.size(); ++si) {
      svg::Series a, b;
      a.name = b.name = settings[si].solver + ", " + settings[si].budget + " budget";
      a.color = b.color = svg::palette(si);
      a.marker = b.marker = markers[si % 4];
      for (const Aggregate& g : aggs) {
        if (g.setting != si) continue;
        a.x.push_back(g.ms_median), a.y.push_back(std::max(g.rot_median, 1e-4));
        a.labels.push_back(f("%g", g.init_deg) + "\u00b0");
        a.titles.push_back(a.name + ", start " + f("%g", g.init_deg) + " deg: median " + f("%.4f", g.rot_median) +
                           " deg in " + f("%.1f", g.ms_median) + " ms, success " + f("%.0f", 100 * g.success_rate) + "%");
        b.x.push_back(g.init_deg), b.y.push_back(g.success_rate);
        b.titles.push_back(a.titles.back());
      }
      time_plot.add(std::move(a));
      success_plot.add(std::move(b));
    }
    const fs::path dir(out_dir);
    if (!write_output((dir / "register_sweep.csv").string(), csv, "bench_register") ||
        !write_output((dir / "register_summary.csv").string(), agg_csv, "bench_register") ||
        !write_output((dir / "time_vs_error.svg").string(), time_plot.render(), "bench_register") ||
        !write_output((dir / "success_vs_init.svg").string(), success_plot.render(), "bench_register"))
      return 1;
  }
  if (!json_path.empty()) {
    nlohmann::ordered_json ja = nlohmann::ordered_json::array();
    for (const Aggregate& a : aggs)
      ja.push_back({{"solver", settings[a.setting].solver},
                    {"budget", settings[a.setting].budget},
                    {"lm_iterations_per_level", settings[a.setting].lm_iterations},
                    {"adam_iterations_per_level", settings[a.setting].adam_iterations},
                    {"init_deg", a.init_deg},
                    {"init_frac", a.init_frac},
                    {"views", a.views},
                    {"median_final_rot_deg", a.rot_median},
                    {"median_final_trans_frac", a.frac_median},
                    {"success_rate", a.success_rate},
                    {"converged_rate", a.converged_rate},
                    {"verdict_agreement_rate", a.agreement_rate},
                    {"median_cpu_ms", a.cpu_median},
                    {"median_ms", a.ms_median},
                    {"mean_ms", a.ms_mean},
                    {"median_iterations", a.iterations_median}});
    nlohmann::ordered_json j = {{"dataset", dataset},
                        {"model", model_path.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(model_path)},
                        {"train_iterations", model_path.empty() ? train_iterations : 0},
                        {"train_seconds", train_seconds},
                        {"test_views", test_views.size()},
                        {"width", w},
                        {"height", h},
                        {"downscale", downscale},
                        {"anchors", model.anchor_count},
                        {"scene_radius", radius},
                        {"seed", seed},
                        {"fixed_point", fixed_point},
                        {"threads", pool.num_threads()},
                        {"success_definition", "rotation < 1 deg and translation < 0.01 scene radius"},
                        {"sweep_seconds", sweep_seconds},
                        {"cpu_model", mi.cpu_model},
                        {"load_average", load_average()},
                        {"settings", std::move(ja)}};
    if (!write_output(json_path, j.dump(2) + "\n", "bench_register")) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
