// SPDX-License-Identifier: MIT
// COLMAP model plumbing shared by the text and binary formats: the camera-model table, record
// checks, the folder-level readers (which pick .bin or .txt) and pose conversion.
#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "../io_util.h"
#include "colmap_internal.h"
#include "gs/platform/file.h"
#include "gs/pose/pose.h"
#include "gs/platform/path.h"

namespace gs::io {
namespace detail {
namespace {

// Ids and parameter counts as in COLMAP (src/colmap/sensor/models.h); `focals` = how many of
// the leading parameters are focal lengths (they must be > 0).
struct ModelRow {
  CameraModelInfo info;
  int focals;
};
const ModelRow kModels[] = {
    {{0, "SIMPLE_PINHOLE", 3}, 1},        {{1, "PINHOLE", 4}, 2},
    {{2, "SIMPLE_RADIAL", 4}, 1},         {{3, "RADIAL", 5}, 1},
    {{4, "OPENCV", 8}, 2},                {{5, "OPENCV_FISHEYE", 8}, 2},
    {{6, "FULL_OPENCV", 12}, 2},          {{7, "FOV", 5}, 2},
    {{8, "SIMPLE_RADIAL_FISHEYE", 4}, 1}, {{9, "RADIAL_FISHEYE", 5}, 1},
    {{10, "THIN_PRISM_FISHEYE", 12}, 2},
};

const ModelRow* find_row(const std::string& name) {
  for (const ModelRow& r : kModels)
    if (name == r.info.name) return &r;
  return nullptr;
}

}  // namespace

const CameraModelInfo* find_camera_model(const std::string& name) {
  const ModelRow* r = find_row(name);
  return r ? &r->info : nullptr;
}

const CameraModelInfo* find_camera_model(int id) {
  for (const ModelRow& r : kModels)
    if (r.info.id == id) return &r.info;
  return nullptr;
}

std::string check_camera(const ColmapCamera& cam) {
  const ModelRow* row = find_row(cam.model);
  if (row == nullptr) return "unknown camera model '" + cam.model + "'";
  if (int(cam.params.size()) != row->info.num_params)
    return "camera model " + cam.model + " takes " + std::to_string(row->info.num_params) + " parameters, got " +
           std::to_string(cam.params.size());
  if (cam.width <= 0 || cam.width > kMaxCameraSide || cam.height <= 0 || cam.height > kMaxCameraSide)
    return "camera size " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + " outside 1.." +
           std::to_string(kMaxCameraSide);
  for (size_t i = 0; i < cam.params.size(); ++i)
    if (!std::isfinite(cam.params[i])) return "camera parameter " + std::to_string(i) + " is not finite";
  for (int i = 0; i < row->focals; ++i)
    if (!(cam.params[size_t(i)] > 0)) return "focal length " + std::to_string(cam.params[size_t(i)]) + " is not positive";
  return {};
}

std::string check_pose(const double qvec[4], const double tvec[3]) {
  for (int i = 0; i < 4; ++i)
    if (!std::isfinite(qvec[i])) return "quaternion component " + std::to_string(i) + " is not finite";
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(tvec[i])) return "translation component " + std::to_string(i) + " is not finite";
  const double n2 = qvec[0] * qvec[0] + qvec[1] * qvec[1] + qvec[2] * qvec[2] + qvec[3] * qvec[3];
  if (!(n2 > 1e-12)) return "quaternion has zero length";
  return {};
}

Status check_model_links(const ColmapModel& model, const std::string& images_file, const std::string& points_file) {
  std::unordered_set<uint32_t> cameras, images;
  for (const ColmapCamera& c : model.cameras) cameras.insert(c.id);
  // Image names become file names (the images read, the renders written): each must stay inside
  // the images folder, and two images may not share one.
  std::unordered_map<std::string, uint32_t> names;
  for (const ColmapImage& im : model.images) {
    if (std::string why = platform::relative_name_problem(im.name); !why.empty())
      return parse_error(images_file + ": image " + std::to_string(im.id) + " is named '" + im.name +
                         "', which cannot be a file below the images folder: " + why);
    const auto [it, fresh] = names.emplace(im.name, im.id);
    if (!fresh)
      return parse_error(images_file + ": images " + std::to_string(it->second) + " and " + std::to_string(im.id) +
                         " have the same name '" + im.name + "'");
    if (!cameras.count(im.camera_id))
      return parse_error(images_file + ": image " + std::to_string(im.id) + " ('" + im.name + "') refers to camera " +
                         std::to_string(im.camera_id) + ", which is not in the cameras file");
    images.insert(im.id);
  }
  for (const ColmapPoint3D& p : model.points)
    for (const ColmapTrackElement& t : p.track)
      if (!images.count(t.image_id))
        return parse_error(points_file + ": point " + std::to_string(p.id) + " has a track element on image " +
                           std::to_string(t.image_id) + ", which is not in the images file");
  return Status::Ok();
}

}  // namespace detail

namespace {

bool has_all(const std::string& dir, const char* ext) {
  for (const char* f : {"cameras", "images", "points3D"})
    if (!platform::file_exists(detail::join_path(dir, std::string(f) + ext))) return false;
  return true;
}

}  // namespace

