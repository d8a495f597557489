// SPDX-License-Identifier: MIT
// Camera-pose utilities shared by training, registration and evaluation (ALGORITHM.md Part A
// items 7, 8, 10, 11; Part B sections 1.6, 10): se(3) twists, pose input validation, the seeded
// pose-noise protocol, and pose errors after a Sim(3) alignment of camera centres.
//
// Twist convention (the renderer's v_pose): xi = (rho[3], phi[3]); a LEFT perturbation of the
// world-to-camera transform, T <- Exp(xi) T, so x_cam' = Exp(phi) x_cam + V(phi) rho.
// All maths in double; Pose stores float (row-major R, t), re-orthonormalised on every update.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/status.h"

namespace gs::pose {

// Rotation matrix of the axis-angle vector phi (radians), row-major; exact near phi = 0.
void so3_exp(const double phi[3], double R[9]);
// Axis-angle vector of a rotation matrix (angle in [0, pi]); robust near 0 and near pi.
void so3_log(const double R[9], double phi[3]);
// SE(3) exponential: R = Exp(phi), t = V(phi) rho (V the left Jacobian of SO(3)).
void se3_exp(const double xi[6], double R[9], double t[3]);
// Inverse of se3_exp: xi = (rho, phi) with Exp(xi) = (R, t); phi from so3_log, rho = V(phi)^-1 t.
void se3_log(const double R[9], const double t[3], double xi[6]);
// pose <- Exp(xi) pose, then R re-orthonormalised (SVD-free: symmetric polar step in double).
void apply_left_twist(const double xi[6], Pose* pose);
// Twist xi with Exp(xi) from = to, i.e. the left difference to * from^-1 (for tests and step sizes).
void left_difference(const Pose& from, const Pose& to, double xi[6]);

// Angle of R_a R_b^T in degrees, from its axis-angle (so3_log). Not BARF's clamped arccos: that
// clamp (1 - 1e-7) floors every error at 0.0256 deg, too coarse for sub-0.1 deg registration.
// pose_errors uses the same formula.
double rotation_error_deg(const Pose& a, const Pose& b);
// Distance between the camera centres of two poses (world units).
double centre_distance(const Pose& a, const Pose& b);
// The error of a relative orientation: the angle between R_ta R_tb^T (truth) and R_ea R_eb^T
// (estimate), degrees. No global alignment changes it (a Sim(3) fitted on camera centres can leave
// a tilt when the centres lie near a line or plane).
double relative_rotation_error_deg(const Pose& truth_a, const Pose& truth_b, const Pose& estimate_a, const Pose& estimate_b);
// Camera centre C = -R^T t (world units).
void centre(const Pose& pose, double c[3]);

// A pose given as text or numbers by a user: COLMAP order qw qx qy qz tx ty tz (world-to-camera).
// Errors (kInvalidArgument, message names `what`): any value NaN/Inf; |q| differs from 1 by more
// than 1e-3 ("normalise it or check the order: qw qx qy qz tx ty tz"); q = 0.
// Row-major rotation of the quaternion q / |q| (w, x, y, z), the norm divided out in double
// (gs/simd/quat.h's formula); the identity for a zero or non-finite q (pose readers refuse those).
void rotation_from_quaternion(const double q[4], double R[9]);
Status pose_from_quaternion_checked(const double q[4], const double t[3], const std::string& what, Pose* out);
// Parses "qw qx qy qz tx ty tz" (spaces and/or commas) then checks it as above.
Status parse_pose(const std::string& text, const std::string& what, Pose* out);

// Seeded pose noise (Part A item 11).
//   kBarf:  BARF's protocol: xi ~ N(0, sigma^2 I_6), rotation entries in radians; w2c_noisy =
//           w2c_gt * Exp(xi) (the perturbation acts on world points), computed in BARF's Blender
//           normalisation: world centred at `scene_centre` and scaled so `scene_radius` = 4.03
//           (BARF's camera radius); sigma 0.15 is BARF's hard case (about 8.6 deg per axis draw).
//   kFixed: an exact rotation of rotation_deg about a uniformly random axis through the camera
//           centre, and a camera-centre displacement of exactly translation_frac * scene_radius
//           in a uniformly random direction.
struct PoseNoise {
  enum Kind { kNone, kBarf, kFixed } kind = kNone;
  double sigma = 0;             // kBarf
  double rotation_deg = 0;      // kFixed
  double rotation_max_deg = 0;  // kFixed, > rotation_deg: each view's angle uniform in [rotation_deg, this]
  double translation_frac = 0;  // kFixed, fraction of scene_radius
  uint64_t seed = 0;
  size_t views = 0;             // > 0: only this many of the views, chosen by the seed (0: every view)
};
// "none", "barf:0.15", "rot:10,trans:0.1" (either part may be omitted, e.g. "rot:5"; "rot:10-40"
// draws each view's angle uniformly in [10, 40]); optional ",seed:N" and ",views:N" (perturb only
// N views, e.g. a sound reconstruction with a few views placed wrong). Errors name the bad token and
// list the accepted forms.
Status parse_pose_noise(const std::string& spec, PoseNoise* out);
std::string describe(const PoseNoise& noise);
// Perturbs poses[0..n) in place. View i draws from a stream seeded by (noise.seed, i), so a view's
// noise does not depend on how many views are perturbed. With noise.views, which views are drawn
// from a stream of their own (a seeded shuffle of 0..n-1, its first `views` entries).
// eligible (optional, [n]): only views with a non-zero entry are perturbed or chosen.
void perturb_poses(const PoseNoise& noise, const double scene_centre[3], double scene_radius, Pose* poses, size_t n,
                   const uint8_t* eligible = nullptr);

// Pose errors of estimates against ground truth (Part B section 10, BARF protocol).
struct PoseErrors {
  size_t count = 0;
  bool aligned = false;            // a Sim(3) was fitted on camera centres and applied to the estimates
  double scale = 1;                // of that Sim(3)
  double rotation_mean_deg = 0, rotation_median_deg = 0, rotation_max_deg = 0;
  double translation_mean = 0, translation_median = 0;  // camera-centre distance, scene units
  double translation_mean_frac = 0;                      // / scene_radius
  double ate_rmse = 0;                                   // RMS camera-centre distance, scene units
  std::vector<double> rotation_deg, translation;         // per view
};
// align: fit s, R, t (Umeyama with determinant fix, outliers trimmed: fit_sim3_trimmed) mapping
// estimated centres onto true centres and apply it to the estimated poses first; needs n >= 3 non-collinear centres, else it falls
// back to no alignment and says so in `aligned`. scene_radius > 0 for the fraction.
PoseErrors pose_errors(const Pose* estimated, const Pose* truth, size_t n, double scene_radius, bool align);

// A similarity transform of the world, X' = s R X + t (R row-major).
struct Sim3 {
  double s = 1;
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  double t[3] = {0, 0, 0};
};
// Umeyama (1991) least squares y ~ s R x + t over n point pairs x, y [n, 3] (weights [n] or nullptr),
// with the reflection fix. Returns false (out untouched) when either set is degenerate (coincident
// or collinear) or n < 3.
bool fit_sim3(const double* x, const double* y, const double* weights, size_t n, Sim3* out);
// The same with gross outliers left out: fit on every pair, then refit (at most 5 rounds) on the
// pairs whose residual |y - T(x)| is at most 3x the median residual (and never on fewer than half of
// them or than 3), so a camera whose estimate is far off (one never registered) cannot tilt the
// alignment of the others. inliers: how many pairs the returned fit used. False as fit_sim3.
bool fit_sim3_trimmed(const double* x, const double* y, size_t n, Sim3* out, size_t* inliers = nullptr);
// The same camera after the world changes by T: a world-to-camera pose (R, t) becomes
// (R R_T^T, s t - R R_T^T t_T), with camera units scaled by s so depths stay in world units.
Pose transform_pose(const Sim3& T, const Pose& pose);
void transform_point(const Sim3& T, const double x[3], double y[3]);
// a then b: X'' = b(a(X)).
Sim3 compose(const Sim3& b, const Sim3& a);
// Trimmed ICP (point to point, Sim(3) updates by fit_sim3) of source points onto target points from
// an initial transform; returns the refined transform. Pairs farther than trim x the median pair
// distance are dropped; the search radius starts at 0.1 x the target's RMS spread and shrinks to
// 3 x trim x median. source/target: [n, 3]; the outputs may be nullptr. (Frame alignment of a
// structure-from-motion reconstruction onto the dataset's points, gs/capture/sfm_pose_init.h.)
Sim3 icp_sim3(const double* source, size_t nsource, const double* target, size_t ntarget, const Sim3& initial,
              int iterations, double trim, double* median_before, double* median_after, int* pairs,
              int* iterations_run);

// Scene frame used by noise and error fractions: mean camera centre and the largest distance of a
// centre from it (floored at 1e-9).
void scene_frame(const Pose* poses, size_t n, double centre[3], double* radius);

}  // namespace gs::pose
