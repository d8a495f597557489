// SPDX-License-Identifier: MIT
// Fixtures shared by the model tests: SfM-like points on a noisy sphere, look-at cameras and raw
// file bytes (for truncating and corrupting model and checkpoint files).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "gs/camera.h"

namespace gs::test {

// n points [n, 3] on a noisy sphere of radius 2 around centre: surface-like, like SfM points.
inline std::vector<float> sphere_points(size_t n, uint32_t seed, const float centre[3] = nullptr) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<float> xyz(3 * n);
  for (size_t i = 0; i < n; ++i) {
    float v[3] = {g(rng), g(rng), g(rng)};
    const float r = 2.0f * (1.0f + 0.02f * g(rng)) / std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + 1e-12f);
    for (int c = 0; c < 3; ++c) xyz[3 * i + size_t(c)] = (centre ? centre[c] : 0.0f) + v[c] * r;
  }
  return xyz;
}

// Camera at centre C looking at `at`, y down roughly along -world y: x = z x up, y = z x x, a
// right-handed frame (x right, y down, z forward); world-to-camera pose.
inline Camera look_at(const double C[3], const double at[3], const PinholeIntrinsics& intr) {
  double z[3] = {at[0] - C[0], at[1] - C[1], at[2] - C[2]};
  const double zn = std::sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  for (double& v : z) v /= zn;
  const double up[3] = {0, -1, 0};
  double x[3] = {z[1] * up[2] - z[2] * up[1], z[2] * up[0] - z[0] * up[2], z[0] * up[1] - z[1] * up[0]};
  const double xn = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (double& v : x) v /= xn;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  Camera cam;
  cam.intr = intr;
  for (int c = 0; c < 3; ++c) {
    cam.pose.R[c] = float(x[c]);
    cam.pose.R[3 + c] = float(y[c]);
    cam.pose.R[6 + c] = float(z[c]);
  }
  for (int r = 0; r < 3; ++r)
    cam.pose.t[r] = float(-(double(cam.pose.R[3 * r]) * C[0] + double(cam.pose.R[3 * r + 1]) * C[1] +
                            double(cam.pose.R[3 * r + 2]) * C[2]));
  return cam;
}

inline std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

inline void write_bytes(const std::string& path, const std::vector<uint8_t>& b) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

}  // namespace gs::test
