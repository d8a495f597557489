// SPDX-License-Identifier: MIT
// `hbgs train`: the flags of gs::jobs::train_run (gs/jobs/train.h, which holds every default), its
// progress line on stderr and the summary on stdout.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/image.h"
#include "gs/jobs/run_folder.h"
#ifndef HBGS_DEVICE
#include "colmap_pose_init.h"
#endif
#include "gs/metrics/lpips.h"

namespace hbgs::cli {
namespace {

constexpr int kMaxIterations = 100000000;
// The largest budgets the options take: 2^32 anchors and 2^34 Gaussians per view, or size_t's
// largest where that is smaller (32-bit ARM: size_t(1) << 32 is undefined there and gave a range
// "1 to 0" that refused every value).
constexpr size_t size_limit(int log2) {
  return size_t(std::min<uint64_t>(uint64_t(1) << log2, std::numeric_limits<size_t>::max()));
}

struct TrainCli {
  gs::jobs::TrainRunOptions options;
  bool quiet = false;
  bool report = false;  // hbgs only: write RUN/report.html at the end (hbgs report)
};

std::string clock_text(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const long s = long(seconds + 0.5);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof(buf), "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else std::snprintf(buf, sizeof(buf), "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// The job's events on stderr: notes and stages as lines, and the progress line, rewritten in place
// on a terminal (at most every second or 50 iterations) and printed every 5 s otherwise.
class ProgressPrinter {
 public:
  explicit ProgressPrinter(bool quiet) : quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}
  void operator()(const gs::jobs::TrainEvent& e) {
    if (quiet_) return;
    switch (e.kind) {
      case gs::jobs::TrainEvent::kNote: line("note: " + e.message); return;
      case gs::jobs::TrainEvent::kStage: line("hbgs train: " + e.message); return;
      case gs::jobs::TrainEvent::kDetail: line(e.message); return;
      case gs::jobs::TrainEvent::kPoseErrors: {
        char buf[200];
        std::snprintf(buf, sizeof(buf), "it %d: training poses vs true: rotation mean %.3f deg (median %.3f), translation %.2f%% of radius",
                      e.iteration, e.pose_errors.rotation_mean_deg, e.pose_errors.rotation_median_deg,
                      100 * e.pose_errors.translation_mean_frac);
        line(buf);
        return;
      }
      case gs::jobs::TrainEvent::kIteration: iteration(e); return;
    }
  }
  // Ends the in-place line before other output.
  void break_line() {
    if (open_) std::fputc('\n', stderr);
    open_ = false;
  }

 private:
  void line(const std::string& text) {
    break_line();
    std::fprintf(stderr, "%s\n", text.c_str());
  }
  // With a time budget the total is the current prediction ("~"), and the remaining time is the
  // budget's.
  void iteration(const gs::jobs::TrainEvent& e) {
    const gs::model::IterationStats& s = *e.stats;
    const int total = e.iterations;
    const bool budget = e.budget_seconds > 0;
    if (s.poses_registered >= 0) line("it " + std::to_string(s.iteration) + ": registration pass moved " +
                                      std::to_string(s.poses_registered) + " poses");
    if (s.views_released > 0)
      line("it " + std::to_string(s.iteration) + ": " + std::to_string(s.views_released) +
           " held-back views registered against the model and joined training; " + std::to_string(s.views_held_back) +
           " still held back");
    ema_loss_ = have_ ? 0.6 * ema_loss_ + 0.4 * s.step.loss : s.step.loss;
    ema_psnr_ = have_ ? 0.6 * ema_psnr_ + 0.4 * s.psnr : s.psnr;
    have_ = true;
    ++since_;
    const double now = gs::platform::now_seconds(), dt = now - last_;
    const bool last = e.last;
    if (!(last || (tty_ ? (dt >= 1.0 || s.iteration % 50 == 0) : dt >= 5.0))) return;
    rate_ = since_ / std::max(dt, 1e-9);
    since_ = 0;
    last_ = now;
    const std::string eta = budget ? "budget " + clock_text(e.budget_seconds) + ", " + clock_text(e.remaining_seconds) + " left"
                                   : "ETA " + clock_text((total - s.iteration) / rate_);
    const std::string of = total > 0 ? (budget && !last ? "~" : "") + std::to_string(total) : "?";
    std::fprintf(stderr, "%sit %d/%s  loss %.4f  train PSNR %.2f  anchors %zu  Gaussians %zu  %.1f it/s  %s%s",
                 tty_ ? "\r\033[K" : "", s.iteration, of.c_str(), ema_loss_, ema_psnr_, s.anchors,
                 s.step.gaussians, rate_, eta.c_str(), tty_ ? "" : "\n");
    std::fflush(stderr);
    open_ = tty_;
  }

  bool quiet_, tty_, have_ = false, open_ = false;
  double ema_loss_ = 0, ema_psnr_ = 0, rate_ = 0, last_ = gs::platform::now_seconds();
  int since_ = 0;
};

}  // namespace

int run_train(const gs::jobs::TrainRunOptions& options, bool quiet, gs::jobs::TrainRunSummary* summary) {
  gs::jobs::TrainRunOptions a = options;
#ifndef HBGS_DEVICE
  // --pose-init sfm: COLMAP through the capture library (hbgs-device has none: the job refuses it).
  if (!a.sfm_pose_init) a.sfm_pose_init = &colmap_pose_initializer();
#endif
  ProgressPrinter printer(quiet);
  gs::jobs::TrainRunSummary s;
  const gs::Status st = gs::jobs::train_run(a, [&](const gs::jobs::TrainEvent& e) { printer(e); }, &s);
  printer.break_line();
  if (!st.ok()) return fail("train", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());

  std::printf("hbgs train: %d iterations in %.1f s%s (median %.1f ms per iteration), %zu anchors, ISA %s, %d threads%s\n",
              s.iterations, s.train_seconds,
              s.time_budget > 0 ? (" of a " + std::to_string(long(std::lround(s.time_budget))) + " s time budget").c_str() : "",
              s.median_iteration_ms, s.anchors, s.isa.c_str(), s.threads,
              s.resumed_from >= 0 ? (" (resumed at iteration " + std::to_string(s.resumed_from) + ")").c_str() : "");
  if (s.have_test_views) {
    const gs::model::EvalResult& e = s.final_eval;
    std::printf("  test (%zu views): PSNR %.2f dB, SSIM %.4f", s.test_views, e.psnr, e.ssim);
    if (e.lpips >= 0) std::printf(", %s %.4f", gs::metrics::LpipsAlex::kLabel, e.lpips);
    std::printf(", %.0f Gaussians per view\n", s.mean_gaussians);
    std::printf("  results: %s/%s, %s/%s, renders in %s/test/ours_%d/renders/\n", a.out.c_str(), gs::jobs::kResultsJson,
                a.out.c_str(), gs::jobs::kPerViewJson, a.out.c_str(), s.iterations);
    if (a.eval_every > 0) std::printf("  PSNR vs time: %s/%s (.csv)\n", a.out.c_str(), gs::jobs::kPsnrSvg);
  }
  if (a.optimize_poses || a.pose_noise != "none")
    std::printf("  training poses (Sim(3)-aligned, vs true): rotation mean %.3f deg (input %.3f), translation mean %.4f "
                "(%.2f%% of radius; input %.2f%%)%s\n",
                s.train_pose_final.rotation_mean_deg, s.train_pose_input.rotation_mean_deg, s.train_pose_final.translation_mean,
                100 * s.train_pose_final.translation_mean_frac, 100 * s.train_pose_input.translation_mean_frac,
                a.optimize_poses ? (", refined poses in " + a.out + "/refined_poses/ (COLMAP text, transforms.json)").c_str() : "");
  std::printf("  model: %s (%.2f MB)\n", s.model_path.c_str(), double(s.model_file_bytes) / 1e6);
  if (s.skipped_steps > 0)
    std::printf("  %d steps skipped: their loss or gradients were NaN or infinite (see progress.json)\n", s.skipped_steps);
  if (summary) *summary = std::move(s);
  return kExitOk;
}

Command add_train_command(CLI::App& parent) {
  auto args = std::make_shared<TrainCli>();
  gs::jobs::TrainRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand("train", "Train the hybrid anchor model on a COLMAP or NeRF-style dataset");
  sub->add_option("dataset", o->dataset,
                  "Dataset: a COLMAP folder (images/ and sparse/0/ with points), or a NeRF-style folder or transforms .json file")
      ->required();
  sub->add_option("--out", o->out, "Run folder (model, checkpoint, results, renders)")->required();
  CLI::Option* iterations =
      sub->add_option("--iterations", o->iterations, "Training iterations (with --time-budget: the most it may run)")
          ->capture_default_str()
          ->check(CLI::Range(1, kMaxIterations));
  CLI::Option* time_budget =
      sub->add_option_function<std::string>(
             "--time-budget", [o](const std::string& text) { o->time_budget = gs::jobs::parse_time_budget(text).value(); },
             "Fit the whole schedule into this much training time (60s, 90, 3m, 1.5m, 1h; seconds without a unit), measured "
             "as it runs, then evaluate as usual; the steps count, not loading, evaluation or checkpoints. Without "
             "--iterations there is no iteration cap")
          ->check(CLI::Validator(
              [](std::string& text) {
                gs::Expected<double> seconds = gs::jobs::parse_time_budget(text);
                return seconds.ok() ? std::string() : seconds.status().message().substr(std::string("--time-budget: ").size());
              },
              "DURATION"));
  sub->add_option("--image-features", o->image_features, "Image-based anchor features (none: plain Scaffold-GS)")
      ->capture_default_str()
      ->check(CLI::IsMember({"paper", "visible", "none"}));
  sub->add_option("--background", o->background,
                  "Colour behind the Gaussians; masked views (alpha or masks/) are composited on it: black, white, "
                  "random (a colour per iteration, evaluated on black) or r,g,b in [0, 1]")
      ->capture_default_str()
      ->check(background_validator());
  sub->add_option("--max-anchors", o->max_anchors, "Hard budget on anchors")->capture_default_str()->check(CLI::Range(size_t(1), size_limit(32)));
  sub->add_option("--max-gaussians", o->max_gaussians, "Hard budget on neural Gaussians per view")
      ->capture_default_str()
      ->check(CLI::Range(size_t(1), size_limit(34)));
  sub->add_option("--gaussians-per-pixel", o->gaussians_per_pixel,
                  "Growth budget: neural Gaussians per training view at most this many per pixel (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  sub->add_option("--opacity-reg", o->opacity_reg,
                  "Weight of an opacity term in the loss (x mean opacity of the kept Gaussians): Gaussians that do not pay for themselves fade and are dropped (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--voxel-size", o->voxel_size, "Anchor voxel size in world units (0: automatic)")
      ->capture_default_str()
      ->check(CLI::Range(0.0f, 1e9f));
  sub->add_option("--offsets", o->offsets, "Neural Gaussians (offsets) per anchor, k (-1: 7 with --time-budget or under 15000 iterations, else 10)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 64))
      ->check(CLI::Validator(
          [](std::string& v) { return v == "0" ? std::string("0 offsets: give 1 to 64, or -1 (automatic)") : std::string(); },
          "NOT 0"));
  sub->add_option("--feature-dim", o->feature_dim, "Width of the learned anchor feature")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  sub->add_option("--seed", o->seed, "Seed (MLP initialisation, view order)")->capture_default_str();
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--max-width", o->max_width, "Downscale views to at most this width (0: full size)")
      ->capture_default_str()
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--fisheye-fov", o->fisheye_fov,
                  "Fisheye cameras (OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV) are undistorted to a pinhole "
                  "of this horizontal field of view, degrees (0: the widest up to 120 whose every pixel lies inside the image)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 170.0));
  sub->add_option("--checkpoint-every", o->checkpoint_every, "Write checkpoint.bin every N iterations (0: only at the end)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  sub->add_option("--eval-every", o->eval_every, "Test PSNR into psnr_vs_time.csv/.svg every N iterations (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  sub->add_option("--save-at", o->save_at, "Iterations at which to save model_<it>.hbgs and evaluate fully (ours_<it>)")
      ->capture_default_str();
  sub->add_option("--lpips-weights", o->lpips_weights, "LPIPS-Alex weights folder (default: ../shared/data/lpips_alex if present)");
  sub->add_option("--pose-noise", o->pose_noise,
                  "Seeded noise on the input poses: none, barf:SIGMA (BARF se(3), 0.15 = hard case), rot:DEG,trans:FRAC (of the scene radius); add ,seed:N")
      ->capture_default_str();
  sub->add_option("--pose-noise-on", o->pose_noise_on, "Which poses the noise perturbs")
      ->capture_default_str()
      ->check(CLI::IsMember({"train", "test", "all"}));
  sub->add_flag("--optimize-poses", o->optimize_poses, "Optimise the training poses jointly with the scene (saved to refined_poses/ as COLMAP text and transforms.json)");
  sub->add_flag("!--no-carve-points", o->carve_points,
                "A dataset without a point cloud whose training views all have masks (alpha or masks/) starts from "
                "random points in the cameras' common view, not from points carved from the masks (the visual hull)");
  sub->add_flag("!--no-view-check", o->view_check,
                "Train on every view whatever its pose: skip the check of each training view's agreement with the SfM points, "
                "which holds back views whose pose the points contradict (docs/POSES.md)");
  sub->add_flag("!--no-point-align", o->point_align,
                "With --optimize-poses: skip the photometric alignment of the poses to the SfM points before training");
  sub->add_option("--pose-init", o->pose_init,
                  "With --optimize-poses: sfm = first reconstruct the training images with COLMAP and bring that into the "
                  "dataset's frame (Sim(3) on camera centres, then ICP onto the SfM points): for poses wrong by several degrees")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "sfm"}));
  sub->add_option("--colmap", o->colmap, "COLMAP program for --pose-init sfm")->capture_default_str();
  sub->add_option("--sfm-images", o->sfm_images,
                  "Images COLMAP sees for --pose-init sfm: auto (the dataset's largest images* copy up to 1600 px, else the "
                  "training images), train, or a folder (in the dataset or a path)")
      ->capture_default_str();
  sub->add_option("--register-passes", o->register_passes,
                  "With --optimize-poses: registration passes (every training pose registered against the current model) over the first half")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  sub->add_option("--feature-refresh", o->feature_refresh,
                  "Recompute the image-based features every N iterations (-1: 250 with --optimize-poses, else 0; 0: never)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 100000000));
  sub->add_option("--coarse-levels", o->coarse_levels,
                  "Coarse-to-fine halvings over the first --coarse-fraction of the iterations (-1: 2 with --optimize-poses, 0 with --pose-init sfm, else 1)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 4));
  sub->add_option("--coarse-fraction", o->coarse_fraction,
                  "Share of the iterations the coarse-to-fine levels span (-1: 0.3 with --optimize-poses, else 0.5)")
      ->capture_default_str()
      ->check(CLI::Range(-1.0, 1.0));
  sub->add_option("--pose-lr", o->pose_lr, "Initial pose learning rate (rad; translation x scene extent)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_flag("--resume", o->resume, "Continue the run in --out from its checkpoint (options default to its run.json)");
  sub->add_flag("--force", o->force, "Overwrite an existing run in --out");
  sub->add_flag("-q,--quiet", args->quiet, "No progress output, only the summary");
#ifndef HBGS_DEVICE
  sub->add_flag("--report", args->report, "Write RUN/report.html at the end, as hbgs report RUN does with its defaults");
#endif
  return {sub, [args, sub, iterations, time_budget] {
            // A time budget alone: no iteration cap (a resume takes the recorded cap: it is not "given").
            if (time_budget->count() > 0 && iterations->count() == 0) args->options.iterations = kMaxIterations;
            args->options.given.clear();
            for (const CLI::Option* opt : sub->get_options())
              if (opt->count() > 0 && !opt->get_lnames().empty()) args->options.given.push_back(opt->get_lnames().front());
            const int rc = run_train(args->options, args->quiet, nullptr);
#ifndef HBGS_DEVICE
            if (rc != kExitOk) return rc;
            if (!args->report) {
              std::printf("  report page: hbgs report %s (or train with --report)\n", args->options.out.c_str());
              return rc;
            }
            gs::jobs::ReportRunOptions r;
            r.run = args->options.out;
            r.threads = args->options.threads;
            return run_report(r);
#else
            return rc;
#endif
          }};
}

}  // namespace hbgs::cli
