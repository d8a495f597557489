// SPDX-License-Identifier: MIT
// TUM RGB-D trajectory files (gs/io/tum.h): write and read "timestamp tx ty tz qx qy qz qw".
#include "gs/io/tum.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "../io_util.h"
#include "gs/io/colmap.h"
#include "gs/platform/file.h"
#include "gs/pose/pose.h"

namespace gs::io {

std::string tum_line(const TimedPose& p, const SceneFrame& frame) {
  double q[4], t[3];  // world-to-camera (w, x, y, z) and translation, in the user's frame
  pose_to_colmap(frame, p.pose, q, t);
  double R[9];
  pose::rotation_from_quaternion(q, R);
  double c[3];  // the centre -R^T t
  for (int i = 0; i < 3; ++i) c[i] = 0.0 - (R[i] * t[0] + R[3 + i] * t[1] + R[6 + i] * t[2]);  // 0 - 0: "+0", not "-0"
  // Camera-to-world rotation = the conjugate; its scalar kept >= 0.
  const double s = q[0] < 0 ? -1.0 : 1.0;
  const double x = 0.0 - s * q[1], y = 0.0 - s * q[2], z = 0.0 - s * q[3];  // 0 - 0 is +0, not "-0"
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g", p.time, c[0], c[1], c[2], x, y, z, s * q[0]);
  return buf;
}

Status write_tum_trajectory(const std::vector<TimedPose>& poses, const std::string& path, const SceneFrame& frame) {
  return detail::guarded("writing " + path, [&]() -> Status {
    std::string s = "# timestamp tx ty tz qx qy qz qw (camera centre and camera-to-world rotation; hbgs)\n";
    for (const TimedPose& p : poses) s += tum_line(p, frame) + "\n";
    return platform::write_file_atomic(path, s);
  });
}

Expected<std::vector<TimedPose>> parse_tum_trajectory(const std::string& text, const std::string& source) {
  return detail::guarded("reading " + source, [&]() -> Expected<std::vector<TimedPose>> {
    std::vector<TimedPose> out;
    size_t pos = 0;
    for (int line = 1; pos <= text.size(); ++line) {
      size_t end = text.find('\n', pos);
      if (end == std::string::npos) end = text.size();
      std::string l = text.substr(pos, end - pos);
      pos = end + 1;
      if (!l.empty() && l.back() == '\r') l.pop_back();
      const size_t first = l.find_first_not_of(" \t");
      if (first == std::string::npos || l[first] == '#') continue;
      double v[8];
      const char* p = l.c_str() + first;
      int n = 0;
      for (;; ++n) {
        while (*p == ' ' || *p == '\t') ++p;
        if (!*p) break;
        if (n == 8)
          return parse_error(source + ":" + std::to_string(line) + ": expected 8 numbers (timestamp tx ty tz qx qy qz qw), found more");
        char* e = nullptr;
        v[n] = std::strtod(p, &e);
        if (e == p || (*e && *e != ' ' && *e != '\t'))
          return parse_error(source + ":" + std::to_string(line) + ": expected a number, found \"" + std::string(p).substr(0, 20) + "\"");
        p = e;
      }
      if (n != 8)
        return parse_error(source + ":" + std::to_string(line) + ": expected 8 numbers (timestamp tx ty tz qx qy qz qw), found " +
                           std::to_string(n));
      for (int i = 0; i < 8; ++i)
        if (!std::isfinite(v[i])) return parse_error(source + ":" + std::to_string(line) + ": value " + std::to_string(i + 1) + " is not finite");
      const double norm = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
      if (!(norm >= 0.5 && norm <= 2))
        return parse_error(source + ":" + std::to_string(line) + ": quaternion norm " + std::to_string(norm) + " is not close to 1");
      // World-to-camera: q = conjugate of the camera-to-world rotation, t = -R c.
      const double q[4] = {v[7] / norm, -v[4] / norm, -v[5] / norm, -v[6] / norm};
      double R[9];
      pose::rotation_from_quaternion(q, R);
      double t[3];
      for (int i = 0; i < 3; ++i) t[i] = -(R[3 * i] * v[1] + R[3 * i + 1] * v[2] + R[3 * i + 2] * v[3]);
      TimedPose tp;
      tp.time = v[0];
      tp.pose = pose_from_colmap(q, t);
      out.push_back(tp);
    }
    return out;
  });
}

Expected<std::vector<TimedPose>> read_tum_trajectory(const std::string& path) {
  Expected<std::vector<uint8_t>> bytes = platform::read_file(path);
  if (!bytes.ok()) return bytes.status();
  return parse_tum_trajectory(std::string(bytes->begin(), bytes->end()), path);
}

}  // namespace gs::io
