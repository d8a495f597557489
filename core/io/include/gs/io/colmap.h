// SPDX-License-Identifier: MIT
// COLMAP sparse models: readers for the binary and text formats, a text writer, and the dataset
// loader that turns a COLMAP folder into pinhole cameras + 8-bit images + SfM points.
// Formats: https://colmap.github.io/format.html (cameras/images/points3D .bin and .txt).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/status.h"

namespace gs::io {

struct ColmapCamera {
  uint32_t id = 0;
  std::string model;           // "PINHOLE", "SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", ...
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

struct DatasetOptions {
  std::string images_dir = "images";  // relative to the dataset root
  std::string sparse_dir = "sparse/0";
  int max_width = 0;                  // > 0: downscale images (and intrinsics) to at most this width
  int llffhold = 8;                   // every llffhold-th image (sorted by name, index 0, 8, ...) is a test view; 0: none
  // Which views' images are decoded: the others keep their camera and an empty image (memory
  // follows the job: evaluating the test views does not hold the training images).
  enum class Images { kAll, kTest, kTrain } images = Images::kAll;
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
  bool is_test = false;
};

struct Dataset {
  std::string root;
  std::vector<DatasetView> views;     // sorted by name
  std::vector<float> points_xyz;      // [P, 3]
  std::vector<uint8_t> points_rgb;    // [P, 3]
};

// Loads a COLMAP dataset. PINHOLE and SIMPLE_PINHOLE are used directly; SIMPLE_RADIAL, RADIAL and
// OPENCV images are undistorted on load to a PINHOLE camera with the same fx, fy, cx, cy;
// any other model is refused with an error naming it. Images must match their camera's size.
Expected<Dataset> load_dataset(const std::string& root, const DatasetOptions& options = {});

}  // namespace gs::io
