// SPDX-License-Identifier: MIT
// Pinhole camera and world-to-camera pose, as every stage of hbgs sees them.
// Conventions (COLMAP): x right, y down, z forward; the pose maps world points to the camera,
// x_cam = R x_world + t; pixel centres sit at (i + 0.5, j + 0.5), so u = fx x/z + cx directly.
#pragma once

#include <cstdint>

namespace gs {

struct PinholeIntrinsics {
  float fx = 1, fy = 1;  // focal lengths, pixels
  float cx = 0, cy = 0;  // principal point, pixels (COLMAP convention, top-left corner = (0,0))
  int width = 0, height = 0;
};

// World-to-camera rigid transform, row-major rotation.
struct Pose {
  float R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  float t[3] = {0, 0, 0};
};

struct Camera {
  PinholeIntrinsics intr;
  Pose pose;
};

// The camera seeing the image averaged over s x s pixel blocks (remainder rows and columns
// dropped): block (i, j) has its centre at s (i + 0.5) in full-resolution pixels, so every
// intrinsic divides by s exactly. s = 1 returns the camera unchanged.
inline Camera scaled_camera(const Camera& c, int s) {
  if (s <= 1) return c;
  Camera out = c;
  const float inv = 1.0f / float(s);
  out.intr.fx *= inv;
  out.intr.fy *= inv;
  out.intr.cx *= inv;
  out.intr.cy *= inv;
  out.intr.width = c.intr.width / s > 0 ? c.intr.width / s : 1;
  out.intr.height = c.intr.height / s > 0 ? c.intr.height / s : 1;
  return out;
}

}  // namespace gs
