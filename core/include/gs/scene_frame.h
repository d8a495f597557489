// SPDX-License-Identifier: MIT
// The frame a scene is trained in: the user's world moved by a similarity (a translation and a
// uniform scale, no rotation), chosen in double precision when a dataset is loaded, so that scenes
// far from the origin (georeferenced models at 1e5 units and more, where float32 keeps centimetres)
// or at an unusual scale (millimetres, kilometres) train as an ordinary scene does:
//
//   x_frame = scale * (x_user - centre)
//
// A camera pose (world to camera, x_cam = R x + t) keeps its rotation; its translation becomes
// scale * (t + R centre) (the camera's own coordinates scale too, which a pinhole camera does not
// see). Gaussians keep their rotations and colours (SH evaluates directions, which a similarity
// without rotation keeps); their means move like points and their log-scales add log(scale).
//
// choose_scene_frame picks the frame from the dataset's camera centres (their mean and the extent
// 1.1 x the largest distance of a centre from it, as model::cameras_extent measures it):
//   centre: the mean rounded per axis to a multiple of G, the power of two at or above the extent,
//           so a scene within about half its extent of the origin (every ordinary COLMAP model) is
//           not moved, and a scene moved by a multiple of G lands exactly where it was;
//   scale:  1 when the extent lies in [kFrameExtentMin, kFrameExtentMax] (the scales hbgs's absolute
//           constants were tuned at: the renderer's near plane 0.2, the decoder's distance input),
//           else the power of ten that brings the extent nearest to kFrameExtentReference (on a
//           logarithmic scale). Powers of ten because a scene at an unusual scale is most often
//           one given in other units (millimetres, kilometres): the same scene in metres and in
//           millimetres then lands in the same frame and trains the same.
// An ordinary scene's frame is therefore the identity and nothing about it changes. What the frame
// cannot remove is hbgs's own dependence on where the anchor voxel grid falls (its origin is the
// frame's origin): a scene moved by an amount off the recentring grid trains as the original moved
// by the remainder would.
#pragma once

#include <cmath>
#include <cstddef>

#include "gs/camera.h"
#include "gs/gaussians.h"

namespace gs {

inline constexpr double kFrameExtentMin = 0.5;        // world units: extents in [min, max] are not rescaled
inline constexpr double kFrameExtentMax = 64.0;
inline constexpr double kFrameExtentReference = 6.0;  // a rescaled scene's extent lands within sqrt(10) of this

struct SceneFrame {
  double centre[3] = {0, 0, 0};  // user units
  double scale = 1;              // frame units per user unit (> 0)

  bool identity() const { return centre[0] == 0 && centre[1] == 0 && centre[2] == 0 && scale == 1; }
  bool operator==(const SceneFrame& o) const {
    return centre[0] == o.centre[0] && centre[1] == o.centre[1] && centre[2] == o.centre[2] && scale == o.scale;
  }
  bool operator!=(const SceneFrame& o) const { return !(*this == o); }
};

// The frame for camera centres [n, 3] in user units (n == 0: the identity). A single camera (no
// extent) is recentred on a grid of 1 unit and not rescaled.
SceneFrame choose_scene_frame(const double* camera_centres, size_t n);
// An error message when the frame cannot be one (a non-finite or non-positive scale, a non-finite
// centre); "" when it is valid.
const char* scene_frame_problem(const SceneFrame& frame);

// Points.
void point_to_frame(const SceneFrame& f, const double user[3], double out[3]);
void point_to_user(const SceneFrame& f, const double frame[3], double out[3]);

// A pose given in user units (R row-major, t) as a float pose in the frame.
Pose pose_to_frame(const SceneFrame& f, const double R[9], const double t[3]);
// The translation in user units (double: it may be far beyond float's precision) of a float pose in
// the frame, for the rotation R the caller writes with it (a proper rotation close to pose.R, e.g.
// from the quaternion it stores): the camera centre is mapped to the user's frame and t = -R C, so a
// reader computing C = -R^T t from R finds the centre exactly, however far from the origin it is.
void pose_to_user(const SceneFrame& f, const Pose& pose, const double R[9], double t[3]);

// Plain Gaussians in place: means and log-scales (rotations, opacities and SH are unchanged).
// Nothing is done for the identity frame, so its clouds stay bit for bit as they were.
void cloud_to_frame(const SceneFrame& f, GaussianCloud* cloud);
void cloud_to_user(const SceneFrame& f, GaussianCloud* cloud);

}  // namespace gs
