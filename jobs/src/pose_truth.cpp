// SPDX-License-Identifier: MIT
// Pose truth, noise and errors for the jobs (see gs/jobs/pose_truth.h).
#include "gs/jobs/pose_truth.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <system_error>

#include "gs/io/transforms.h"
#include "gs/jobs/run_folder.h"
#include "gs/platform/file.h"
#include "gs/stats.h"

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
  truth->unit = 1.0 / ds->frame.scale;
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
  pose::PoseErrors e = pose::pose_errors(estimated.data(), gt.data(), gt.size(), truth.radius, align);
  if (truth.unit != 1) {  // distances in the user's units (fractions of the radius need nothing)
    e.translation_mean *= truth.unit, e.translation_median *= truth.unit, e.ate_rmse *= truth.unit;
    for (double& t : e.translation) t *= truth.unit;
  }
  return e;
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

namespace {

// `path` as seen from `folder`: relative when it can be (symbolic links resolved on both sides, as
// the OS resolves a '..' when following it), else absolute.
std::string path_from(const std::string& folder, const std::string& path) {
  std::error_code ec;
  const std::filesystem::path rel = std::filesystem::relative(path, folder, ec);
  return ec || rel.empty() ? absolute_path(path) : rel.generic_string();
}

// <out_dir>/transforms.json: the views of `files` with their (replaced) poses in nerfstudio's
// layout, file_path and mask_path leading from out_dir to the dataset's own files, and the
// dataset's split as train/val/test lists (val = test: nerfstudio asks for the val list once any
// list is given).
Status write_posed_transforms(const io::DatasetFiles& files, const std::string& out_dir) {
  io::TransformsFile t;
  std::vector<std::string> train, test;
  for (const io::DatasetFileView& v : files.views) {
    io::TransformsFrame f;
    f.file_path = path_from(out_dir, v.image_path);
    if (!v.mask_path.empty()) f.mask_path = path_from(out_dir, v.mask_path);
    Expected<io::TransformsIntrinsics> intrinsics = io::transforms_intrinsics(v.camera);
    if (!intrinsics.ok()) return Status(intrinsics.status().code(), v.name + ": " + intrinsics.status().message());
    f.intrinsics = *intrinsics;
    const io::ColmapImage& im = files.model.images[v.model_image];
    io::transform_matrix_from_pose(im.qvec, im.tvec, f.transform_matrix);
    (v.is_test ? test : train).push_back(f.file_path);
    t.frames.push_back(std::move(f));
  }
  // Without test views the lists would leave nerfstudio an empty evaluation split: none then.
  if (!test.empty()) t.train_filenames = train, t.val_filenames = test, t.test_filenames = test;
  return io::write_transforms_json((std::filesystem::path(out_dir) / kPosedTransformsJson).string(), t);
}

}  // namespace

Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                         const std::vector<Pose>& poses, const std::string& out_dir, const SceneFrame& frame) {
  Expected<io::DatasetFiles> files = io::read_dataset_files(dataset_root);
  if (!files.ok()) return files.status();
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < names.size(); ++i) index[names[i]] = i;
  size_t replaced = 0;
  for (io::ColmapImage& im : files->model.images) {
    const auto it = index.find(im.name);
    if (it == index.end()) continue;
    io::pose_to_colmap(frame, poses[it->second], im.qvec, im.tvec);
    ++replaced;
  }
  if (replaced != names.size())
    return invalid_argument(dataset_root + ": " + std::to_string(names.size() - replaced) + " of the posed images are not in the dataset");
  GS_RETURN_IF_ERROR(io::write_colmap_text(files->model, out_dir));
  return write_posed_transforms(*files, out_dir);
}

namespace {

// A dataset root (with sparse/0) or a model folder.
Expected<io::ColmapModel> read_model(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(path) / "sparse" / "0", ec)) return io::read_colmap_model(path + "/sparse/0");
  return io::read_colmap_model(path);
}

}  // namespace

Expected<PoseComparison> compare_pose_models(const std::string& truth_path, const std::string& estimate_path,
                                             const std::string& json_path) {
  Expected<io::ColmapModel> truth = read_model(truth_path), est = read_model(estimate_path);
  if (!truth.ok()) return truth.status();
  if (!est.ok()) return est.status();
  PoseComparison c;
  c.truth_images = truth->images.size();
  c.estimate_images = est->images.size();
  std::map<std::string, const io::ColmapImage*> by_name;
  for (const io::ColmapImage& im : truth->images) by_name[im.name] = &im;
  std::vector<Pose> t, e;
  for (const io::ColmapImage& im : est->images) {
    auto it = by_name.find(im.name);
    if (it == by_name.end()) continue;
    t.push_back(io::pose_from_colmap(it->second->qvec, it->second->tvec));
    e.push_back(io::pose_from_colmap(im.qvec, im.tvec));
    c.names.push_back(im.name);
  }
  if (t.size() < 3)
    return invalid_argument("only " + std::to_string(t.size()) + " images are in both models (matched by name); at least 3 are needed");
  double centre[3];
  pose::scene_frame(t.data(), t.size(), centre, &c.scene_radius);
  c.errors = pose::pose_errors(e.data(), t.data(), t.size(), c.scene_radius, true);
  std::vector<double> relative;
  for (size_t i = 1; i < t.size(); ++i) relative.push_back(pose::relative_rotation_error_deg(t[i - 1], t[i], e[i - 1], e[i]));
  c.relative_rotation_mean_deg = mean(relative);
  c.relative_rotation_max_deg = relative.empty() ? 0.0 : *std::max_element(relative.begin(), relative.end());
  if (!json_path.empty()) {
    const pose::PoseErrors& err = c.errors;
    nlohmann::json j = {{"matched", t.size()},
                        {"aligned", err.aligned},
                        {"scale", err.scale},
                        {"scene_radius", c.scene_radius},
                        {"rotation_deg", {{"mean", err.rotation_mean_deg}, {"median", err.rotation_median_deg}, {"max", err.rotation_max_deg}}},
                        {"centre", {{"mean", err.translation_mean}, {"median", err.translation_median}, {"mean_frac", err.translation_mean_frac}}},
                        {"ate_rmse", err.ate_rmse},
                        {"relative_rotation_deg", {{"mean", c.relative_rotation_mean_deg}, {"max", c.relative_rotation_max_deg}}},
                        {"per_image", nlohmann::json::array()}};
    for (size_t i = 0; i < c.names.size(); ++i)
      j["per_image"].push_back({{"name", c.names[i]}, {"rotation_deg", err.rotation_deg[i]}, {"centre", err.translation[i]}});
    GS_RETURN_IF_ERROR(platform::write_file_atomic(json_path, j.dump(2) + "\n"));
  }
  return c;
}

}  // namespace gs::jobs
