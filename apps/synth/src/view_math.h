// SPDX-License-Identifier: MIT
// Ray generation and projection for the synth scene, in double precision, following gs/camera.h:
// x_cam = R x_world + t, u = fx x/z + cx, v = fy y/z + cy (pixel centres at +0.5); or, for the
// fisheye datasets, an equidistant lens (COLMAP's OPENCV_FISHEYE with k1..k4 = 0): a ray at angle
// theta from the axis lands theta * f from (cx, cy) in its direction.
#pragma once

#include <cmath>

#include "gs/camera.h"

namespace hbgs::synth::detail {

// Rays through image points of one camera. R is inverted exactly (not transposed) so that a point
// on the ray through (u, v) projects back to (u, v) to double precision even though the float R
// from gs::Pose is only orthonormal to ~1e-7.
class ViewRays {
 public:
  explicit ViewRays(const gs::Camera& cam) {
    const float* R = cam.pose.R;
    double r[9];
    for (int i = 0; i < 9; ++i) r[i] = R[i];
    // Inverse via the adjugate.
    double c00 = r[4] * r[8] - r[5] * r[7], c01 = r[5] * r[6] - r[3] * r[8], c02 = r[3] * r[7] - r[4] * r[6];
    double c10 = r[2] * r[7] - r[1] * r[8], c11 = r[0] * r[8] - r[2] * r[6], c12 = r[1] * r[6] - r[0] * r[7];
    double c20 = r[1] * r[5] - r[2] * r[4], c21 = r[2] * r[3] - r[0] * r[5], c22 = r[0] * r[4] - r[1] * r[3];
    double det = r[0] * c00 + r[1] * c01 + r[2] * c02;
    double inv = 1.0 / det;
    rinv_[0] = c00 * inv; rinv_[1] = c10 * inv; rinv_[2] = c20 * inv;
    rinv_[3] = c01 * inv; rinv_[4] = c11 * inv; rinv_[5] = c21 * inv;
    rinv_[6] = c02 * inv; rinv_[7] = c12 * inv; rinv_[8] = c22 * inv;
    for (int i = 0; i < 3; ++i) {
      centre_[i] = -(rinv_[3 * i] * cam.pose.t[0] + rinv_[3 * i + 1] * cam.pose.t[1] + rinv_[3 * i + 2] * cam.pose.t[2]);
    }
    fx_ = cam.intr.fx;
    fy_ = cam.intr.fy;
    cx_ = cam.intr.cx;
    cy_ = cam.intr.cy;
  }
  // The same pose and principal point through an equidistant fisheye of focal length f (pixels)
  // instead of the pinhole; rays up to max_theta (radians) from the axis.
  ViewRays(const gs::Camera& cam, double fisheye_focal, double max_theta) : ViewRays(cam) {
    fisheye_f_ = fisheye_focal;
    max_theta_ = max_theta;
  }

  const double* centre() const { return centre_; }
  double fisheye_focal() const { return fisheye_f_; }  // 0: pinhole
  double max_theta() const { return max_theta_; }

  // World-space ray through image point (u, v) (pixels, top-left corner at 0); dir is unit length.
  // False (no ray) for a fisheye point beyond max_theta.
  bool ray(double u, double v, double origin[3], double dir[3]) const {
    if (fisheye_f_ > 0) return fisheye_ray(u, v, origin, dir);
    double c[3] = {(u - cx_) / fx_, (v - cy_) / fy_, 1.0};
    double n2 = 0;
    for (int i = 0; i < 3; ++i) {
      dir[i] = rinv_[3 * i] * c[0] + rinv_[3 * i + 1] * c[1] + rinv_[3 * i + 2] * c[2];
      n2 += dir[i] * dir[i];
    }
    double inv = 1.0 / std::sqrt(n2);
    for (int i = 0; i < 3; ++i) {
      dir[i] *= inv;
      origin[i] = centre_[i];
    }
    return true;
  }

 private:
  bool fisheye_ray(double u, double v, double origin[3], double dir[3]) const {
    const double a = (u - cx_) / fisheye_f_, b = (v - cy_) / fisheye_f_;
    const double theta = std::sqrt(a * a + b * b);
    if (theta > max_theta_) return false;
    const double s = theta > 0 ? std::sin(theta) / theta : 1.0;
    const double c[3] = {a * s, b * s, std::cos(theta)};  // unit length
    for (int i = 0; i < 3; ++i) {
      dir[i] = rinv_[3 * i] * c[0] + rinv_[3 * i + 1] * c[1] + rinv_[3 * i + 2] * c[2];
      origin[i] = centre_[i];
    }
    return true;
  }

  double rinv_[9];
  double centre_[3];
  double fx_, fy_, cx_, cy_;
  double fisheye_f_ = 0, max_theta_ = 0;
};

// Camera-space point and its projection, computed in double from the float pose exactly as a
// reader of the dataset would: x_cam = R X + t, u = fx x/z + cx.
struct Projection {
  double cam[3];
  double u, v;
};
inline Projection project(const gs::Pose& pose, double fx, double fy, double cx, double cy, const double X[3]) {
  Projection p;
  for (int r = 0; r < 3; ++r) {
    p.cam[r] = double(pose.R[3 * r]) * X[0] + double(pose.R[3 * r + 1]) * X[1] + double(pose.R[3 * r + 2]) * X[2] +
               double(pose.t[r]);
  }
  p.u = fx * p.cam[0] / p.cam[2] + cx;
  p.v = fy * p.cam[1] / p.cam[2] + cy;
  return p;
}
// The same through an equidistant fisheye of focal f: theta = the angle from the axis, the point
// lands f theta from (cx, cy) in its direction. cam[2] is set to -1 (not seen) beyond max_theta.
inline Projection project_fisheye(const gs::Pose& pose, double f, double max_theta, double cx, double cy, const double X[3]) {
  Projection p;
  for (int r = 0; r < 3; ++r) {
    p.cam[r] = double(pose.R[3 * r]) * X[0] + double(pose.R[3 * r + 1]) * X[1] + double(pose.R[3 * r + 2]) * X[2] +
               double(pose.t[r]);
  }
  const double rho = std::sqrt(p.cam[0] * p.cam[0] + p.cam[1] * p.cam[1]);
  const double theta = std::atan2(rho, p.cam[2]);
  const double scale = rho > 0 ? f * theta / rho : 0.0;
  p.u = scale * p.cam[0] + cx;
  p.v = scale * p.cam[1] + cy;
  if (!(theta <= max_theta)) p.cam[2] = -1;
  return p;
}

}  // namespace hbgs::synth::detail
