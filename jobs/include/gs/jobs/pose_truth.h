// SPDX-License-Identifier: MIT
// What the training, registration and evaluation jobs share about camera poses: applying the seeded
// pose-noise protocol to a loaded dataset while keeping the true poses, errors against them, and
// writing a COLMAP text model with refined poses.
#pragma once

#include <string>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/pose/pose.h"
#include "gs/status.h"

namespace gs::jobs {

// True poses of the views (before any noise) and the scene frame of the training cameras.
struct PoseTruth {
  std::vector<Pose> poses;  // [dataset.views]
  double centre[3] = {0, 0, 0};
  double radius = 1;        // largest distance of a training camera centre from their mean
  // User units per unit of the dataset's scene frame (1 / io::Dataset::frame.scale): poses, centre
  // and radius are in the frame; reported distances (errors_for, register.json) are multiplied by it.
  double unit = 1;
};

// Records the true poses, then perturbs the poses of the views in `which` ("train", "test" or
// "all") as `spec` says (gs::pose::parse_pose_noise). Errors name the option.
Status apply_pose_noise(io::Dataset* dataset, const std::string& spec, const std::string& which, PoseTruth* truth);

// Errors of estimated[i] against the truth of dataset view views[i].
pose::PoseErrors errors_for(const std::vector<Pose>& estimated, const std::vector<size_t>& views,
                            const PoseTruth& truth, bool align);

// Writes <out_dir>/{cameras,images,points3D}.txt: the dataset's own COLMAP model with the poses of
// the named images replaced (names[i] gets poses[i]); for a NeRF-style dataset, a model made of its
// views (io::read_dataset_files: PINHOLE or OPENCV cameras, images named by their path relative to
// the json, no points). Beside it <out_dir>/transforms.json (kPosedTransformsJson): the same views
// and poses in nerfstudio's layout (io::write_transforms_json), file_path and mask_path relative to
// out_dir leading to the dataset's own images and masks (so ns-train and other tools read them in
// place; hbgs's loader refuses '..' in dataset paths), with the dataset's split as
// train_filenames / val_filenames / test_filenames (val = test) when it has test views.
inline constexpr const char* kPosedTransformsJson = "transforms.json";
// The poses are in the scene frame `frame` (the model's, gs/scene_frame.h) and are written in the
// dataset's own frame.
Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                         const std::vector<Pose>& poses, const std::string& out_dir, const SceneFrame& frame = {});

// Pose errors of one COLMAP model against another (`hbgs compare-poses`): images matched by name
// (at least 3), the estimate Sim(3)-aligned onto the truth by camera centres, plus the relative
// rotation between consecutive matched images, which no alignment can change. truth and estimate are
// model folders or dataset roots (with sparse/0); json_path non-empty: also written there (atomic).
struct PoseComparison {
  size_t truth_images = 0, estimate_images = 0;
  std::vector<std::string> names;  // the matched images, in the estimate's order
  double scene_radius = 1;         // of the true camera centres
  pose::PoseErrors errors;
  double relative_rotation_mean_deg = 0, relative_rotation_max_deg = 0;
};
Expected<PoseComparison> compare_pose_models(const std::string& truth, const std::string& estimate,
                                             const std::string& json_path = "");

}  // namespace gs::jobs
