// SPDX-License-Identifier: MIT
// Cameras from text and from a dataset's shared camera (camera_input.h).
#include "camera_input.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <sstream>
#include <vector>

namespace gs::jobs {

void pose_text_numbers(const std::string& text, double q[4], double t[3]) {
  std::string spaced = text;
  std::replace(spaced.begin(), spaced.end(), ',', ' ');
  std::istringstream in(spaced);
  double v[7] = {1, 0, 0, 0, 0, 0, 0};
  for (double& x : v) in >> x;
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
  for (int i = 0; i < 4; ++i) q[i] = v[i] / n;
  for (int i = 0; i < 3; ++i) t[i] = v[4 + i];
}

Status parse_intrinsics_text(const std::string& text, const std::string& flag, PinholeIntrinsics* K) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream in(s);
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    size_t used = 0;
    double x = 0;
    try {
      x = std::stod(tok, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != tok.size() || !std::isfinite(x))
      return invalid_argument(flag + ": '" + tok + "' is not a finite number (expected \"fx fy cx cy\")");
    v.push_back(x);
  }
  if (v.size() != 4)
    return invalid_argument(flag + ": expected 4 numbers \"fx fy cx cy\", got " + std::to_string(v.size()));
  if (!(v[0] > 0) || !(v[1] > 0)) return invalid_argument(flag + ": fx and fy must be positive");
  K->fx = float(v[0]), K->fy = float(v[1]), K->cx = float(v[2]), K->cy = float(v[3]);
  return Status::Ok();
}

Status shared_dataset_camera(const io::DatasetFiles& files, const std::string& dataset, const std::string& hint,
                             io::ColmapCamera* camera, std::string* note) {
  const io::DatasetFileView* first = nullptr;
  for (const io::DatasetFileView& v : files.views) {
    if (!first) {
      first = &v;
    } else if (v.camera.width != first->camera.width || v.camera.height != first->camera.height ||
               v.camera.params != first->camera.params) {
      return invalid_argument(dataset + ": the views do not share one camera (" + first->name + " and " + v.name +
                              " differ); " + hint);
    }
  }
  if (!first) return invalid_argument(dataset + ": no views, so no camera; " + hint);
  *camera = first->camera;
  if (camera->model != "PINHOLE" && note)
    *note = "the dataset's camera has lens distortion (" + camera->model + " terms); the image is used as a pinhole image";
  return Status::Ok();
}

bool is_uniform_scale(const io::ColmapCamera& camera, int width, int height) {
  if (width == camera.width && height == camera.height) return true;
  const double sx = double(width) / camera.width, sy = double(height) / camera.height;
  const long h_loader = std::max(1L, std::lround(double(camera.height) * width / camera.width));
  return h_loader == height || std::fabs(sx / sy - 1) <= 1e-3;
}

PinholeIntrinsics scaled_intrinsics(const io::ColmapCamera& camera, int width, int height) {
  const double sx = double(width) / camera.width, sy = double(height) / camera.height;
  PinholeIntrinsics K;
  K.fx = float(camera.params[0] * sx), K.cx = float(camera.params[2] * sx);
  K.fy = float(camera.params[1] * sy), K.cy = float(camera.params[3] * sy);
  K.width = width, K.height = height;
  return K;
}

}  // namespace gs::jobs
