// SPDX-License-Identifier: MIT
// Structure from motion by running Debian's `colmap` command on a folder of frames: feature
// extraction (CPU SIFT, one shared camera), sequential or exhaustive matching, incremental mapping,
// and undistortion to PINHOLE. The result is a dataset `hbgs train` reads directly:
// <dataset>/images/*.png and <dataset>/sparse/0/{cameras,images,points3D}.bin. Everything COLMAP
// prints goes to a log file; progress is reported per stage.
#pragma once

#include <functional>
#include <string>

#include "gs/status.h"

namespace gs::capture {

enum class Matcher { kSequential, kExhaustive };

// The camera models COLMAP's feature extractor takes (ColmapOptions::camera_model).
inline constexpr const char* kColmapCameraModels[] = {
    "SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "FULL_OPENCV", "OPENCV_FISHEYE",
    "RADIAL_FISHEYE", "SIMPLE_RADIAL_FISHEYE", "FOV", "THIN_PRISM_FISHEYE"};
// Whether hbgs undistorts this model itself (the fisheye models io::load_dataset reads).
bool is_fisheye_model_name(const std::string& model);
Expected<Matcher> parse_matcher(const std::string& name);  // "sequential", "exhaustive"

struct ColmapOptions {
  std::string colmap = "colmap";          // program name or path
  Matcher matcher = Matcher::kSequential;  // video frames are in order: sequential is linear time
  // COLMAP's camera model for the one shared camera (--ImageReader.camera_model; kColmapCameraModels).
  // The fisheye models (OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV) are not given
  // to COLMAP's image_undistorter: run_colmap_sfm writes the model and frames as they are, and hbgs
  // undistorts them on load (io::DatasetOptions::fisheye_fov_deg).
  std::string camera_model = "SIMPLE_RADIAL";
  std::string camera_params;               // "fx,fy,cx,cy" etc.: known intrinsics, held fixed in mapping
  bool permissive_registration = false;    // register images on fewer inliers (12, 10 %; COLMAP: 30, 25 %),
                                           // which small images with few features need
  int threads = 0;                         // 0: COLMAP's default (all cores)
  int max_image_size = 1600;               // SIFT works on images downscaled to this (px, longest side)
  double min_registered_fraction = 0.5;    // fewer registered images than this fraction is an error
  int min_registered = 3;                  // ... and fewer than this, whatever the fraction
};

struct ColmapReport {
  int images = 0;        // frames given to COLMAP
  int registered = 0;    // images in the chosen (largest) model
  int models = 0;        // reconstructions COLMAP made (several when it loses track)
  int points = 0;        // 3D points in the chosen model
  double seconds_features = 0, seconds_matching = 0, seconds_mapping = 0, seconds_undistort = 0;
};

// Where progress lines go ("[2/4] matching (sequential) ..."); may be empty.
using ProgressFn = std::function<void(const std::string&)>;

// Fails fast (before any slow work) when the COLMAP program cannot be found; the message says how
// to install it or where to point --colmap.
Status check_colmap(const ColmapOptions& options);

// Feature extraction, matching and mapping only: on success *model_dir is COLMAP's largest
// reconstruction (binary model) under work_dir/sparse. report->registered etc. are filled.
Status run_colmap_reconstruction(const std::string& frames_dir, const std::string& work_dir, const std::string& log_path,
                                 const ColmapOptions& options, const ProgressFn& progress, ColmapReport* report,
                                 std::string* model_dir);

// Runs COLMAP on frames_dir (PNG/JPEG files) using work_dir for its database and raw models, and
// writes the undistorted dataset to dataset_dir (created); with a fisheye camera model the
// registered frames as they are and COLMAP's model (hbgs undistorts them on load). Errors: COLMAP missing (says how to
// install it or point --colmap at it), a stage failing (names the stage, exit code and the log's
// last lines), too few images registered (says how many of how many).
Status run_colmap_sfm(const std::string& frames_dir, const std::string& work_dir, const std::string& dataset_dir,
                      const std::string& log_path, const ColmapOptions& options, const ProgressFn& progress,
                      ColmapReport* report);

}  // namespace gs::capture
