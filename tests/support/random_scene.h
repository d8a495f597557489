// SPDX-License-Identifier: MIT
// Seeded random scenes for renderer tests: a pinhole view with a non-centred principal point and a
// set of Gaussians placed in (or deliberately around) its frustum. The seed is printed by callers
// on failure so any case can be replayed.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "gs/camera.h"
#include "gs/render.h"
#include "gs/render_ref.h"

namespace gs::test {

struct SceneSpec {
  int width = 40, height = 30;
  size_t count = 24;
  double min_depth = 2.0, max_depth = 6.0;
  double min_scale = 0.04, max_scale = 0.35;
  double min_opacity = 0.15, max_opacity = 0.9;
  int sh_degree = -1;        // -1: plain colours
  double frac_outside = 0;   // fraction of Gaussians placed beyond the image edge (Jacobian clamp)
};

// A dense opaque stack: early termination and (with saturate) the 0.99 alpha clamp.
inline SceneSpec opaque_stack_spec() {
  SceneSpec s;
  s.count = 40;
  s.min_opacity = 0.6;
  s.max_opacity = 1.0;
  s.min_scale = 0.2;
  s.max_scale = 0.6;
  return s;
}

// Rodrigues: rotation matrix (row-major) of axis-angle w.
template <class T>
inline void so3_exp(const T w[3], T R[9]) {
  const T th = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  const T K[9] = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};
  T K2[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) K2[i * 3 + j] = K[i * 3] * K[j] + K[i * 3 + 1] * K[3 + j] + K[i * 3 + 2] * K[6 + j];
  const T a = th < T(1e-12) ? T(1) : std::sin(th) / th;
  const T b = th < T(1e-12) ? T(0.5) : (T(1) - std::cos(th)) / (th * th);
  for (int k = 0; k < 9; ++k) R[k] = (k % 4 == 0 ? T(1) : T(0)) + a * K[k] + b * K2[k];
}

inline ref::View<double> random_view(std::mt19937_64& rng, int width, int height) {
  std::uniform_real_distribution<double> u(-1, 1);
  ref::View<double> v;
  v.width = width;
  v.height = height;
  v.fx = 1.1 * width;
  v.fy = 1.05 * width;
  v.cx = 0.5 * width + 0.13 * width * u(rng);
  v.cy = 0.5 * height + 0.11 * height * u(rng);
  const double w[3] = {0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng)};
  so3_exp(w, v.R);
  for (double& t : v.t) t = 0.5 * u(rng);
  return v;
}

// Gaussians in camera space mapped to world by the inverse of the view's pose.
inline ref::Scene<double> random_scene(std::mt19937_64& rng, const ref::View<double>& v, const SceneSpec& spec) {
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> nrm(0, 1);
  ref::Scene<double> s;
  s.n = spec.count;
  s.sh_degree = spec.sh_degree;
  for (size_t i = 0; i < spec.count; ++i) {
    const double z = spec.min_depth + (spec.max_depth - spec.min_depth) * u01(rng);
    const bool outside = u01(rng) < spec.frac_outside;
    // Pixel position: inside the image, or 1.2-1.8 half-widths from the centre (beyond the 1.3 clamp).
    double px, py;
    if (outside) {
      const double side = u01(rng) < 0.5 ? -1 : 1;
      px = v.cx + side * (0.6 + 0.3 * u01(rng)) * 2 * v.width / 2 * 1.0;
      py = v.height * u01(rng);
    } else {
      px = v.width * (0.05 + 0.9 * u01(rng));
      py = v.height * (0.05 + 0.9 * u01(rng));
    }
    const double cam[3] = {(px - v.cx) / v.fx * z, (py - v.cy) / v.fy * z, z};
    // world = R^T (cam - t)
    for (int k = 0; k < 3; ++k) {
      double acc = 0;
      for (int j = 0; j < 3; ++j) acc += v.R[j * 3 + k] * (cam[j] - v.t[j]);
      s.means.push_back(acc);
    }
    const double scale_mult = outside ? 4.0 : 1.0;  // outside ones must still reach into the image
    for (int k = 0; k < 3; ++k)
      s.log_scales.push_back(std::log(scale_mult * (spec.min_scale + (spec.max_scale - spec.min_scale) * u01(rng))));
    for (int k = 0; k < 4; ++k) s.quats.push_back(nrm(rng));
    s.opacities.push_back(spec.min_opacity + (spec.max_opacity - spec.min_opacity) * u01(rng));
    if (spec.sh_degree < 0) {
      for (int k = 0; k < 3; ++k) s.colors.push_back(u01(rng));
    } else {
      const int K = (spec.sh_degree + 1) * (spec.sh_degree + 1);
      for (int k = 0; k < K * 3; ++k) s.sh.push_back(k < 3 ? 0.8 * u01(rng) : 0.25 * nrm(rng));
    }
  }
  return s;
}

template <class To, class From>
inline std::vector<To> cast_vec(const std::vector<From>& v) {
  return std::vector<To>(v.begin(), v.end());
}

inline ref::Scene<float> to_float(const ref::Scene<double>& s) {
  ref::Scene<float> f;
  f.n = s.n;
  f.sh_degree = s.sh_degree;
  f.means = cast_vec<float>(s.means);
  f.log_scales = cast_vec<float>(s.log_scales);
  f.quats = cast_vec<float>(s.quats);
  f.opacities = cast_vec<float>(s.opacities);
  f.colors = cast_vec<float>(s.colors);
  f.sh = cast_vec<float>(s.sh);
  return f;
}

inline ref::View<float> to_float(const ref::View<double>& v) {
  ref::View<float> f;
  for (int k = 0; k < 9; ++k) f.R[k] = float(v.R[k]);
  for (int k = 0; k < 3; ++k) f.t[k] = float(v.t[k]), f.background[k] = float(v.background[k]);
  f.fx = float(v.fx); f.fy = float(v.fy); f.cx = float(v.cx); f.cy = float(v.cy);
  f.width = v.width; f.height = v.height;
  return f;
}

inline Camera to_camera(const ref::View<float>& v) {
  Camera c;
  c.intr = {v.fx, v.fy, v.cx, v.cy, v.width, v.height};
  for (int k = 0; k < 9; ++k) c.pose.R[k] = v.R[k];
  for (int k = 0; k < 3; ++k) c.pose.t[k] = v.t[k];
  return c;
}

inline GaussianParams to_params(const ref::Scene<float>& s) {
  GaussianParams p;
  p.count = s.n;
  p.means = s.means.data();
  p.log_scales = s.log_scales.data();
  p.quats = s.quats.data();
  p.opacities = s.opacities.data();
  if (s.sh_degree >= 0) {
    p.sh = s.sh.data();
    p.sh_degree = s.sh_degree;
  } else {
    p.colors = s.colors.data();
  }
  return p;
}

}  // namespace gs::test
