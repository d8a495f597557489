// SPDX-License-Identifier: MIT
// COLMAP sparse models: readers for the binary and text formats, a text writer, and the dataset
// loader that turns a COLMAP folder into pinhole cameras + 8-bit images + SfM points.
// Formats: https://colmap.github.io/format.html (cameras/images/points3D .bin and .txt).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/scene_frame.h"
#include "gs/status.h"

namespace gs::io {

struct ColmapCamera {
  uint32_t id = 0;
  std::string model;           // "PINHOLE", "SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "OPENCV_FISHEYE", ...
  int width = 0, height = 0;
  std::vector<double> params;  // model-specific, COLMAP order
};

struct ColmapPoint2D {
  double xy[2] = {0, 0};
  int64_t point3d_id = -1;  // -1: no 3D point
};

struct ColmapImage {
  uint32_t id = 0;
  double qvec[4] = {1, 0, 0, 0};  // world-to-camera rotation (w, x, y, z)
  double tvec[3] = {0, 0, 0};     // world-to-camera translation
  uint32_t camera_id = 0;
  std::string name;               // relative to the images folder
  std::vector<ColmapPoint2D> points2d;
};

struct ColmapTrackElement {
  uint32_t image_id = 0;
  uint32_t point2d_idx = 0;
};

struct ColmapPoint3D {
  uint64_t id = 0;
  double xyz[3] = {0, 0, 0};
  uint8_t rgb[3] = {0, 0, 0};
  double error = 0;
  std::vector<ColmapTrackElement> track;
};

struct ColmapModel {
  std::vector<ColmapCamera> cameras;
  std::vector<ColmapImage> images;
  std::vector<ColmapPoint3D> points;
};

// Reads <dir>/{cameras,images,points3D}.bin, or the .txt files if the .bin set is absent.
// Errors name the file, the record (line number for text, record index/byte offset for binary)
// and what was wrong; on error nothing is returned.
Expected<ColmapModel> read_colmap_model(const std::string& dir);
Expected<ColmapModel> read_colmap_text(const std::string& dir);
Expected<ColmapModel> read_colmap_binary(const std::string& dir);
// Parsers over in-memory bytes (used by the file readers and the malformed-input tests).
// `source` names the file in error messages.
Status parse_cameras_text(const std::string& text, const std::string& source, std::vector<ColmapCamera>* out);
Status parse_images_text(const std::string& text, const std::string& source, std::vector<ColmapImage>* out);
Status parse_points3d_text(const std::string& text, const std::string& source, std::vector<ColmapPoint3D>* out);
Status parse_cameras_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapCamera>* out);
Status parse_images_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapImage>* out);
Status parse_points3d_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapPoint3D>* out);

// Writes the three .txt files into dir (created if missing); each file is written atomically.
Status write_colmap_text(const ColmapModel& model, const std::string& dir);
// Writes the three .bin files (used by round-trip tests and by tools that want binary).
Status write_colmap_binary(const ColmapModel& model, const std::string& dir);

// Converts a COLMAP (qvec, tvec) to a gs::Pose and back.
Pose pose_from_colmap(const double qvec[4], const double tvec[3]);
void pose_to_colmap(const Pose& pose, double qvec[4], double tvec[3]);
// A pose in a scene frame (gs/scene_frame.h) as COLMAP's (qvec, tvec) in the user's frame; for the
// identity frame exactly pose_to_colmap's values.
void pose_to_colmap(const SceneFrame& frame, const Pose& pose, double qvec[4], double tvec[3]);

