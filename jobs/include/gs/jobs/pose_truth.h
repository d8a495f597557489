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
// train_filenames / val_filenames / test_filenames (val = test) when it has test views; not for a
// dataset with a fisheye camera (OPENCV_FISHEYE, FOV, ...: the COLMAP model keeps it as stored).
inline constexpr const char* kPosedTransformsJson = "transforms.json";
// The poses are in the scene frame `frame` (the model's, gs/scene_frame.h) and are written in the
// dataset's own frame.
Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                         const std::vector<Pose>& poses, const std::string& out_dir, const SceneFrame& frame = {});

// Pose errors of one set of camera poses against another (`hbgs compare-poses`). Each side is a
// COLMAP model (a model folder or a dataset root with sparse/0) or a TUM trajectory file
// (gs/io/tum.h; any regular file is read as one).
//   Matching: two COLMAP models by image name (at least 3 in both), the comparison in the
//   estimate's order; two TUM files by timestamp (each estimate pose to the nearest true time,
//   within half the median interval of the true times; a true frame matched once), the comparison
//   in time order; with by_order (and only so when one side is a COLMAP model and the other a TUM
//   file) the i-th pose of each side, TUM in time order and COLMAP by image name, which needs the
//   same number of poses on both sides.
//   Alignment: the estimate Sim(3)-aligned onto the truth by camera centres (a reconstruction's
//   frame and scale are arbitrary; pose::pose_errors), or with align = false compared as it is
//   (poses already in the truth's frame, as tracking against a model of the same dataset gives).
//   Lost frames: lost_path lists frames the estimate marks as lost, one per line (the first word;
//   '#' starts a comment): a timestamp (matched within the same half interval) or an image name.
//   Those frames are not counted; truth frames with no estimate pose are counted as missing.
//   Errors: per compared frame the rotation (degrees) and the camera-centre distance (truth units,
//   and as a fraction of the radius: `radius` when > 0, else that of the compared true centres);
//   ATE = RMS of the centre errors; RPE between consecutive true frames both compared (Sturm et al.:
//   the error of the relative motion, rotation in degrees and translation in truth units, the
//   estimate's translations scaled by the Sim(3)'s scale), plus, as before, the relative rotation
//   between consecutive compared images in comparison order.
struct PoseCompareOptions {
  bool align = true;
  bool by_order = false;
  std::string lost_path;      // optional
  double radius = 0;          // > 0: centre-error fractions of this radius
  std::string json_path;      // non-empty: the result as JSON there (atomic)
  std::string per_frame_csv;  // non-empty: one row per true frame there (atomic)
};

// One true frame's outcome, in the truth's order (COLMAP: by image name; TUM: by time).
struct FrameComparison {
  enum class Status { kCompared, kLost, kMissing };
  std::string name;     // COLMAP image name (empty for TUM)
  double time = -1;     // TUM timestamp, seconds (-1 for COLMAP)
  Status status = Status::kMissing;
  double rotation_deg = 0, centre = 0, centre_frac = 0;  // kCompared only
};
const char* frame_status_name(FrameComparison::Status s);  // "compared", "lost", "missing"

struct RelativePoseErrors {
  size_t pairs = 0;
  double rotation_mean_deg = 0, rotation_median_deg = 0, rotation_max_deg = 0;
  double translation_mean = 0, translation_median = 0, translation_max = 0;
};

struct PoseComparison {
  size_t truth_images = 0, estimate_images = 0;  // poses on each side
  std::string matching;            // "name", "time" or "order"
  double time_tolerance = 0;       // "time": seconds
  std::vector<std::string> names;  // the compared frames (image names, or TUM times as text), in comparison order
  double scene_radius = 1;         // of the compared true centres, or options.radius
  pose::PoseErrors errors;
  double centre_max = 0;           // largest centre error
  double relative_rotation_mean_deg = 0, relative_rotation_max_deg = 0;
  RelativePoseErrors rpe;
  size_t lost = 0;                 // estimate poses matched to a true frame but listed as lost
  size_t missing = 0;              // true frames without an estimate pose
  size_t missing_listed_lost = 0;  // of those, how many the lost list names
  size_t unmatched = 0;            // estimate poses that match no true frame (or one already matched)
  std::vector<FrameComparison> frames;  // every true frame, in the truth's order
};
Expected<PoseComparison> compare_poses(const std::string& truth, const std::string& estimate,
                                       const PoseCompareOptions& options = {});
// compare_poses of two COLMAP models (or TUM files) with the defaults, JSON written to json_path
// when it is not empty.
Expected<PoseComparison> compare_pose_models(const std::string& truth, const std::string& estimate,
                                             const std::string& json_path = "");

}  // namespace gs::jobs
