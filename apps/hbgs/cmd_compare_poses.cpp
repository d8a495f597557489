// SPDX-License-Identifier: MIT
// `hbgs compare-poses TRUTH ESTIMATE`: how far one set of camera poses is from another (a COLMAP
// model each, images matched by name), after a Sim(3) fit on the camera centres, because a
// reconstruction's frame and scale are arbitrary. With --max-rot-deg / --max-centre-frac it is a
// check that fails (exit 1) when the errors are larger, which is how the ingest test uses it.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common.h"
#include "gs/io/colmap.h"
#include "gs/platform/file.h"
#include "gs/pose/pose.h"

namespace hbgs::cli {
namespace {

struct CompareArgs {
  std::string truth, estimate, json;
  double max_rot_deg = 0, max_centre_frac = 0;  // 0: no check
};

// A dataset root (with sparse/0) or a model folder.
gs::Expected<gs::io::ColmapModel> read_model(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(path) / "sparse" / "0", ec))
    return gs::io::read_colmap_model(path + "/sparse/0");
  return gs::io::read_colmap_model(path);
}

// Rotation between consecutive matched views, truth against estimate, in degrees: the relative
// orientation error, which no choice of alignment can change (a Sim(3) fitted on camera centres
// can leave a global tilt when the centres lie near a line or plane).
double relative_rotation_error_deg(const gs::Pose& ta, const gs::Pose& tb, const gs::Pose& ea, const gs::Pose& eb) {
  auto rel = [](const gs::Pose& a, const gs::Pose& b) {  // R_a R_b^T
    gs::Pose r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        double s = 0;
        for (int k = 0; k < 3; ++k) s += double(a.R[3 * i + k]) * double(b.R[3 * j + k]);
        r.R[3 * i + j] = float(s);
      }
    return r;
  };
  return gs::pose::rotation_error_deg(rel(ta, tb), rel(ea, eb));
}

int run_compare(const CompareArgs& a) {
  gs::Expected<gs::io::ColmapModel> truth = read_model(a.truth), est = read_model(a.estimate);
  if (!truth.ok()) return fail("compare-poses", truth.status().to_string());
  if (!est.ok()) return fail("compare-poses", est.status().to_string());
  std::map<std::string, const gs::io::ColmapImage*> by_name;
  for (const gs::io::ColmapImage& im : truth->images) by_name[im.name] = &im;
  std::vector<gs::Pose> t, e;
  std::vector<std::string> names;
  for (const gs::io::ColmapImage& im : est->images) {
    auto it = by_name.find(im.name);
    if (it == by_name.end()) continue;
    t.push_back(gs::io::pose_from_colmap(it->second->qvec, it->second->tvec));
    e.push_back(gs::io::pose_from_colmap(im.qvec, im.tvec));
    names.push_back(im.name);
  }
  if (t.size() < 3)
    return fail("compare-poses", "only " + std::to_string(t.size()) +
                                     " images are in both models (matched by name); at least 3 are needed");
  double centre[3], radius = 1;
  gs::pose::scene_frame(t.data(), t.size(), centre, &radius);
  const gs::pose::PoseErrors err = gs::pose::pose_errors(e.data(), t.data(), t.size(), radius, true);
  std::vector<double> relative;
  for (size_t i = 1; i < t.size(); ++i) relative.push_back(relative_rotation_error_deg(t[i - 1], t[i], e[i - 1], e[i]));
  const double relative_mean = gs::mean(relative), relative_max = relative.empty() ? 0.0 : *std::max_element(relative.begin(), relative.end());
  std::printf("compare-poses: %zu images matched (%zu in the estimate, %zu in the truth)%s\n", t.size(),
              est->images.size(), truth->images.size(), err.aligned ? ", Sim(3)-aligned" : ", NOT aligned (degenerate)");
  std::printf("  rotation error: mean %.4f, median %.4f, max %.4f degrees\n", err.rotation_mean_deg,
              err.rotation_median_deg, err.rotation_max_deg);
  std::printf("  relative rotation between consecutive images: mean %.4f, max %.4f degrees\n", relative_mean, relative_max);
  std::printf("  centre error:   mean %.5f (%.3f %% of the radius %.3f), median %.5f; ATE RMSE %.5f\n",
              err.translation_mean, 100 * err.translation_mean_frac, radius, err.translation_median, err.ate_rmse);
  if (!a.json.empty()) {
    nlohmann::json j = {{"matched", t.size()},
                        {"aligned", err.aligned},
                        {"scale", err.scale},
                        {"scene_radius", radius},
                        {"rotation_deg", {{"mean", err.rotation_mean_deg}, {"median", err.rotation_median_deg}, {"max", err.rotation_max_deg}}},
                        {"centre", {{"mean", err.translation_mean}, {"median", err.translation_median}, {"mean_frac", err.translation_mean_frac}}},
                        {"ate_rmse", err.ate_rmse},
                        {"relative_rotation_deg", {{"mean", relative_mean}, {"max", relative_max}}},
                        {"per_image", nlohmann::json::array()}};
    for (size_t i = 0; i < names.size(); ++i)
      j["per_image"].push_back({{"name", names[i]}, {"rotation_deg", err.rotation_deg[i]}, {"centre", err.translation[i]}});
    if (gs::Status st = gs::platform::write_file_atomic(a.json, j.dump(2) + "\n"); !st.ok())
      return fail("compare-poses", st.to_string());
  }
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
