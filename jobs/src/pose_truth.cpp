// SPDX-License-Identifier: MIT
// Pose truth, noise and errors for the jobs (see gs/jobs/pose_truth.h).
#include "gs/jobs/pose_truth.h"

#include <map>

#include "json_util.h"

namespace gs::jobs {

Status apply_pose_noise(io::Dataset* ds, const std::string& spec, const std::string& which, PoseTruth* truth) {
  pose::PoseNoise noise;
  if (Status st = pose::parse_pose_noise(spec, &noise); !st.ok()) return invalid_argument("--pose-noise: " + st.message());
  if (which != "train" && which != "test" && which != "all")
    return invalid_argument("--pose-noise-on: '" + which + "' is not one of train, test, all");
  truth->poses.clear();
  std::vector<Pose> train;
  for (const io::DatasetView& v : ds->views) {
    truth->poses.push_back(v.camera.pose);
    if (!v.is_test) train.push_back(v.camera.pose);
  }
  pose::scene_frame(train.data(), train.size(), truth->centre, &truth->radius);
  if (noise.kind == pose::PoseNoise::kNone) return Status::Ok();
  // Each view draws its own stream (seeded by its index in the whole dataset), so which views are
  // perturbed does not change any one view's noise.
  std::vector<Pose> all = truth->poses;
  pose::perturb_poses(noise, truth->centre, truth->radius, all.data(), all.size());
  for (size_t i = 0; i < ds->views.size(); ++i) {
    const bool test = ds->views[i].is_test;
    if (which == "all" || (which == "test") == test) ds->views[i].camera.pose = all[i];
  }
  return Status::Ok();
}

pose::PoseErrors errors_for(const std::vector<Pose>& estimated, const std::vector<size_t>& views,
                                const PoseTruth& truth, bool align) {
  std::vector<Pose> gt;
  for (size_t i : views) gt.push_back(truth.poses[i]);
  return pose::pose_errors(estimated.data(), gt.data(), gt.size(), truth.radius, align);
}

nlohmann::json pose_errors_json(const pose::PoseErrors& e, bool per_view, const std::vector<std::string>& names) {
  nlohmann::json j = {{"views", e.count},
                      {"sim3_aligned", e.aligned},
                      {"sim3_scale", e.scale},
                      {"rotation_mean_deg", e.rotation_mean_deg},
                      {"rotation_median_deg", e.rotation_median_deg},
                      {"rotation_max_deg", e.rotation_max_deg},
                      {"translation_mean", e.translation_mean},
                      {"translation_median", e.translation_median},
                      {"translation_mean_fraction_of_radius", e.translation_mean_frac},
                      {"ate_rmse", e.ate_rmse}};
  if (per_view) {
    nlohmann::json rot = nlohmann::json::object(), tr = nlohmann::json::object();
    for (size_t i = 0; i < e.rotation_deg.size(); ++i) {
      const std::string key = i < names.size() ? names[i] : std::to_string(i);
      rot[key] = e.rotation_deg[i];
      tr[key] = e.translation[i];
    }
    j["per_view_rotation_deg"] = std::move(rot);
    j["per_view_translation"] = std::move(tr);
  }
  return j;
}

Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                             const std::vector<Pose>& poses, const std::string& out_dir) {
  Expected<io::ColmapModel> model = io::read_colmap_model(dataset_root + "/sparse/0");
  if (!model.ok()) return model.status();
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < names.size(); ++i) index[names[i]] = i;
  size_t replaced = 0;
  for (io::ColmapImage& im : model->images) {
    const auto it = index.find(im.name);
    if (it == index.end()) continue;
    io::pose_to_colmap(poses[it->second], im.qvec, im.tvec);
    ++replaced;
  }
  if (replaced != names.size())
    return invalid_argument(dataset_root + "/sparse/0: " + std::to_string(names.size() - replaced) +
                                " of the posed images are not in the COLMAP model");
  return io::write_colmap_text(*model, out_dir);
}

}  // namespace gs::jobs
