// SPDX-License-Identifier: MIT
// Pinhole ray generation and projection for the synth scene, in double precision, following
// gs/camera.h: x_cam = R x_world + t, u = fx x/z + cx, v = fy y/z + cy (pixel centres at +0.5).
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

  const double* centre() const { return centre_; }

  // World-space ray through image point (u, v) (pixels, top-left corner at 0); dir is unit length.
  void ray(double u, double v, double origin[3], double dir[3]) const {
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
  }

 private:
  double rinv_[9];
  double centre_[3];
  double fx_, fy_, cx_, cy_;
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

}  // namespace hbgs::synth::detail
