// SPDX-License-Identifier: MIT
// What train, register and eval share about camera poses: applying the seeded pose-noise protocol
// to a loaded dataset (keeping the true poses), pose errors as JSON, and writing a COLMAP text
// model with refined poses.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/pose.h"
#include "gs/status.h"

namespace hbgs::cli {

// True poses of the views (before any noise) and the scene frame of the training cameras.
struct PoseTruth {
  std::vector<gs::Pose> poses;  // [dataset.views]
  double centre[3] = {0, 0, 0};
  double radius = 1;            // largest distance of a training camera centre from their mean
};

// Records the true poses, then perturbs the poses of the views in `which` ("train", "test" or
// "all") as `spec` says (gs::pose::parse_pose_noise). Errors name the option.
gs::Status apply_pose_noise(gs::io::Dataset* dataset, const std::string& spec, const std::string& which,
                            PoseTruth* truth);

// Errors of cameras[i] against truth for the views in `views` (indices into the dataset).
gs::pose::PoseErrors errors_for(const std::vector<gs::Pose>& estimated, const std::vector<size_t>& views,
                                const PoseTruth& truth, bool align);
nlohmann::json pose_errors_json(const gs::pose::PoseErrors& e, bool per_view, const std::vector<std::string>& names = {});

// Writes <out_dir>/{cameras,images,points3D}.txt: the dataset's own COLMAP model with the poses of
// the named images replaced (names[i] gets poses[i]).
gs::Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                             const std::vector<gs::Pose>& poses, const std::string& out_dir);

}  // namespace hbgs::cli
