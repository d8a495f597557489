// SPDX-License-Identifier: MIT
// Projection of camera-space rays through the COLMAP camera models hbgs undistorts (the pinholes,
// OpenCV's radial-tangential polynomial, and the fisheye models: OPENCV_FISHEYE, RADIAL_FISHEYE,
// SIMPLE_RADIAL_FISHEYE, FOV), written from COLMAP's documented model definitions (gs/io/colmap.h).
#include <cmath>

#include "gs/constants.h"
#include "gs/io/colmap.h"

namespace gs::io {
namespace {

// The fisheye models' parameters in one form: fx, fy, cx, cy and either the equidistant polynomial
// theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8), or FOV's omega.
struct Fisheye {
  double fx, fy, cx, cy;
  double k[4] = {0, 0, 0, 0};
  double omega = 0;
  bool fov = false;
};

bool fisheye_of(const ColmapCamera& cam, Fisheye* f) {
  const std::vector<double>& p = cam.params;
  if (cam.model == "OPENCV_FISHEYE" && p.size() == 8) {
    *f = {p[0], p[1], p[2], p[3], {p[4], p[5], p[6], p[7]}, 0, false};
  } else if (cam.model == "RADIAL_FISHEYE" && p.size() == 5) {
    *f = {p[0], p[0], p[1], p[2], {p[3], p[4], 0, 0}, 0, false};
  } else if (cam.model == "SIMPLE_RADIAL_FISHEYE" && p.size() == 4) {
    *f = {p[0], p[0], p[1], p[2], {p[3], 0, 0, 0}, 0, false};
  } else if (cam.model == "FOV" && p.size() == 5) {
    *f = {p[0], p[1], p[2], p[3], {0, 0, 0, 0}, p[4], true};
  } else {
    return false;
  }
  return true;
}

// The distorted radius of a ray at angle theta from the axis: the equidistant polynomial, or FOV's
// atan(2 tan(theta) tan(omega / 2)) / omega (tan(theta) is the pinhole radius; omega -> 0: tan(theta)).
double fisheye_radius(const Fisheye& f, double theta) {
  if (f.fov) {
    const double r_u = std::tan(theta);
    if (std::fabs(f.omega) < 1e-9) return r_u;
    return std::atan(2 * r_u * std::tan(0.5 * f.omega)) / f.omega;
  }
  const double t2 = theta * theta;
  return theta * (1 + t2 * (f.k[0] + t2 * (f.k[1] + t2 * (f.k[2] + t2 * f.k[3]))));
}

}  // namespace

bool is_fisheye_model(const std::string& model) {
  return model == "OPENCV_FISHEYE" || model == "RADIAL_FISHEYE" || model == "SIMPLE_RADIAL_FISHEYE" || model == "FOV";
}

bool colmap_project(const ColmapCamera& cam, const double ray[3], double* u, double* v) {
  const std::vector<double>& p = cam.params;
  Fisheye f;
  if (fisheye_of(cam, &f)) {
    // The angle from the optical axis (any ray of the front half-space, theta < 90 degrees).
    if (!(ray[2] > 0)) return false;
    const double rho = std::sqrt(ray[0] * ray[0] + ray[1] * ray[1]);
    const double theta = std::atan2(rho, ray[2]);
    double ux = 0, uy = 0;  // unit direction in the image plane (any at the axis: radius 0)
    if (rho > 0) ux = ray[0] / rho, uy = ray[1] / rho;
    const double r_d = fisheye_radius(f, theta);
    if (!std::isfinite(r_d)) return false;
    *u = f.fx * r_d * ux + f.cx;
    *v = f.fy * r_d * uy + f.cy;
    return true;
  }
  double fx, fy, cx, cy, k1 = 0, k2 = 0, p1 = 0, p2 = 0;
  if (cam.model == "PINHOLE" && p.size() == 4) {
    fx = p[0], fy = p[1], cx = p[2], cy = p[3];
  } else if (cam.model == "SIMPLE_PINHOLE" && p.size() == 3) {
    fx = fy = p[0], cx = p[1], cy = p[2];
  } else if (cam.model == "SIMPLE_RADIAL" && p.size() == 4) {
    fx = fy = p[0], cx = p[1], cy = p[2], k1 = p[3];
  } else if (cam.model == "RADIAL" && p.size() == 5) {
    fx = fy = p[0], cx = p[1], cy = p[2], k1 = p[3], k2 = p[4];
  } else if (cam.model == "OPENCV" && p.size() == 8) {
    fx = p[0], fy = p[1], cx = p[2], cy = p[3], k1 = p[4], k2 = p[5], p1 = p[6], p2 = p[7];
  } else {
    return false;
  }
  if (!(ray[2] > 0)) return false;
  const double x = ray[0] / ray[2], y = ray[1] / ray[2];
  const double r2 = x * x + y * y, radial = k1 * r2 + k2 * r2 * r2;
  const double xd = x + x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y + y * radial + 2 * p2 * x * y + p1 * (r2 + 2 * y * y);
  *u = fx * xd + cx;
  *v = fy * yd + cy;
  return true;
}

double fisheye_valid_angle(const ColmapCamera& cam) {
  Fisheye f;
  if (!fisheye_of(cam, &f)) return 0;
  // FOV: r_d = atan(2 tan(theta) tan(omega / 2)) / omega rises on the whole front half-space when
  // |omega| < pi (even in omega; the pinhole's tan(theta) at omega = 0).
  if (f.fov) return std::fabs(f.omega) < kPi ? 0.5 * kPi : 0;
  // The polynomial: the first angle where theta_d stops rising, sampled every 0.01 degree up to 90.
  constexpr int kSteps = 9000;
  double last = 0;
  for (int i = 1; i <= kSteps; ++i) {
    const double theta = 0.5 * kPi * i / kSteps;
    const double r = fisheye_radius(f, theta);
    if (!std::isfinite(r) || !(r > last)) return 0.5 * kPi * (i - 1) / kSteps;
    last = r;
  }
  return 0.5 * kPi;
}

}  // namespace gs::io
