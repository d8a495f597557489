// SPDX-License-Identifier: MIT
// NeRF-style datasets: the transforms.json camera files of NeRF's synthetic ("Blender") scenes
// (transforms_{train,val,test}.json, camera_angle_x), instant-ngp and nerfstudio (one
// transforms.json, fl_x/fl_y/cx/cy/w/h globally or per frame, OpenCV distortion, split lists, a PLY
// point cloud), the pose conversion from their OpenGL camera-to-world matrices to hbgs's
// world-to-camera poses, point-cloud PLY files, and the random initial points used when such a
// dataset has none. gs::io::load_dataset (gs/io/colmap.h) reads these folders; this header exposes
// the parts for tests, the fuzz harnesses and writers, and the transforms.json writer (hbgs synth
// --object, and the refined and registered poses of hbgs train and hbgs register).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/colmap.h"
#include "gs/status.h"

namespace gs::io {

// Intrinsics as a transforms file gives them; a key that is absent stays empty. Units: pixels,
// except camera_angle_x/y (radians, the full field of view across the width / height).
struct TransformsIntrinsics {
  std::optional<double> fl_x, fl_y, cx, cy;
  std::optional<double> camera_angle_x, camera_angle_y;
  std::optional<int> w, h;
  // OpenCV distortion (nerfstudio's names). k1, k2, p1, p2 are undistorted on load like a COLMAP
  // OPENCV camera; a non-zero k3 or k4 is refused.
  std::optional<double> k1, k2, k3, k4, p1, p2;
};

struct TransformsFrame {
  std::string file_path;  // as written (relative to the json's folder, extension optional)
  std::string mask_path;  // nerfstudio's per-frame "mask_path"; empty when absent
  // The file's top-level intrinsics overridden by the frame's own keys.
  TransformsIntrinsics intrinsics;
  // "transform_matrix": camera-to-world, row-major 4x4, camera axes x right, y up, z back (OpenGL).
  double transform_matrix[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
};

struct TransformsFile {
  std::vector<TransformsFrame> frames;  // in file order
  // nerfstudio's split lists (paths relative to the json's folder); empty optional when absent.
  std::optional<std::vector<std::string>> train_filenames, val_filenames, test_filenames;
  std::string ply_file_path;  // nerfstudio's point cloud, relative to the json's folder; "" when absent
};

// Parses one transforms file. Checks: valid JSON (the error gives line and column), a non-empty
// "frames" array of objects with a string "file_path" and a 4x4 (or 3x4) "transform_matrix" whose
// entries are finite and whose rotation is rigid (see pose_from_transform_matrix), and every
// intrinsic key a finite number (focal lengths and angles > 0; w, h integers in 1..kMaxImageSide).
// A nerfstudio "camera_model" other than OPENCV, PINHOLE or SIMPLE_PINHOLE (fisheye,
// equirectangular) and non-zero k3/k4 are refused (kUnsupported). "applied_transform" and
// "applied_scale" are not read: they say how the file's frame relates to the capture it was
// converted from, and the frames and the PLY points are both already in the file's frame. Nor are
// instant-ngp's "aabb_scale", "scale" and "offset" (its own normalisation of the scene) or any
// other key (NeRF's "rotation", nerfstudio's "depth_file_path", ...).
// Errors name `source`, the frame index and the key.
Status parse_transforms_json(const std::string& text, const std::string& source, TransformsFile* out);

// Camera-to-world in OpenGL camera axes (x right, y up, z back) -> world-to-camera in hbgs/COLMAP
// camera axes (x right, y down, z forward): R = diag(1, -1, -1) R_c2w^T, t = -R C with C the
// matrix's translation column; as a COLMAP quaternion (w >= 0) and translation. Returns "" on
// success, else why the matrix is not a camera pose: a non-finite entry, a last row other than
// (0, 0, 0, 1), or a rotation block that is not a rotation (|R^T R - I| > 1e-3 in any entry, or a
// reflection). Within that tolerance the quaternion is the normalised nearest one.
std::string pose_from_transform_matrix(const double c2w[16], double qvec[4], double tvec[3]);
// The inverse: the transform_matrix of a COLMAP (qvec, tvec) pose (used by writers).
void transform_matrix_from_pose(const double qvec[4], const double tvec[3], double c2w[16]);

// Writes a transforms file in nerfstudio's layout (what its dataparser, instant-ngp and hbgs read):
// "camera_model" ("OPENCV" when a frame has a non-zero k1, k2, p1 or p2, else "PINHOLE"), the
// intrinsics fl_x, fl_y, cx, cy, w, h (and k1, k2, p1, p2 for OPENCV; camera_angle_x/y when set) at
// the top level when every frame has the same ones, else in each frame, then "frames" with
// "file_path", "mask_path" (when not empty) and the 4x4 "transform_matrix", and the split lists and
// "ply_file_path" when set. file_path and mask_path are written as given (relative to the json's
// folder; hbgs's loader refuses absolute paths and '..', other tools follow them).
// Checks: at least one frame, a non-empty file_path, every frame's fl_x, fl_y, cx, cy, w, h set
// and finite (focal lengths > 0, sizes in 1..kMaxImageSide), no non-zero k3/k4, and a
// transform_matrix that is a camera pose (pose_from_transform_matrix); errors name `source` and
// the frame. Doubles are written in the shortest form that reads back to the same value.
Expected<std::string> encode_transforms_json(const TransformsFile& file, const std::string& source);
// encode_transforms_json to a file, atomically (platform::write_file_atomic).
Status write_transforms_json(const std::string& path, const TransformsFile& file);
// The intrinsics of a "PINHOLE" (fx, fy, cx, cy), "SIMPLE_PINHOLE" (f, cx, cy) or "OPENCV" (fx, fy,
// cx, cy, k1, k2, p1, p2) camera (DatasetFileView::camera in gs/io/colmap.h) as a frame's
// fl_x, fl_y, cx, cy, w, h (and k1, k2, p1, p2); other models are refused naming the camera.
Expected<TransformsIntrinsics> transforms_intrinsics(const ColmapCamera& camera);

// A point cloud: positions and 8-bit colours.
struct PointCloud {
  std::vector<float> xyz;    // [P, 3]
  std::vector<uint8_t> rgb;  // [P, 3]; grey (128) when the file has no colours
};
// PLY point clouds as nerfstudio and its converters write them: ascii or binary_little_endian, a
// "vertex" element with x, y, z (float or double) and optionally red, green, blue (uchar, or
// float/double in [0, 1]); other vertex properties are skipped, elements after the vertices are
// ignored, elements before them are refused. Every count is checked against the file size first.
Expected<PointCloud> parse_point_ply(const uint8_t* data, size_t size, const std::string& source);
Expected<PointCloud> read_point_ply(const std::string& path);

// Random initial points for a dataset without any (3DGS initialises NeRF's synthetic scenes with
// random points too): `count` points drawn uniformly, with a SplitMix64 stream of `seed`, from the
// region that every camera sees (in front of it, beyond `near` and inside its image), grey. The
// region is searched around the cameras' focus (the point nearest to all optical axes, least
// squares) in a cube of half side the median camera-to-focus distance; when fewer than 1 in 500 of
// the cube's samples is seen by every camera, "every" relaxes to 90 %, 75 %, then 50 % of them.
// The points are drawn inside the box bounding the region (estimated from 65,536 probe samples) and
// kept only where that many cameras see them. Fails when the cameras see no common region.
struct RandomPoints {
  std::vector<float> xyz;    // [count, 3]
  std::vector<uint8_t> rgb;  // [count, 3], 128
  float box_min[3] = {0, 0, 0}, box_max[3] = {0, 0, 0};  // the box they were drawn in, world units
  double min_view_fraction = 1.0;  // fraction of the cameras that see every point
};
Expected<RandomPoints> random_points_in_common_view(const std::vector<Camera>& cameras, size_t count, uint64_t seed,
                                                    float near = 0.2f);

// Initial points from the views' masks (an RGBA image's alpha or masks/): the visual hull as the
// views see it. The region the views' cameras share (as above) is cut into cubic voxels, 128 along
// its longest side; a voxel stays in the hull when enough cameras see it (as above) and at most 1 in
// 20 of them (rounded down) sees its centre outside the mask dilated by one pixel. Each of the
// `count` points lies on the ray through a random point of a random mask pixel (>= 128) of a
// random view (marched through the hull in half-voxel steps; seeded SplitMix64), at the first depth
// whose colour most nearby views that see it inside their masks agree with (photo-consistency),
// else where the ray enters the hull, and takes that pixel's colour: for an object capture, points
// on the surfaces the cameras see, as structure from motion gives them, instead of throughout the
// box (or on hull faces no view sees, where empty space the masks cannot carve remains). Errors: a view
// without a mask or image of its camera's size, no common region, masks that carve everything away.
struct CarvedPoints {
  std::vector<float> xyz;    // [count, 3]
  std::vector<uint8_t> rgb;  // [count, 3]
  float box_min[3] = {0, 0, 0}, box_max[3] = {0, 0, 0};  // the carved region, world units
  double voxel = 0;            // voxel side, world units
  int grid[3] = {0, 0, 0};     // voxels along x, y, z
  size_t hull_voxels = 0;      // voxels of the hull
  size_t consistent = 0;       // points at a photo-consistent depth (the others: where the ray enters the hull)
};
Expected<CarvedPoints> carve_points_from_masks(const std::vector<const DatasetView*>& views, size_t count, uint64_t seed,
                                               float near = 0.2f);

}  // namespace gs::io
