// SPDX-License-Identifier: MIT
// The training frame of a scene (gs/scene_frame.h): its choice and the conversions of points, poses
// and Gaussians between it and the user's frame, all in double precision.
#include "gs/scene_frame.h"

#include <algorithm>

namespace gs {

SceneFrame choose_scene_frame(const double* c, size_t n) {
  SceneFrame f;
  if (n == 0) return f;
  double mean[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) mean[k] += c[3 * i + k] / double(n);
  double radius = 0;
  for (size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (c[3 * i + k] - mean[k]) * (c[3 * i + k] - mean[k]);
    radius = std::max(radius, std::sqrt(d2));
  }
  if (!std::isfinite(radius) || !std::isfinite(mean[0] + mean[1] + mean[2])) return f;
  const double extent = 1.1 * radius;
  const double grid = extent > 0 ? std::exp2(std::ceil(std::log2(extent))) : 1.0;
  for (int k = 0; k < 3; ++k) f.centre[k] = std::nearbyint(mean[k] / grid) * grid + 0.0;  // + 0.0: no -0
  if (extent > 0 && (extent < kFrameExtentMin || extent > kFrameExtentMax))
    f.scale = std::pow(10.0, std::nearbyint(std::log10(kFrameExtentReference / extent)));
  return f;
}

const char* scene_frame_problem(const SceneFrame& f) {
  if (!(f.scale > 0) || !std::isfinite(f.scale)) return "the scene frame's scale must be positive and finite";
  for (double c : f.centre)
    if (!std::isfinite(c)) return "the scene frame's centre must be finite";
  return "";
}

void point_to_frame(const SceneFrame& f, const double u[3], double out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = f.scale * (u[k] - f.centre[k]);
}

void point_to_user(const SceneFrame& f, const double x[3], double out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = x[k] / f.scale + f.centre[k];
}

Pose pose_to_frame(const SceneFrame& f, const double R[9], const double t[3]) {
  Pose p;
  for (int i = 0; i < 9; ++i) p.R[i] = float(R[i]);
  for (int i = 0; i < 3; ++i) {
    const double rc = R[3 * i] * f.centre[0] + R[3 * i + 1] * f.centre[1] + R[3 * i + 2] * f.centre[2];
    p.t[i] = float(f.scale * (t[i] + rc));
  }
  return p;
}

void pose_to_user(const SceneFrame& f, const Pose& pose, const double R[9], double t[3]) {
  double c[3], u[3];
  for (int k = 0; k < 3; ++k)  // the centre in the frame, -R^T t with the pose's own rotation
    c[k] = -(double(pose.R[k]) * pose.t[0] + double(pose.R[3 + k]) * pose.t[1] + double(pose.R[6 + k]) * pose.t[2]);
  point_to_user(f, c, u);
  for (int i = 0; i < 3; ++i) t[i] = -(R[3 * i] * u[0] + R[3 * i + 1] * u[1] + R[3 * i + 2] * u[2]);
}

namespace {

// Means through point_to_frame or point_to_user, log-scales plus or minus log(scale).
void move_cloud(const SceneFrame& f, bool to_frame, GaussianCloud* cloud) {
  if (f.identity()) return;
  for (size_t i = 0; i < cloud->size(); ++i) {
    double a[3], b[3];
    for (int k = 0; k < 3; ++k) a[k] = cloud->means[3 * i + size_t(k)];
    (to_frame ? point_to_frame : point_to_user)(f, a, b);
    for (int k = 0; k < 3; ++k) cloud->means[3 * i + size_t(k)] = float(b[k]);
  }
  const float log_scale = float(std::log(f.scale));
  for (float& s : cloud->log_scales) s += to_frame ? log_scale : -log_scale;
}

}  // namespace

void cloud_to_frame(const SceneFrame& f, GaussianCloud* cloud) { move_cloud(f, true, cloud); }
void cloud_to_user(const SceneFrame& f, GaussianCloud* cloud) { move_cloud(f, false, cloud); }

}  // namespace gs
