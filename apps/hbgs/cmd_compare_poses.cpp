// SPDX-License-Identifier: MIT
// `hbgs compare-poses TRUTH ESTIMATE`: how far one set of camera poses is from another. Each side
// is a COLMAP model (images matched by name) or a TUM trajectory file (poses matched by timestamp,
// or by order with --by-order); the estimate is Sim(3)-fitted on the camera centres first, because a
// reconstruction's frame and scale are arbitrary, unless --no-align (tracking against a model gives
// poses in the truth's frame). Prints rotation and centre errors, ATE and RPE, optionally per frame
// (--per-frame CSV, --json); --lost leaves frames the estimate marks as lost out. With --max-rot-deg
// / --max-centre-frac it is a check that fails (exit 1) when the errors are larger, which is how
// the ingest test uses it.
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/jobs/pose_truth.h"

namespace hbgs::cli {
namespace {

struct CompareArgs {
  std::string truth, estimate, json;
  double max_rot_deg = 0, max_centre_frac = 0;  // 0: no check
  bool no_align = false, by_order = false;
  std::string lost, per_frame;
  double radius = 0;
};

int run_compare(const CompareArgs& a) {
  gs::jobs::PoseCompareOptions options;
  options.align = !a.no_align;
  options.by_order = a.by_order;
  options.lost_path = a.lost;
  options.radius = a.radius;
  options.json_path = a.json;
  options.per_frame_csv = a.per_frame;
  gs::Expected<gs::jobs::PoseComparison> c = gs::jobs::compare_poses(a.truth, a.estimate, options);
  if (!c.ok()) return fail("compare-poses", c.status().code() == gs::StatusCode::kInvalidArgument ? c.status().message()
                                                                                             : c.status().to_string());
  const gs::pose::PoseErrors& err = c->errors;
  const char* alignment = a.no_align ? ", not aligned (--no-align)" : err.aligned ? ", Sim(3)-aligned" : ", NOT aligned (degenerate)";
  if (c->matching == "name") {
    std::printf("compare-poses: %zu images matched (%zu in the estimate, %zu in the truth)%s\n", c->names.size(),
                c->estimate_images, c->truth_images, alignment);
  } else {
    char matched[96] = "order";
    if (c->matching == "time") std::snprintf(matched, sizeof matched, "timestamp within %.4g s", c->time_tolerance);
    std::printf("compare-poses: %zu frames compared (%zu poses in the estimate, %zu in the truth; matched by %s)%s\n",
                c->names.size(), c->estimate_images, c->truth_images, matched, alignment);
  }
  std::printf("  rotation error: mean %.4f, median %.4f, max %.4f degrees\n", err.rotation_mean_deg,
              err.rotation_median_deg, err.rotation_max_deg);
  std::printf("  relative rotation between consecutive images: mean %.4f, max %.4f degrees\n", c->relative_rotation_mean_deg,
              c->relative_rotation_max_deg);
  std::printf("  centre error:   mean %.5f (%.3f %% of the radius %.3f), median %.5f; ATE RMSE %.5f\n",
              err.translation_mean, 100 * err.translation_mean_frac, c->scene_radius, err.translation_median, err.ate_rmse);
  std::printf("                  median %.3f %% of the radius, max %.5f (%.3f %%)\n", 100 * err.translation_median / c->scene_radius,
              c->centre_max, 100 * c->centre_max / c->scene_radius);
  std::printf("  RPE (%zu consecutive pairs): rotation mean %.4f, median %.4f, max %.4f degrees; translation mean %.5f, "
              "median %.5f, max %.5f\n",
              c->rpe.pairs, c->rpe.rotation_mean_deg, c->rpe.rotation_median_deg, c->rpe.rotation_max_deg,
              c->rpe.translation_mean, c->rpe.translation_median, c->rpe.translation_max);
  if (c->lost > 0 || c->missing > 0 || c->unmatched > 0 || !a.lost.empty())
    std::printf("  frames: %zu left out as lost, %zu missing from the estimate (%zu of them listed as lost), %zu estimate "
                "poses matching no true frame\n",
                c->lost, c->missing, c->missing_listed_lost, c->unmatched);
  if (a.max_rot_deg > 0 && !(err.rotation_mean_deg <= a.max_rot_deg))
    return fail("compare-poses", "mean rotation error " + std::to_string(err.rotation_mean_deg) + " deg exceeds " +
                                     std::to_string(a.max_rot_deg));
  if (a.max_centre_frac > 0 && !(err.translation_mean_frac <= a.max_centre_frac))
    return fail("compare-poses", "mean centre error " + std::to_string(err.translation_mean_frac) +
                                     " of the radius exceeds " + std::to_string(a.max_centre_frac));
  return kExitOk;
}

}  // namespace

Command add_compare_poses_command(CLI::App& parent) {
  auto args = std::make_shared<CompareArgs>();
  CLI::App* sub = parent.add_subcommand(
      "compare-poses", "Pose errors of one set of camera poses against another (COLMAP models or TUM trajectories)");
  sub->add_option("truth", args->truth, "Reference: a COLMAP model folder or dataset root, or a TUM trajectory file")->required();
  sub->add_option("estimate", args->estimate, "Estimate: a COLMAP model folder or dataset root, or a TUM trajectory file")
      ->required();
  sub->add_option("--json", args->json, "Also write the errors (per image and per true frame) to this JSON file");
  sub->add_option("--per-frame", args->per_frame,
                  "Write one CSV row per true frame: index, name, time, status (compared, lost, missing), rotation error "
                  "(degrees), centre error and its fraction of the radius");
  sub->add_flag("--no-align", args->no_align,
                "Compare the poses as they are, without the Sim(3) fit (both in the same frame, as tracking against a "
                "model of the truth's dataset gives)");
  sub->add_flag("--by-order", args->by_order,
                "Pair the i-th pose of each side (TUM by time, COLMAP by image name) instead of matching timestamps or "
                "names; needed between a TUM file and a COLMAP model");
  sub->add_option("--lost", args->lost,
                  "A file naming the estimate's lost frames, one per line (a timestamp or an image name; '#' comments): "
                  "they are not counted");
  sub->add_option("--radius", args->radius,
                  "Centre errors as fractions of this radius (default: of the compared true camera centres; a synth "
                  "trajectory's trajectory.json gives its dataset's as scene.dataset_radius)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-rot-deg", args->max_rot_deg, "Fail if the mean rotation error exceeds this (degrees)");
  sub->add_option("--max-centre-frac", args->max_centre_frac,
                  "Fail if the mean camera-centre error exceeds this fraction of the scene radius");
  return {sub, [args] { return run_compare(*args); }};
}

}  // namespace hbgs::cli
