// SPDX-License-Identifier: MIT
// The registration jobs (`hbgs register`): the pose of one image against a frozen trained model,
// or of every view of a dataset split from starts perturbed by the seeded noise protocol, with
// errors against the dataset poses, image metrics before and after, <out>/register.json and the
// registered poses as a COLMAP model. For repeated registration on a device, use
// gs::pose::Registrar directly (planned once, allocation-free calls).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/jobs/run_folder.h"
#include "gs/model/register.h"
#include "gs/pose/pose.h"
#include "gs/status.h"

namespace gs::jobs {

struct RegisterRunOptions {
  std::string input;    // run folder (from train_run) or .hbgs model file
  std::string dataset;  // "" : the one recorded in the run's run.json
  std::string solver = "keyframe";  // "keyframe", "lm" or "adam" (gs/model/register.h)
  int downscale = 1;                // resolution divisor of the finest level (4: quarter resolution)
  bool fixed_point = false;         // on-device mode: fixed-point keyframe renders (RegisterOptions::fixed_point)
  double time_budget_ms = 0;        // > 0: stop a view after this long, keeping the best pose
  int threads = 0;                  // 0: all CPUs
  std::string json;                 // "" or a file that also gets the JSON result
  // The colour behind the model (black, white or r,g,b; "" : the run's training background). Masked
  // views, and the alpha of an RGBA image, are composited on it before registration.
  std::string background;
  // One image: its file, the start pose "qw qx qy qz tx ty tz" and optionally "fx fy cx cy" (default:
  // the dataset's one shared camera, scaled to the image).
  std::string image, init, camera;
  // A split ("test", "train" or "all"): the start-pose noise and the output folder ("" : <run>/register).
  std::string views, init_noise = "rot:10,trans:0.1", out;
  // Batch mode: a view that does not converge from its start is registered again from the poses of
  // the dataset's views outside the split (the training views for "test", the test views for
  // "train"; none for "all") whose renders look most like it, up to this many (0: never;
  // RegisterOptions::relocalize_candidates).
  int relocalize = 3;
};

// register_image refuses a start pose whose camera centre is farther than this many scene radii from
// the centre of the model's anchors (a wrong unit or order: nothing of the scene would be in view).
inline constexpr double kMaxStartDistanceInRadii = 1000;

// The solver options these resolve to (errors: an unknown solver, downscale < 1).
Expected<pose::RegisterOptions> register_options(const RegisterRunOptions& options);

struct RegisterImageSummary {
  ModelSource source;
  PinholeIntrinsics intrinsics;
  Pose init;                  // in the model's scene frame (frame)
  pose::RegisterResult result;  // result.pose: in the model's scene frame
  SceneFrame frame;             // the model's (for plain Gaussians, their dataset's) scene frame
  double pose_qvec[4] = {1, 0, 0, 0}, pose_tvec[3] = {0, 0, 0};  // result.pose in the user's frame (COLMAP)
  double moved_rotation_deg = 0, moved_translation = 0;  // from init (camera centre, user units)
  int threads = 0;
  std::string note;  // e.g. a distorted dataset camera used as a pinhole ("" : nothing to say)
};
Status register_image(const RegisterRunOptions& options, RegisterImageSummary* summary);

struct RegisteredView {
  std::string name;
  double initial_rotation_deg = 0, initial_translation = 0;  // of the start against the dataset pose
  double rotation_deg = 0, translation = 0;                  // of the result against the dataset pose
  double initial_translation_fraction = 0, translation_fraction = 0;  // the translations / scene radius
  bool success = false;  // < 1 degree and < 1 % of the scene radius
  pose::RegisterResult result;
  std::string relocalized_from;  // the candidate view the pose was registered from ("" : the start)
};
struct RegisterViewsSummary {
  ModelSource source;
  std::string noise, json_path, posed_dir;  // the start-noise description, register.json, the COLMAP model
  std::vector<RegisteredView> views;
  double scene_radius = 1;
  double median_initial_rotation_deg = 0, median_initial_translation = 0;
  double median_rotation_deg = 0, median_translation = 0;
  size_t success = 0, converged = 0, relocalized = 0, candidates = 0;
  double median_ms = 0, mean_ms = 0, total_seconds = 0;
  double psnr_at_start = 0, ssim_at_start = 0, psnr_registered = 0, ssim_registered = 0;
  int threads = 0;
};
// progress: called after each view with its row, its 1-based number and the count.
Status register_views(const RegisterRunOptions& options,
                      const std::function<void(const RegisteredView&, size_t, size_t)>& progress,
                      RegisterViewsSummary* summary);

}  // namespace gs::jobs
