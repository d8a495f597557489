// SPDX-License-Identifier: MIT
// transforms.json parsing (NeRF synthetic, instant-ngp, nerfstudio) and the conversion of its
// OpenGL camera-to-world matrices to hbgs's world-to-camera poses. The parser only checks and
// collects; gs::io::load_dataset resolves image sizes, splits and points (dataset.cpp).
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>

#include "../colmap/colmap_internal.h"
#include "../io_util.h"
#include "gs/constants.h"
#include "gs/io/image.h"
#include "gs/io/transforms.h"
#include "gs/pose/pose.h"

namespace gs::io {
namespace {

using Json = nlohmann::json;

// Largest deviation of R^T R from the identity accepted as a rotation: matrices written with
// float32 precision are orthonormal to ~1e-7, a scaled or sheared one is off by far more.
constexpr double kRigidTolerance = 1e-3;

std::string frame_prefix(const std::string& source, long frame) {
  return frame < 0 ? source + ": " : source + ": frame " + std::to_string(frame) + ": ";
}

Status read_number(const Json& obj, const char* key, const std::string& at, std::optional<double>* out) {
  const auto it = obj.find(key);
  if (it == obj.end()) return Status::Ok();
  if (!it->is_number()) return parse_error(at + "'" + key + "' must be a number");
  const double v = it->get<double>();
  if (!std::isfinite(v)) return parse_error(at + "'" + key + "' is not finite");
  *out = v;
  return Status::Ok();
}

Status read_intrinsics(const Json& obj, const std::string& at, TransformsIntrinsics* in) {
  struct Key {
    const char* name;
    std::optional<double> TransformsIntrinsics::*field;
    bool positive;
  };
  static const Key kKeys[] = {
      {"fl_x", &TransformsIntrinsics::fl_x, true},   {"fl_y", &TransformsIntrinsics::fl_y, true},
      {"cx", &TransformsIntrinsics::cx, false},      {"cy", &TransformsIntrinsics::cy, false},
      {"camera_angle_x", &TransformsIntrinsics::camera_angle_x, true},
      {"camera_angle_y", &TransformsIntrinsics::camera_angle_y, true},
      {"k1", &TransformsIntrinsics::k1, false},      {"k2", &TransformsIntrinsics::k2, false},
      {"k3", &TransformsIntrinsics::k3, false},      {"k4", &TransformsIntrinsics::k4, false},
      {"p1", &TransformsIntrinsics::p1, false},      {"p2", &TransformsIntrinsics::p2, false},
  };
  for (const Key& k : kKeys) {
    GS_RETURN_IF_ERROR(read_number(obj, k.name, at, &(in->*k.field)));
    const std::optional<double>& v = in->*k.field;
    if (k.positive && v && !(*v > 0)) return parse_error(at + "'" + k.name + "' must be > 0, got " + std::to_string(*v));
  }
  for (const auto& angle : {in->camera_angle_x, in->camera_angle_y})
    if (angle && !(*angle < kPi)) return parse_error(at + "a camera angle must be below pi radians, got " + std::to_string(*angle));
  for (const char* key : {"w", "h"}) {
    std::optional<double> v;
    GS_RETURN_IF_ERROR(read_number(obj, key, at, &v));
    if (!v) continue;
    if (!(*v >= 1 && *v <= kMaxImageSide) || std::floor(*v) != *v)
      return parse_error(at + "'" + key + "' must be a whole number of pixels in 1.." + std::to_string(kMaxImageSide) +
                         ", got " + std::to_string(*v));
    (key[0] == 'w' ? in->w : in->h) = int(*v);
  }
  for (const auto& [name, value] : {std::pair<const char*, std::optional<double>>{"k3", in->k3}, {"k4", in->k4}})
    if (value && *value != 0)
      return unsupported(at + "'" + name + "' = " + std::to_string(*value) +
                         ": hbgs undistorts k1, k2, p1, p2 (OpenCV) only; undistort the images first");
  return Status::Ok();
}

Status check_camera_model(const Json& obj, const std::string& at) {
  const auto it = obj.find("camera_model");
  if (it == obj.end()) return Status::Ok();
  if (!it->is_string()) return parse_error(at + "'camera_model' must be a string");
  const std::string model = it->get<std::string>();
  if (model == "OPENCV" || model == "PINHOLE" || model == "SIMPLE_PINHOLE" || model == "PERSPECTIVE") return Status::Ok();
  return unsupported(at + "camera_model '" + model + "' is not supported (OPENCV, PINHOLE or SIMPLE_PINHOLE)");
}

// Overrides the fields of `base` that `frame` sets.
TransformsIntrinsics merged(const TransformsIntrinsics& base, const TransformsIntrinsics& frame) {
  TransformsIntrinsics m = base;
  auto take = [](auto& dst, const auto& src) {
    if (src) dst = src;
  };
  take(m.fl_x, frame.fl_x), take(m.fl_y, frame.fl_y), take(m.cx, frame.cx), take(m.cy, frame.cy);
  take(m.camera_angle_x, frame.camera_angle_x), take(m.camera_angle_y, frame.camera_angle_y);
  take(m.w, frame.w), take(m.h, frame.h);
  take(m.k1, frame.k1), take(m.k2, frame.k2), take(m.k3, frame.k3), take(m.k4, frame.k4);
  take(m.p1, frame.p1), take(m.p2, frame.p2);
  return m;
}

Status read_matrix(const Json& frame, const std::string& at, double m[16]) {
  const auto it = frame.find("transform_matrix");
  if (it == frame.end()) return parse_error(at + "no 'transform_matrix'");
  const Json& rows = *it;
  if (!rows.is_array() || (rows.size() != 4 && rows.size() != 3))
    return parse_error(at + "'transform_matrix' must be an array of 4 (or 3) rows of 4 numbers");
  const double last[4] = {0, 0, 0, 1};
  std::memcpy(m + 12, last, sizeof last);
  for (size_t r = 0; r < rows.size(); ++r) {
    if (!rows[r].is_array() || rows[r].size() != 4)
      return parse_error(at + "'transform_matrix' row " + std::to_string(r) + " is not an array of 4 numbers");
    for (size_t c = 0; c < 4; ++c) {
      if (!rows[r][c].is_number())
        return parse_error(at + "'transform_matrix' entry (" + std::to_string(r) + ", " + std::to_string(c) + ") is not a number");
      m[4 * r + c] = rows[r][c].get<double>();
    }
  }
  double q[4], t[3];
  if (std::string why = pose_from_transform_matrix(m, q, t); !why.empty())
    return parse_error(at + "'transform_matrix' is not a camera pose: " + why);
  return Status::Ok();
}

Status read_string_list(const Json& top, const char* key, const std::string& source,
                        std::optional<std::vector<std::string>>* out) {
  const auto it = top.find(key);
  if (it == top.end()) return Status::Ok();
  if (!it->is_array()) return parse_error(source + ": '" + key + "' must be an array of file names");
  std::vector<std::string> names;
  for (size_t i = 0; i < it->size(); ++i) {
    if (!(*it)[i].is_string()) return parse_error(source + ": '" + key + "' entry " + std::to_string(i) + " is not a string");
    names.push_back((*it)[i].get<std::string>());
  }
  *out = std::move(names);
  return Status::Ok();
}

Status parse(const std::string& text, const std::string& source, TransformsFile* out) {
  Json top;
  try {
    top = Json::parse(text);
  } catch (const Json::exception& e) {
    // e.what(): "[json.exception.parse_error.101] parse error at line L, column C: ..." (or an
    // out_of_range error for a number too large for a double).
    std::string what = e.what();
    if (const size_t p = what.find("] "); p != std::string::npos) what = what.substr(p + 2);
    return parse_error(source + ": not valid JSON: " + what);
  }
  if (!top.is_object()) return parse_error(source + ": the top level must be a JSON object");
  TransformsFile file;
  TransformsIntrinsics global;
  GS_RETURN_IF_ERROR(read_intrinsics(top, frame_prefix(source, -1), &global));
  GS_RETURN_IF_ERROR(check_camera_model(top, frame_prefix(source, -1)));
  GS_RETURN_IF_ERROR(read_string_list(top, "train_filenames", source, &file.train_filenames));
  GS_RETURN_IF_ERROR(read_string_list(top, "val_filenames", source, &file.val_filenames));
  GS_RETURN_IF_ERROR(read_string_list(top, "test_filenames", source, &file.test_filenames));
  if (const auto ply = top.find("ply_file_path"); ply != top.end()) {
    if (!ply->is_string() || ply->get<std::string>().empty())
      return parse_error(source + ": 'ply_file_path' must be a non-empty string");
    file.ply_file_path = ply->get<std::string>();
  }
  const auto frames = top.find("frames");
  if (frames == top.end()) return parse_error(source + ": no 'frames' array");
  if (!frames->is_array()) return parse_error(source + ": 'frames' must be an array");
  if (frames->empty()) return parse_error(source + ": 'frames' is empty");
  file.frames.reserve(frames->size());
  for (size_t i = 0; i < frames->size(); ++i) {
    const Json& f = (*frames)[i];
    const std::string at = frame_prefix(source, long(i));
    if (!f.is_object()) return parse_error(at + "not a JSON object");
    TransformsFrame frame;
    const auto path = f.find("file_path");
    if (path == f.end()) return parse_error(at + "no 'file_path'");
    if (!path->is_string() || path->get<std::string>().empty()) return parse_error(at + "'file_path' must be a non-empty string");
    frame.file_path = path->get<std::string>();
    if (const auto mask = f.find("mask_path"); mask != f.end()) {
      if (!mask->is_string() || mask->get<std::string>().empty()) return parse_error(at + "'mask_path' must be a non-empty string");
      frame.mask_path = mask->get<std::string>();
    }
    TransformsIntrinsics own;
    GS_RETURN_IF_ERROR(read_intrinsics(f, at, &own));
    GS_RETURN_IF_ERROR(check_camera_model(f, at));
    frame.intrinsics = merged(global, own);
    GS_RETURN_IF_ERROR(read_matrix(f, at, frame.transform_matrix));
    file.frames.push_back(std::move(frame));
  }
  *out = std::move(file);
  return Status::Ok();
}

}  // namespace

Status parse_transforms_json(const std::string& text, const std::string& source, TransformsFile* out) {
  return detail::guarded(source, [&]() { return parse(text, source, out); });
}

std::string pose_from_transform_matrix(const double c2w[16], double qvec[4], double tvec[3]) {
  for (int i = 0; i < 16; ++i)
    if (!std::isfinite(c2w[i])) return "entry (" + std::to_string(i / 4) + ", " + std::to_string(i % 4) + ") is not finite";
  const double last[4] = {0, 0, 0, 1};
  for (int c = 0; c < 4; ++c)
    if (std::abs(c2w[12 + c] - last[c]) > 1e-6) return "the last row is not (0, 0, 0, 1)";
  // World-to-camera rotation in COLMAP axes: R[i][j] = s_i R_c2w[j][i], s = (1, -1, -1) flips the
  // camera's y (up -> down) and z (back -> forward).
  const double s[3] = {1, -1, -1};
  double R[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[3 * i + j] = s[i] * c2w[4 * j + i];
  double worst = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double dot = 0;
      for (int k = 0; k < 3; ++k) dot += R[3 * k + i] * R[3 * k + j];
      worst = std::max(worst, std::abs(dot - (i == j ? 1.0 : 0.0)));
    }
  if (!(worst <= kRigidTolerance))
    return "its 3x3 rotation is not orthonormal (R^T R differs from the identity by " + std::to_string(worst) +
           "; a scaled or sheared matrix?)";
  const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) + R[2] * (R[3] * R[7] - R[4] * R[6]);
  if (!(det > 0)) return "its 3x3 rotation is a reflection (determinant " + std::to_string(det) + ")";
  detail::quaternion_from_rotation(R, qvec);
  // t = -R C with the rotation the quaternion stands for, so the camera centre stays exact.
  double Rq[9];
  pose::rotation_from_quaternion(qvec, Rq);
  const double C[3] = {c2w[3], c2w[7], c2w[11]};
  for (int i = 0; i < 3; ++i) tvec[i] = -(Rq[3 * i] * C[0] + Rq[3 * i + 1] * C[1] + Rq[3 * i + 2] * C[2]);
  return "";
}

void transform_matrix_from_pose(const double qvec[4], const double tvec[3], double c2w[16]) {
  double R[9];
  pose::rotation_from_quaternion(qvec, R);
  const double s[3] = {1, -1, -1};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c2w[4 * i + j] = R[3 * j + i] * s[j];  // R_c2w = R^T diag(s)
    c2w[4 * i + 3] = -(R[i] * tvec[0] + R[3 + i] * tvec[1] + R[6 + i] * tvec[2]);  // C = -R^T t
  }
  c2w[12] = c2w[13] = c2w[14] = 0;
  c2w[15] = 1;
}

}  // namespace gs::io