Expected<ColmapModel> read_colmap_text(const std::string& dir) {
  return detail::guarded(dir, [&]() -> Expected<ColmapModel> {
    const std::string cams = detail::join_path(dir, "cameras.txt");
    const std::string imgs = detail::join_path(dir, "images.txt");
    const std::string pts = detail::join_path(dir, "points3D.txt");
    ColmapModel model;
    auto text = platform::read_text_file(cams);
    if (!text.ok()) return text.status();
    GS_RETURN_IF_ERROR(parse_cameras_text(*text, cams, &model.cameras));
    text = platform::read_text_file(imgs);
    if (!text.ok()) return text.status();
    GS_RETURN_IF_ERROR(parse_images_text(*text, imgs, &model.images));
    text = platform::read_text_file(pts);
    if (!text.ok()) return text.status();
    GS_RETURN_IF_ERROR(parse_points3d_text(*text, pts, &model.points));
    GS_RETURN_IF_ERROR(detail::check_model_links(model, imgs, pts));
    return model;
  });
}

Expected<ColmapModel> read_colmap_binary(const std::string& dir) {
  return detail::guarded(dir, [&]() -> Expected<ColmapModel> {
    const std::string cams = detail::join_path(dir, "cameras.bin");
    const std::string imgs = detail::join_path(dir, "images.bin");
    const std::string pts = detail::join_path(dir, "points3D.bin");
    ColmapModel model;
    auto bytes = platform::read_file(cams);
    if (!bytes.ok()) return bytes.status();
    GS_RETURN_IF_ERROR(parse_cameras_binary(bytes->data(), bytes->size(), cams, &model.cameras));
    bytes = platform::read_file(imgs);
    if (!bytes.ok()) return bytes.status();
    GS_RETURN_IF_ERROR(parse_images_binary(bytes->data(), bytes->size(), imgs, &model.images));
    bytes = platform::read_file(pts);
    if (!bytes.ok()) return bytes.status();
    GS_RETURN_IF_ERROR(parse_points3d_binary(bytes->data(), bytes->size(), pts, &model.points));
    GS_RETURN_IF_ERROR(detail::check_model_links(model, imgs, pts));
    return model;
  });
}

Expected<ColmapModel> read_colmap_model(const std::string& dir) {
  return detail::guarded(dir, [&]() -> Expected<ColmapModel> {
    if (!platform::is_directory(dir)) return io_error(dir + ": no such folder (expected a COLMAP sparse model)");
    if (has_all(dir, ".bin")) return read_colmap_binary(dir);
    if (has_all(dir, ".txt")) return read_colmap_text(dir);
    return io_error(dir + ": no complete COLMAP model (need cameras, images and points3D as .bin or .txt)");
  });
}

Pose pose_from_colmap(const double qvec[4], const double tvec[3]) {
  Pose pose;
  double R[9];
  pose::rotation_from_quaternion(qvec, R);
  for (int i = 0; i < 9; ++i) pose.R[i] = float(R[i]);
  for (int i = 0; i < 3; ++i) pose.t[i] = float(tvec[i]);
  return pose;
}

void pose_to_colmap(const Pose& pose, double qvec[4], double tvec[3]) {
  double m[9];
  for (int i = 0; i < 9; ++i) m[i] = pose.R[i];
  detail::quaternion_from_rotation(m, qvec);
  for (int i = 0; i < 3; ++i) tvec[i] = pose.t[i];
}

void pose_to_colmap(const SceneFrame& frame, const Pose& pose, double qvec[4], double tvec[3]) {
  pose_to_colmap(pose, qvec, tvec);
  if (frame.identity()) return;
  double R[9];  // the rotation a reader gets from qvec
  pose::rotation_from_quaternion(qvec, R);
  pose_to_user(frame, pose, R, tvec);
}

namespace detail {

void quaternion_from_rotation(const double m[9], double q[4]) {
  // Shepperd's method: divide by the largest of the four candidate terms for stability.
  const double tr = m[0] + m[4] + m[8];
  double w, x, y, z;
  if (tr > m[0] && tr > m[4] && tr > m[8]) {
    const double s = 2 * std::sqrt(std::max(0.0, 1 + tr));
    w = s / 4, x = (m[7] - m[5]) / s, y = (m[2] - m[6]) / s, z = (m[3] - m[1]) / s;
  } else if (m[0] > m[4] && m[0] > m[8]) {
    const double s = 2 * std::sqrt(std::max(0.0, 1 + m[0] - m[4] - m[8]));
    w = (m[7] - m[5]) / s, x = s / 4, y = (m[1] + m[3]) / s, z = (m[2] + m[6]) / s;
  } else if (m[4] > m[8]) {
    const double s = 2 * std::sqrt(std::max(0.0, 1 + m[4] - m[0] - m[8]));
    w = (m[2] - m[6]) / s, x = (m[1] + m[3]) / s, y = s / 4, z = (m[5] + m[7]) / s;
  } else {
    const double s = 2 * std::sqrt(std::max(0.0, 1 + m[8] - m[0] - m[4]));
    w = (m[3] - m[1]) / s, x = (m[2] + m[6]) / s, y = (m[5] + m[7]) / s, z = s / 4;
  }
  double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (!(n > 0) || !std::isfinite(n)) w = 1, x = y = z = 0, n = 1;
  const double sign = w < 0 ? -1.0 : 1.0;  // COLMAP keeps w >= 0
  q[0] = sign * w / n, q[1] = sign * x / n, q[2] = sign * y / n, q[3] = sign * z / n;
}

}  // namespace detail

}  // namespace gs::io