// Camera models (https://colmap.github.io/cameras.html; COLMAP's src/colmap/sensor/models.h), for
// a ray (x, y, z) in camera axes (x right, y down, z forward), z > 0, pixel centres at +0.5:
//   PINHOLE fx fy cx cy / SIMPLE_PINHOLE f cx cy: u = fx x/z + cx, v = fy y/z + cy.
//   SIMPLE_RADIAL f cx cy k / RADIAL f cx cy k1 k2 / OPENCV fx fy cx cy k1 k2 p1 p2: on the pinhole
//     coordinates (a, b) = (x/z, y/z), r2 = a^2 + b^2, a_d = a (1 + k1 r2 + k2 r2^2) + 2 p1 a b +
//     p2 (r2 + 2 a^2), b_d = b (1 + k1 r2 + k2 r2^2) + 2 p2 a b + p1 (r2 + 2 b^2); u = fx a_d + cx.
//   OPENCV_FISHEYE fx fy cx cy k1 k2 k3 k4 (equidistant): theta = the ray's angle from the axis,
//     theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8); the image point lies
//     theta_d from the principal point (in focal units) in the ray's direction:
//     u = fx theta_d x / sqrt(x^2 + y^2) + cx, v = fy theta_d y / sqrt(x^2 + y^2) + cy.
//   RADIAL_FISHEYE f cx cy k1 k2 / SIMPLE_RADIAL_FISHEYE f cx cy k: the same with k3 = k4 = 0
//     (and k2 = 0), fx = fy = f.
//   FOV fx fy cx cy omega (Devernay and Faugeras): the radius is
//     atan(2 tan(theta) tan(omega / 2)) / omega instead of theta_d (tan(theta) at omega = 0).
// colmap_project gives (u, v) for these models; false for another model, a ray with z <= 0 or a
// non-finite result. The fisheye models only describe rays of the front half-space (theta < 90
// degrees), and only where the radius still grows with theta: fisheye_valid_angle is the angle up
// to which it does (radians, at most pi / 2, sampled every 0.01 degree; FOV: pi / 2 when
// |omega| < pi, else 0), 0 for a model that is not a fisheye.
bool colmap_project(const ColmapCamera& camera, const double ray[3], double* u, double* v);
bool is_fisheye_model(const std::string& model);  // OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV
double fisheye_valid_angle(const ColmapCamera& camera);

// Which kind of folder load_dataset reads (see load_dataset).
enum class DatasetLayout {
  kAuto,        // COLMAP when <root>/<sparse_dir> is a folder, else transforms files when present
  kColmap,      // <root>/<sparse_dir> + <root>/<images_dir>
  kTransforms,  // <root>/transforms.json, or <root>/transforms_train.json (+ _test.json)
};

// Where a dataset's points came from (Dataset::points_source).
enum class PointsSource {
  kNone,    // none: a transforms dataset with DatasetOptions::random_points = 0
  kSfm,     // the COLMAP model's points3D
  kPly,     // a transforms file's "ply_file_path" point cloud
  kRandom,  // drawn by load_dataset (random_points_in_common_view, gs/io/transforms.h)
  kCarved,  // the training job's replacement of random points when every training view has a mask
            // (carve_points_from_masks, gs/io/transforms.h)
};
const char* points_source_name(PointsSource source);  // "none", "sfm", "ply", "random", "carved"

struct DatasetOptions {
  std::string images_dir = "images";  // relative to the dataset root (COLMAP layout)
  std::string sparse_dir = "sparse/0";
  // Masks by image name, relative to the dataset root ("" disables): for image NAME (its name in
  // the COLMAP model, or its path relative to the transforms file) the first of masks/NAME.png
  // (COLMAP's --ImageReader.mask_path convention, e.g. masks/0001.jpg.png), masks/NAME, and
  // masks/NAME with its extension replaced by .png (CO3D); for a transforms view the same three
  // again with NAME's first folder dropped (images/0001.png -> masks/0001.png). When the folder
  // exists every loaded view must have a mask there (else an error names the view and the paths
  // tried), unless the transforms frames name their masks (mask_path; then all of them must).
  std::string masks_dir = "masks";
  DatasetLayout layout = DatasetLayout::kAuto;
  int max_width = 0;                  // > 0: downscale images (and intrinsics) to at most this width
  // Every llffhold-th image (sorted by name, index 0, 8, ...) is a test view; 0: none. A transforms
  // dataset's own split (transforms_test.json, test_filenames) takes precedence.
  int llffhold = 8;
  // Which views' images are decoded: the others keep their camera and an empty image (memory
  // follows the job: evaluating the test views does not hold the training images). Masks follow.
  enum class Images { kAll, kTest, kTrain } images = Images::kAll;
  // Points drawn for a transforms dataset without a point cloud (uniform in the cameras' common
  // view, grey; see random_points_in_common_view), and their seed. 0: leave it without points.
  // 10,000 points voxelise into ~10,000 anchors (100,000 neural Gaussians at k = 10), within the
  // trainer's default initial budget (25,000) and quick to prune where the scene is empty.
  int random_points = 10000;
  uint64_t random_points_seed = 1;
  // Fisheye cameras (OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV) become a PINHOLE
  // camera of the source image's size with this horizontal field of view (degrees, across the
  // width; 1-170), fx = fy, the principal point at the image centre. 0: the widest one up to
  // kDefaultFisheyeFovDeg whose every pixel has a source pixel (inside the image, and within the
  // lens's valid angle, fisheye_valid_angle); found to 0.01 degree. Pixels without a source are
  // marked in DatasetView::valid (training and evaluation leave them out).
  double fisheye_fov_deg = 0;
  // The frame the cameras and points are given in (gs/scene_frame.h): unset, the one
  // choose_scene_frame picks from all the views' camera centres (the identity for an ordinary scene);
  // set, that one (a trained model's, so its dataset lines up with it).
  std::optional<SceneFrame> frame;
};

