// SPDX-License-Identifier: MIT
// Private to the photometric pose solvers (built into gs_model): what they share (registration's
// keyframe and renderer Levenberg-Marquardt, the point alignment of training poses): bilinear
// colour sampling with derivatives, the projection's twist Jacobian, Huber weights and the damped, trust-region-limited
// 6-DoF step.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "gs/bilinear.h"

namespace gs::pose::detail {

// RGB float image [h, w, 3] view.
struct RgbView {
  const float* rgb = nullptr;
  int w = 0, h = 0;
};

// Bilinear colour c and its derivatives cu, cv w.r.t. the continuous pixel position (u, v), pixel
// centres at i + 0.5. False when the 2 x 2 neighbourhood leaves the image (gs/bilinear.h).
inline bool sample_bilinear(const RgbView& im, double u, double v, double c[3], double cu[3], double cv[3]) {
  return sample_bilinear_rgb(im.rgb, im.w, im.h, u, v, false, c, cu, cv);
}

// d(u, v) / d(left twist) of the projection of camera-space point m through (fx, fy):
// du = fx / z [1, 0, -x / z] dm, dv = fy / z [0, 1, -y / z] dm, dm/dxi = [I | -[m]x].
inline void projection_twist_jacobian(const double m[3], double fx, double fy, double du[6], double dv[6]) {
  const double iz = 1.0 / m[2];
  const double du_dm[3] = {fx * iz, 0, -fx * m[0] * iz * iz};
  const double dv_dm[3] = {0, fy * iz, -fy * m[1] * iz * iz};
  const double dm[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, -m[2], m[1]}, {m[2], 0, -m[0]}, {-m[1], m[0], 0}};
  for (int j = 0; j < 6; ++j) {
    du[j] = du_dm[0] * dm[j][0] + du_dm[1] * dm[j][1] + du_dm[2] * dm[j][2];
    dv[j] = dv_dm[0] * dm[j][0] + dv_dm[1] * dm[j][1] + dv_dm[2] * dm[j][2];
  }
}

// Huber cost and IRLS weight of a residual norm r.
inline double huber_cost(double r, double delta) { return r <= delta ? 0.5 * r * r : delta * (r - 0.5 * delta); }
inline double huber_weight(double r, double delta) { return r <= delta ? 1.0 : delta / r; }

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

// The Levenberg-Marquardt step xi = -(A + lambda diag(A) + eps I)^-1 b for normal equations A, b
// (b = J^T W r), with non-finite entries zeroed, scaled down so the rotation is at most max_rot
// radians and the translation at most max_trans (a trust region: a flat or blurred cost cannot
// send the pose far in one jump). No allocation.
inline void damped_step(const Mat6& A, const Vec6& b, double lambda, double max_rot, double max_trans, double xi[6]) {
  Mat6 Ad = A;
  const double eps = 1e-12 * (A.trace() + 1e-30);
  for (int d = 0; d < 6; ++d) Ad(d, d) += lambda * A(d, d) + eps;
  const Vec6 x = Ad.ldlt().solve(-b);
  for (int d = 0; d < 6; ++d) xi[d] = std::isfinite(x(d)) ? x(d) : 0.0;
  const double r = std::sqrt(xi[3] * xi[3] + xi[4] * xi[4] + xi[5] * xi[5]);
  const double t = std::sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
  const double shrink = std::min({1.0, max_rot / std::max(r, 1e-30), max_trans / std::max(t, 1e-30)});
  for (int d = 0; d < 6; ++d) xi[d] *= shrink;
}

}  // namespace gs::pose::detail
