// SPDX-License-Identifier: MIT
// Pieces shared by the synth datasets (generate_scene, generate_object) and camera paths
// (generate_path): the scenes' camera rigs, the camera model and look-at poses, seeded sparse
// points with their visibility tracks, and the COLMAP model of rendered views. Defined in
// generate.cpp (object_camera_distance in object.cpp).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "hbgs/synth.h"

namespace hbgs::synth::detail {

// A camera of a synth dataset: its pose is exactly pose_from_colmap(qvec, tvec).
struct ViewSetup {
  gs::Camera camera;
  double qvec[4];
  double tvec[3];
};

// The point every camera of the built-in scene looks at (plus jitter), metres: the middle of the
// object layout.
inline constexpr double kSceneTarget[3] = {0.1, 0.2, 0.45};
// The object capture's ring elevations, degrees: the pedestal's side, a typical three-quarter view,
// and from above.
inline constexpr double kObjectRingElevationsDeg[3] = {15.0, 35.0, 60.0};
// The object capture's camera distance from kObjectCentre for these intrinsics: 1.1 x the distance
// at which the subject's bounding sphere touches the narrower side of the image.
double object_camera_distance(const gs::PinholeIntrinsics& K);

// fx = fy = 0.9 width rounded to a quarter pixel (exact in float); principal point centred.
double focal_for(int width);
gs::PinholeIntrinsics synth_intrinsics(int width, int height);
// World-to-camera pose looking from `eye` at `at` with world +z as up (camera y points down).
gs::Pose look_at(const double eye[3], const double at[3]);
// The view from `eye` to `at`, rounded through COLMAP's (qvec, tvec) so a reader of images.txt gets
// exactly the pose the images are rendered with.
ViewSetup make_view(const gs::PinholeIntrinsics& intr, const double eye[3], const double at[3]);
// The same for any world-to-camera pose.
ViewSetup make_view(const gs::PinholeIntrinsics& intr, const gs::Pose& pose);

struct Observation {
  uint32_t view;
  double u, v;
};

struct SparsePoint {
  double xyz[3];  // stored position (surface point + noise), metres
  uint8_t rgb[3];
  std::vector<Observation> track;
};

// Surface points of seeded pixel-centre rays that `accept` keeps, plus N(0, noise) noise, coloured
// by the rendered pixel (images: RGB or RGBA, one per view), each with the views that see its
// noise-free surface point (at least two when there are two views or more). Candidates come from a
// sequential stream and their tracks are computed in parallel, so the result does not depend on the
// thread count. *draws: pixel draws used. fisheye_focal > 0: the views' lens is the equidistant
// fisheye of that focal length about (cx, cy) (rays up to 90 degrees from the axis; SynthOptions).
std::vector<SparsePoint> sample_sparse_points(const Scene& scene, const std::vector<ViewSetup>& views,
                                              const std::vector<gs::io::Image8>& images, int num_points, float noise,
                                              uint64_t seed, int threads, const std::function<bool(const SceneHit&)>& accept,
                                              long long* draws, double fisheye_focal = 0);

// The one PINHOLE camera (id 1) of a synth COLMAP model.
gs::io::ColmapCamera colmap_pinhole(const gs::PinholeIntrinsics& K);
// The OPENCV_FISHEYE camera (id 1) of a fisheye synth dataset: fx = fy = focal, K's cx, cy, k = 0.
gs::io::ColmapCamera colmap_fisheye(const gs::PinholeIntrinsics& K, double focal);

// The COLMAP model: one PINHOLE camera (id 1), images with ids from 1 in view order, the points
// with ids from 1 and their tracks as POINTS2D.
gs::io::ColmapModel make_colmap_model(const std::vector<ViewSetup>& views, const std::vector<std::string>& names,
                                      const std::vector<SparsePoint>& points);

// "0042" + extension, at least `digits` digits.
std::string view_name(int index, int digits, const std::string& extension);

}  // namespace hbgs::synth::detail