// One view of a dataset: a pinhole camera (after undistortion and downscaling) and its image.
struct DatasetView {
  std::string name;
  uint32_t image_id = 0;
  Camera camera;
  Image8 image;  // RGB, camera.intr.width x camera.intr.height, as stored (not composited)
  // Coverage of the subject, 1 channel, same size as image (255: the subject, 0: background), from
  // the image's alpha channel or a file in masks/; empty when the dataset has none. Training and
  // evaluation compare renders with image * mask + background * (1 - mask).
  Image8 mask;
  // Which pixels have a source pixel, 1 channel, same size as image (255: yes, 0: no), when some do
  // not; empty when all do (always for pinhole cameras). Undistortion leaves pixels without a
  // source: those whose position in the distorted image lies outside it, or (fisheye) beyond the
  // lens's valid angle; such a pixel is 0 in image and mask. A downscaled pixel is valid when its
  // area mean rounds to 255 (over 99.8 % of its area has a source). Training drops the other pixels from the loss and evaluation
  // from its figures (gs/model/step_graph.h, gs/model/evaluate.h), instead of comparing them with
  // the background.
  Image8 valid;
  bool is_test = false;
};
// The largest default field of view for fisheye cameras (DatasetOptions::fisheye_fov_deg = 0):
// wider pinholes stretch the image's edges (a pinhole's radius grows as tan(theta)).
inline constexpr double kDefaultFisheyeFovDeg = 120.0;

struct Dataset {
  std::string root;
  DatasetLayout layout = DatasetLayout::kColmap;  // the layout read (never kAuto)
  std::vector<DatasetView> views;     // sorted by name
  std::vector<float> points_xyz;      // [P, 3]
  std::vector<uint8_t> points_rgb;    // [P, 3]
  PointsSource points_source = PointsSource::kSfm;
  // The frame of every pose and point above (x_frame = scale (x_user - centre)); converted from the
  // files' double values, so a scene far from the origin keeps its precision. The identity for an
  // ordinary scene (then everything is as stored).
  SceneFrame frame;
  // kRandom: the box the points were drawn in (world units) and the fraction of all cameras that
  // see each of them (1: every camera).
  float random_box_min[3] = {0, 0, 0}, random_box_max[3] = {0, 0, 0};
  double random_min_view_fraction = 0;
};

