// SPDX-License-Identifier: MIT
// Structure from motion by running Debian's `colmap` command on a folder of frames: feature
// extraction (CPU SIFT, one shared camera), sequential or exhaustive matching, incremental mapping,
// and undistortion to PINHOLE. The result is a dataset `hbgs train` reads directly:
// <dataset>/images/*.png and <dataset>/sparse/0/{cameras,images,points3D}.bin. Everything COLMAP
// prints goes to a log file; progress is reported per stage.
//
// COLMAP 3.8 (Debian 12) cannot repeat a reconstruction, whatever its seed and thread options
// (docs/CAPTURE.md, "Repeatable SfM"): its CPU SIFT leaves a few descriptors uninitialised, and its
// matcher's FLANN kd-trees are shuffled from std::random_device and split by rand(), which COLMAP
// reseeds from its verifier thread mid-matching. The mapper alone repeats exactly on one database
// and seed. So after mapping, a consistency check maps the same database again with other seeds
// and compares every view's pose after a robust Sim(3): views the reconstructions disagree on are
// reported as suspect.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "gs/io/colmap.h"
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
  // The consistency check: this many more mapper runs on the same database, with seeds 1, 2, ...
  // (0: no check). A view of the chosen reconstruction is suspect when its pose differs from the
  // same view's in at least half of the check runs that registered it by more than
  // suspect_rotation_deg, or its centre by more than suspect_centre_fraction of the scene radius.
  // 3 runs (a majority of 2 is needed) flag as many misplaced views as 2 (where 1 suffices) with
  // about half the false alarms (docs/CAPTURE.md, "Repeatable SfM").
  int check_runs = 3;
  double suspect_rotation_deg = 5.0;
  double suspect_centre_fraction = 0.1;
};

// One view of the chosen reconstruction against the check runs.
struct ViewAgreement {
  std::string name;                 // image name in the reconstruction
  int check_runs = 0;               // check runs that registered this view too
  int disagreeing = 0;              // ... and placed it farther than the limits
  double rotation_deg = 0;          // largest rotation difference over those runs, after the Sim(3)
  double centre_fraction = 0;       // largest centre distance, fraction of the scene radius
  bool suspect = false;             // disagreeing >= 1 and >= half of check_runs
};

struct SfmConsistency {
  int check_runs = 0;               // check reconstructions compared (0: no check ran)
  int aligned_runs = 0;             // ... of which could be aligned (3 or more shared, non-collinear views)
  int suspect = 0;                  // views flagged
  double rotation_median_deg = 0;   // median over views of rotation_deg (how well runs agree)
  double rotation_max_deg = 0;
  double seconds = 0;               // the check's mapper runs and comparison
  std::vector<ViewAgreement> views; // every registered view of the chosen reconstruction, sorted by name
  std::vector<std::string> suspect_names() const;
};

// The comparison alone (no COLMAP): each check reconstruction is aligned onto `chosen` by a robust
// Sim(3) of the shared views' camera centres (the 3-view fit most views agree with within 5 % of
// the scene radius, refitted on those: corrupted views, even a quarter of them moved together, do
// not tilt it), then every shared view's rotation and centre are compared. The scene radius is
// the largest distance of a chosen camera centre from their mean.
SfmConsistency compare_reconstructions(const io::ColmapModel& chosen, const std::vector<io::ColmapModel>& checks,
                                       double suspect_rotation_deg, double suspect_centre_fraction);

struct ColmapReport {
  int images = 0;        // frames given to COLMAP
  int registered = 0;    // images in the chosen (largest) model
  int models = 0;        // reconstructions COLMAP made (several when it loses track)
  int points = 0;        // 3D points in the chosen model
  double seconds_features = 0, seconds_matching = 0, seconds_mapping = 0, seconds_undistort = 0;
  SfmConsistency consistency;  // the check of the chosen reconstruction (ColmapOptions::check_runs)
  // The mapper seed of the chosen reconstruction: 0 (the first mapping) unless the consistency
  // check found a check run that agrees with the others on more views (choose_most_consistent).
  int chosen_seed = 0;
  int first_run_suspect = 0;  // views the check doubted in the first mapping (before any switch)
};

// Of several reconstructions of the same database (the first mapping and the check runs), the one
// whose views the others agree with most: compare_reconstructions of each against the rest, fewest
// suspect views wins, then more registered views, then the earlier one (index 0 on a tie). A
// corrupted first mapping (13 of 35 views doubted once in the end-to-end test, 11.9 degrees mean)
// is then replaced by a sound check run instead of training on it. Only reconstructions with at
// least min_registered images take part (index 0 always does). Returns the index; *consistency is
// its comparison, *first_suspect (when not null) the suspect count of index 0.
size_t choose_most_consistent(const std::vector<io::ColmapModel>& runs, size_t min_registered, double suspect_rotation_deg,
                              double suspect_centre_fraction, SfmConsistency* consistency, int* first_suspect = nullptr);

// Where progress lines go ("[2/4] matching (sequential) ..."); may be empty.
using ProgressFn = std::function<void(const std::string&)>;

// Fails fast (before any slow work) when the COLMAP program cannot be found; the message says how
// to install it or where to point --colmap.
Status check_colmap(const ColmapOptions& options);

// Feature extraction, matching, mapping and the consistency check: on success *model_dir is
// COLMAP's largest reconstruction (binary model) under work_dir/sparse, or, when the check finds
// one that agrees with the others on more views, the check run's under work_dir/sparse_check<seed>
// (report->chosen_seed). report->registered, report->consistency etc. are filled.
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
