// SPDX-License-Identifier: MIT
// `hbgs register`: the flags of gs::jobs::register_image / register_views (gs/jobs/register.h) and
// their printed summaries.
//   single image: hbgs register RUN IMAGE --init "qw qx qy qz tx ty tz" [--camera "fx fy cx cy"]
//   batch:        hbgs register RUN --views test|train|all [--init-noise rot:10,trans:0.1]
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/io/colmap.h"
#include "gs/jobs/register.h"

namespace hbgs::cli {
namespace {

constexpr const char* kCmd = "register";

struct RegisterArgs {
  gs::jobs::RegisterRunOptions options;
  bool quiet = false;
};

int failed(const gs::Status& st) {
  return fail(kCmd, st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
}

// The pose in the user's frame; a scene far from the origin (a scene frame of its own) gets every
// digit of its translation.
std::string pose_text(const double q[4], const double t[3], bool far) {
  char buf[200];
  const int d = far ? 17 : 8;
  std::snprintf(buf, sizeof(buf), "%.8g %.8g %.8g %.8g %.*g %.*g %.*g", q[0], q[1], q[2], q[3], d, t[0], d, t[1], d, t[2]);
  return buf;
}

int run_single(const RegisterArgs& args) {
  const gs::jobs::RegisterRunOptions& a = args.options;
  gs::jobs::RegisterImageSummary s;
  if (gs::Status st = gs::jobs::register_image(a, &s); !st.ok()) return failed(st);
  if (!s.note.empty() && !args.quiet) std::fprintf(stderr, "note: %s\n", s.note.c_str());
  const gs::pose::RegisterResult& r = s.result;
  std::printf("hbgs register: %s (%dx%d) against %s\n", a.image.c_str(), s.intrinsics.width, s.intrinsics.height,
              s.source.model_path.c_str());
  std::printf("  pose (qw qx qy qz tx ty tz): %s\n", pose_text(s.pose_qvec, s.pose_tvec, !s.frame.identity()).c_str());
  std::printf("  verdict %s; RMSE %.4f -> %.4f, explained %.2f, coverage %.2f\n", gs::pose::verdict_name(r.verdict),
              r.initial_rmse, r.final_rmse, r.explained, r.coverage);
  std::printf("  moved %.3f deg, %.4g from --init; %d iterations over %d levels, %.1f ms (%s, downscale %d, %d threads)\n",
              s.moved_rotation_deg, s.moved_translation, r.iterations, r.levels, r.milliseconds, a.solver.c_str(), a.downscale,
              s.threads);
  if (!a.json.empty()) std::printf("  json: %s\n", a.json.c_str());
  if (!r.converged()) {
    std::fprintf(stderr, "hbgs register: the verdict is %s, not converged (exit code %d)\n", gs::pose::verdict_name(r.verdict),
                 kExitNotConverged);
    return kExitNotConverged;
  }
  return kExitOk;
}

int run_batch(const RegisterArgs& args) {
  const gs::jobs::RegisterRunOptions& a = args.options;
  auto progress = [&](const gs::jobs::RegisteredView& v, size_t k, size_t n) {
    if (args.quiet) return;
    std::fprintf(stderr, "[%zu/%zu] %s: rotation %.2f -> %.3f deg, translation %.3f -> %.4f r, %s%s%s, %d it, %.0f ms\n", k, n,
                 v.name.c_str(), v.initial_rotation_deg, v.rotation_deg, v.initial_translation_fraction, v.translation_fraction,
                 gs::pose::verdict_name(v.result.verdict), v.relocalized_from.empty() ? "" : " (relocalised from ",
                 v.relocalized_from.empty() ? "" : (v.relocalized_from + ")").c_str(), v.result.iterations, v.result.milliseconds);
  };
  gs::jobs::RegisterViewsSummary s;
  if (gs::Status st = gs::jobs::register_views(a, progress, &s); !st.ok()) return failed(st);
  const double radius = s.scene_radius;
  const size_t n = s.views.size();
  std::printf("hbgs register: %zu %s views of %s against %s (%s, downscale %d, %d threads)\n", n, a.views.c_str(),
              s.source.dataset.c_str(), s.source.model_path.c_str(), a.solver.c_str(), a.downscale, s.threads);
  std::printf("  start: %s (median %.2f deg, %.3f of the scene radius %.4g)\n", s.noise.c_str(), s.median_initial_rotation_deg,
              s.median_initial_translation / radius, radius);
  std::printf("  final: median rotation %.4f deg, median translation %.4g (%.5f of the radius)\n", s.median_rotation_deg,
              s.median_translation, s.median_translation / radius);
  std::printf("  success (< 1 deg and < 1%% of the radius) %zu/%zu, converged verdict %zu/%zu\n", s.success, n, s.converged, n);
  if (a.relocalize > 0)
    std::printf("  relocalised from other views (%zu candidates, up to %d tried per view): %zu\n", s.candidates, a.relocalize,
                s.relocalized);
  std::printf("  time per view: median %.1f ms, mean %.1f ms (total %.1f s)\n", s.median_ms, s.mean_ms, s.total_seconds);
  std::printf("  images: PSNR %.2f dB / SSIM %.4f at the start poses, %.2f dB / %.4f at the registered poses\n",
              s.psnr_at_start, s.ssim_at_start, s.psnr_registered, s.ssim_registered);
  std::printf("  results: %s, poses: %s/ (COLMAP text, transforms.json)\n", s.json_path.c_str(), s.posed_dir.c_str());
  if (s.converged < n) {
    std::fprintf(stderr, "hbgs register: %zu of %zu views did not reach the converged verdict (exit code %d)\n", n - s.converged, n,
                 kExitNotConverged);
    return kExitNotConverged;
  }
  return kExitOk;
}

int run_register(const RegisterArgs& args) {
  const gs::jobs::RegisterRunOptions& a = args.options;
  if (!a.image.empty()) {
    if (!a.views.empty()) {
      fail(kCmd, "give either an IMAGE (with --init) or --views, not both");
      return kExitUsage;
    }
    if (a.init.empty()) {
      fail(kCmd, "an IMAGE needs its start pose: --init \"qw qx qy qz tx ty tz\"");
      return kExitUsage;
    }
    return run_single(args);
  }
  if (a.views.empty()) {
    fail(kCmd, "give an IMAGE with --init \"qw qx qy qz tx ty tz\", or --views test|train|all");
    return kExitUsage;
  }
  if (!a.init.empty() || !a.camera.empty()) {
    fail(kCmd, "--init and --camera apply to a single IMAGE; --views starts from the dataset poses (--init-noise)");
    return kExitUsage;
  }
  return run_batch(args);
}

}  // namespace

Command add_register_command(CLI::App& parent) {
  auto args = std::make_shared<RegisterArgs>();
  gs::jobs::RegisterRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand(
      "register", "Find the camera pose of an image (or of a dataset's views) against a trained model");
  sub->footer("Exit codes: 0 every result has the verdict converged; 3 a result is poor_fit or diverged (its pose and the "
              "files are still written); 1 an error; 2 a usage error.");
  sub->add_option("model", o->input, "Run folder (from hbgs train), .hbgs model file or .hbgc compact model file")->required();
  sub->add_option("image", o->image, "Image to register (single-image mode; needs --init)");
  sub->add_option("--init", o->init, "Start pose \"qw qx qy qz tx ty tz\" (world-to-camera, COLMAP order)");
  sub->add_option("--camera", o->camera,
                  "Intrinsics \"fx fy cx cy\" in pixels of IMAGE (default: the dataset's camera, scaled to the image)");
  sub->add_option("--json", o->json, "Also write the result as JSON to this file");
  sub->add_option("--views", o->views, "Batch mode: register these views of the dataset from perturbed poses")
      ->check(CLI::IsMember({"test", "train", "all"}));
  sub->add_option("--dataset", o->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--init-noise", o->init_noise,
                  "Batch mode: start-pose noise, rot:DEG,trans:FRACTION_OF_RADIUS[,seed:N] or barf:SIGMA")
      ->capture_default_str();
  sub->add_option("--out", o->out, "Batch mode: folder for register.json and registered/ (default: <run>/register)");
  sub->add_option("--downscale", o->downscale, "Resolution divisor of the finest level (4: quarter resolution)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  sub->add_option("--background", o->background,
                  "Colour behind the model; masked views and RGBA images are composited on it: black, white or r,g,b "
                  "(default: the run's training background)")
      ->check(background_validator());
  sub->add_flag("--fixed-point", o->fixed_point, "On-device mode: fixed-point keyframe renders (int16 blending)");
  sub->add_option("--solver", o->solver, "keyframe (direct alignment to rendered keyframes, then LM polish), lm (Levenberg-Marquardt with the renderer's analytic pose Jacobian at every level) or adam")
      ->capture_default_str()
      ->check(CLI::IsMember({"keyframe", "lm", "adam"}));
  sub->add_option("--time-budget-ms", o->time_budget_ms, "Stop a view after this many ms, keeping the best pose (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  sub->add_option("--relocalize", o->relocalize,
                  "Batch mode: a view that does not converge from its start is registered again from this many of the "
                  "dataset's views outside the split (training views for --views test), those whose renders look most "
                  "like it (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_flag("-q,--quiet", args->quiet, "No per-view progress lines");
  return {sub, [args] { return run_register(*args); }};
}

}  // namespace hbgs::cli