// Loads a dataset (`root` is its folder, or a transforms .json file inside it).
//
// COLMAP layout: <root>/<sparse_dir> (binary or text) and <root>/<images_dir>. PINHOLE and
// SIMPLE_PINHOLE are used directly; SIMPLE_RADIAL, RADIAL and OPENCV images are undistorted on load
// to a PINHOLE camera with the same fx, fy, cx, cy; OPENCV_FISHEYE, RADIAL_FISHEYE,
// SIMPLE_RADIAL_FISHEYE and FOV images to a PINHOLE camera of options.fisheye_fov_deg (the
// projections are colmap_project's; bilinear resampling). Pixels of the undistorted image without
// a source pixel are marked in DatasetView::valid. A fisheye camera whose radius stops growing
// within the angles the pinhole needs (fisheye_valid_angle) is refused, naming the file and camera
// and the widest field of view it allows; any other model (FULL_OPENCV, THIN_PRISM_FISHEYE, ...)
// is refused with an error naming it. Images must match their camera's size. Points: the model's
// points3D.
//
// Transforms layout (gs/io/transforms.h): <root>/transforms.json (instant-ngp, nerfstudio: split
// from its test_filenames (else val_filenames) and train_filenames, frames in neither list are left
// out; without lists every llffhold-th by name), or NeRF synthetic's <root>/transforms_train.json
// and transforms_test.json (their split; transforms_val.json is not read). A .json path as `root`
// reads that file (transforms_train/test/val.json: the train + test pair beside it). Image paths are
// relative to the json and must stay below it (no absolute paths, no '..'); one without an extension
// gets .png, .jpg or .jpeg, whichever exists. Focal length from fl_x/fl_y, else
// 0.5 w / tan(0.5 camera_angle_x) (camera_angle_y for fy, else fy = fx); cx, cy default to the
// centre, w, h to the image's size. k1, k2, p1, p2 are undistorted like an OPENCV camera. Poses
// are converted from OpenGL camera-to-world (pose_from_transform_matrix). Points: the
// "ply_file_path" point cloud, else options.random_points random ones.
//
// Masks (both layouts): an image with an alpha channel (PNG RGBA or grey + alpha) keeps its RGB in
// `image` and its alpha becomes `mask`. A mask file (nerfstudio's per-frame "mask_path", else
// options.masks_dir) is read as its grey level composited over black: luminance
// (77 R + 150 G + 29 B) / 256 times alpha / 255, so a grey, RGB, grey + alpha or RGBA file works; a
// file holding only 0 and 1 is a 0/1 mask and is scaled to 0/255. With both, the mask is their
// intersection min(alpha, mask): a binary mask cuts a soft alpha, and the same coverage given twice
// (hbgs synth --object writes RGBA images and masks/) stays as it is, where a product would square
// the partial coverage of edge pixels. A mask must have its image's size (else an error names both
// files and sizes), and is undistorted and downscaled with the image (outside the distorted image: 0).
Expected<Dataset> load_dataset(const std::string& root, const DatasetOptions& options = {});

// A dataset's views as its files describe them, without decoding any pixels: what writers of posed
// models start from (hbgs train --optimize-poses writes refined_poses/, hbgs register --views
// writes registered/). Views, names, split and mask files are those load_dataset(root, options)
// would give; cameras are as stored (the image files' size, distortion terms kept).
struct DatasetFileView {
  std::string name;        // as DatasetView::name
  std::string image_path;  // the image file (root or the json's folder joined with the name)
  // The mask file load_dataset reads for this view (nerfstudio's mask_path or the one found in
  // options.masks_dir); "" when there is none (no masks, the image's alpha only, or none found).
  std::string mask_path;
  // The view's camera before undistortion and downscaling, as model "PINHOLE" (fx, fy, cx, cy),
  // "OPENCV" (fx, fy, cx, cy, k1, k2, p1, p2), "OPENCV_FISHEYE" (fx, fy, cx, cy, k1, k2, k3, k4) or
  // "FOV" (fx, fy, cx, cy, omega) whatever the stored model (SIMPLE_RADIAL is OPENCV with fx = fy
  // and k2 = p1 = p2 = 0; RADIAL_FISHEYE and SIMPLE_RADIAL_FISHEYE are OPENCV_FISHEYE with fx = fy
  // and the missing k zero): fx fy cx cy first in every case; id is the model camera's id.
  // Writers that need a pinhole or OpenCV camera (transforms_intrinsics) refuse the fisheye ones.
  ColmapCamera camera;
  size_t model_image = 0;  // index into DatasetFiles::model.images: the view's id and pose
  bool is_test = false;    // as DatasetView::is_test
};
struct DatasetFiles {
  DatasetLayout layout = DatasetLayout::kColmap;  // never kAuto
  // COLMAP layout: the model as read from <root>/<sparse_dir> (its cameras, images and points as
  // stored). Transforms layout: one PINHOLE or OPENCV camera per distinct set of intrinsics, one
  // image per view (named as the view, the pose from its transform_matrix), no points.
  ColmapModel model;
  std::vector<DatasetFileView> views;  // sorted by name, as Dataset::views
};
Expected<DatasetFiles> read_dataset_files(const std::string& root, const DatasetOptions& options = {});

}  // namespace gs::io
