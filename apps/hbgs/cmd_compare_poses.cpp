// SPDX-License-Identifier: MIT
// `hbgs compare-poses TRUTH ESTIMATE`: how far one set of camera poses is from another (a COLMAP
// model each, images matched by name), after a Sim(3) fit on the camera centres, because a
// reconstruction's frame and scale are arbitrary. With --max-rot-deg / --max-centre-frac it is a
// check that fails (exit 1) when the errors are larger, which is how the ingest test uses it.
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
};

int run_compare(const CompareArgs& a) {
  gs::Expected<gs::jobs::PoseComparison> c = gs::jobs::compare_pose_models(a.truth, a.estimate, a.json);
  if (!c.ok()) return fail("compare-poses", c.status().code() == gs::StatusCode::kInvalidArgument ? c.status().message()
                                                                                             : c.status().to_string());
  const gs::pose::PoseErrors& err = c->errors;
  std::printf("compare-poses: %zu images matched (%zu in the estimate, %zu in the truth)%s\n", c->names.size(),
              c->estimate_images, c->truth_images, err.aligned ? ", Sim(3)-aligned" : ", NOT aligned (degenerate)");
  std::printf("  rotation error: mean %.4f, median %.4f, max %.4f degrees\n", err.rotation_mean_deg,
              err.rotation_median_deg, err.rotation_max_deg);
  std::printf("  relative rotation between consecutive images: mean %.4f, max %.4f degrees\n", c->relative_rotation_mean_deg,
              c->relative_rotation_max_deg);
  std::printf("  centre error:   mean %.5f (%.3f %% of the radius %.3f), median %.5f; ATE RMSE %.5f\n",
              err.translation_mean, 100 * err.translation_mean_frac, c->scene_radius, err.translation_median, err.ate_rmse);
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
  CLI::App* sub = parent.add_subcommand("compare-poses", "Pose errors of one COLMAP model against another (Sim(3)-aligned)");
  sub->add_option("truth", args->truth, "Reference model folder or dataset root")->required();
  sub->add_option("estimate", args->estimate, "Estimated model folder or dataset root")->required();
  sub->add_option("--json", args->json, "Also write the errors (and per image) to this JSON file");
  sub->add_option("--max-rot-deg", args->max_rot_deg, "Fail if the mean rotation error exceeds this (degrees)");
  sub->add_option("--max-centre-frac", args->max_centre_frac,
                  "Fail if the mean camera-centre error exceeds this fraction of the scene radius");
  return {sub, [args] { return run_compare(*args); }};
}

}  // namespace hbgs::cli
