// SPDX-License-Identifier: MIT
// Private to the COLMAP sources: the camera-model table (ids, names, parameter counts from
// COLMAP's src/colmap/sensor/models.h) and the record checks shared by the text and binary paths.
#pragma once

#include <string>

#include "gs/io/colmap.h"

namespace gs::io::detail {

struct CameraModelInfo {
  int id;
  const char* name;
  int num_params;
};

// nullptr when unknown.
const CameraModelInfo* find_camera_model(const std::string& name);
const CameraModelInfo* find_camera_model(int id);

// Largest width/height accepted for a COLMAP camera (anything bigger is a corrupt record).
constexpr int kMaxCameraSide = 100000;

// Each returns an error message (empty when fine); the caller prefixes file and record.
std::string check_camera(const ColmapCamera& cam);
std::string check_pose(const double qvec[4], const double tvec[3]);

// Unit quaternion (w >= 0, COLMAP's sign) of a row-major rotation matrix, Shepperd's method.
void quaternion_from_rotation(const double R[9], double q[4]);

// Cross-file checks: images refer to existing cameras, tracks to existing images.
Status check_model_links(const ColmapModel& model, const std::string& images_file, const std::string& points_file);

}  // namespace gs::io::detail
