// SPDX-License-Identifier: MIT
// Random initial points for datasets without SfM points (NeRF's synthetic scenes): uniform in the
// region all (or most) cameras see. 3DGS draws 100,000 points in a fixed [-1.3, 1.3]^3 box that
// suits those scenes only; the region the cameras share fits any object capture's scale and
// keeps points out of space no training view constrains.
#include <algorithm>
#include <cmath>

#include "../io_util.h"
#include "gs/io/transforms.h"
#include "gs/random.h"

namespace gs::io {
namespace {

constexpr size_t kProbes = 65536;
// A threshold is usable when at least 1 in 500 of the cube's probes passes it (131 probes).
constexpr size_t kMinPassingProbes = kProbes / 500;

struct CameraRays {
  double R[9], t[3], centre[3], axis[3];
  double fx, fy, cx, cy, width, height;
};

CameraRays prepare(const Camera& c) {
  CameraRays r;
  for (int i = 0; i < 9; ++i) r.R[i] = c.pose.R[i];
  for (int i = 0; i < 3; ++i) r.t[i] = c.pose.t[i];
  for (int i = 0; i < 3; ++i) {
    r.centre[i] = -(r.R[i] * r.t[0] + r.R[3 + i] * r.t[1] + r.R[6 + i] * r.t[2]);  // -R^T t
    r.axis[i] = r.R[6 + i];                                                      // R^T (0, 0, 1)
  }
  r.fx = c.intr.fx, r.fy = c.intr.fy, r.cx = c.intr.cx, r.cy = c.intr.cy;
  r.width = c.intr.width, r.height = c.intr.height;
  return r;
}

bool sees(const CameraRays& c, const double X[3], double near) {
  double p[3];
  for (int i = 0; i < 3; ++i) p[i] = c.R[3 * i] * X[0] + c.R[3 * i + 1] * X[1] + c.R[3 * i + 2] * X[2] + c.t[i];
  if (!(p[2] > near)) return false;
  const double u = c.fx * p[0] / p[2] + c.cx, v = c.fy * p[1] / p[2] + c.cy;
  return u >= 0 && u < c.width && v >= 0 && v < c.height;
}

size_t seen_by(const std::vector<CameraRays>& cams, const double X[3], double near) {
  size_t n = 0;
  for (const CameraRays& c : cams) n += sees(c, X, near) ? 1 : 0;
  return n;
}

// The point nearest (least squares) to every optical axis: sum_i (I - a_i a_i^T) (x - c_i) = 0.
// Nearly parallel axes (a forward-facing capture) leave it undetermined; then the mean centre moved
// along the mean axis by the cameras' mean distance from their centroid (at least 1) stands in.
void focus_point(const std::vector<CameraRays>& cams, double focus[3]) {
  double A[9] = {}, b[3] = {}, mean_c[3] = {}, mean_a[3] = {};
  const double n = double(cams.size());
  for (const CameraRays& c : cams) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        const double m = (i == j ? 1.0 : 0.0) - c.axis[i] * c.axis[j];
        A[3 * i + j] += m / n;
        b[i] += m * c.centre[j] / n;
      }
      mean_c[i] += c.centre[i] / n;
      mean_a[i] += c.axis[i] / n;
    }
  }
  const double c00 = A[4] * A[8] - A[5] * A[7], c01 = A[5] * A[6] - A[3] * A[8], c02 = A[3] * A[7] - A[4] * A[6];
  const double det = A[0] * c00 + A[1] * c01 + A[2] * c02;
  // det of the mean projector: about the product of the axes' angular spreads squared; 1e-6 is a
  // spread of a few degrees, where the least-squares point runs off to a far, noisy place.
  if (det > 1e-6) {
    const double inv[9] = {c00, A[2] * A[7] - A[1] * A[8], A[1] * A[5] - A[2] * A[4],
                           c01, A[0] * A[8] - A[2] * A[6], A[2] * A[3] - A[0] * A[5],
                           c02, A[1] * A[6] - A[0] * A[7], A[0] * A[4] - A[1] * A[3]};
    for (int i = 0; i < 3; ++i) focus[i] = (inv[3 * i] * b[0] + inv[3 * i + 1] * b[1] + inv[3 * i + 2] * b[2]) / det;
    return;
  }
  double spread = 0;
  for (const CameraRays& c : cams)
    spread += std::sqrt((c.centre[0] - mean_c[0]) * (c.centre[0] - mean_c[0]) + (c.centre[1] - mean_c[1]) * (c.centre[1] - mean_c[1]) +
                        (c.centre[2] - mean_c[2]) * (c.centre[2] - mean_c[2])) / n;
  const double an = std::sqrt(mean_a[0] * mean_a[0] + mean_a[1] * mean_a[1] + mean_a[2] * mean_a[2]);
  for (int i = 0; i < 3; ++i) focus[i] = mean_c[i] + (an > 0 ? mean_a[i] / an : 0.0) * std::max(1.0, spread);
}

Expected<RandomPoints> draw(const std::vector<Camera>& cameras, size_t count, uint64_t seed, float near) {
  if (cameras.empty()) return invalid_argument("random points: no cameras");
  if (!(near >= 0) || !std::isfinite(near)) return invalid_argument("random points: near must be finite and >= 0");
  std::vector<CameraRays> cams;
  cams.reserve(cameras.size());
  for (const Camera& c : cameras) {
    if (c.intr.width <= 0 || c.intr.height <= 0 || !(c.intr.fx > 0) || !(c.intr.fy > 0))
      return invalid_argument("random points: a camera has no valid intrinsics");
    cams.push_back(prepare(c));
  }
  double focus[3];
  focus_point(cams, focus);
  std::vector<double> dist;
  for (const CameraRays& c : cams)
    dist.push_back(std::sqrt((c.centre[0] - focus[0]) * (c.centre[0] - focus[0]) + (c.centre[1] - focus[1]) * (c.centre[1] - focus[1]) +
                             (c.centre[2] - focus[2]) * (c.centre[2] - focus[2])));
  std::nth_element(dist.begin(), dist.begin() + long(dist.size() / 2), dist.end());
  double half = dist[dist.size() / 2];
  if (!(half > 0) || !std::isfinite(half)) half = 1.0;
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(focus[i])) return invalid_argument("random points: the cameras' focus is not finite");

  SplitMix64 rng{mix64(seed ^ 0x7a4d0e5ull)};
  // 1. Probe the cube around the focus: how many cameras see each sample.
  std::vector<double> probe(3 * kProbes);
  std::vector<size_t> seen(kProbes);
  for (size_t p = 0; p < kProbes; ++p) {
    for (int i = 0; i < 3; ++i) probe[3 * p + size_t(i)] = focus[i] + half * (2 * rng.uniform() - 1);
    seen[p] = seen_by(cams, &probe[3 * p], near);
  }
  // 2. The strictest threshold enough probes pass.
  size_t needed = 0;
  double fraction = 0;
  for (double f : {1.0, 0.9, 0.75, 0.5}) {
    const size_t k = std::max<size_t>(1, size_t(std::ceil(f * double(cams.size()) - 1e-9)));
    if (size_t(std::count_if(seen.begin(), seen.end(), [&](size_t s) { return s >= k; })) >= kMinPassingProbes) {
      needed = k, fraction = f;
      break;
    }
  }
  if (needed == 0)
    return invalid_argument("random points: the " + std::to_string(cams.size()) +
                            " cameras share no common view (not even half of them see a common region around their focus); "
                            "give the dataset a point cloud");
  // 3. The box of the passing probes, one probe spacing larger on every side, inside the cube.
  RandomPoints out;
  out.min_view_fraction = fraction;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (size_t p = 0; p < kProbes; ++p) {
    if (seen[p] < needed) continue;
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], probe[3 * p + size_t(i)]), hi[i] = std::max(hi[i], probe[3 * p + size_t(i)]);
  }
  const double spacing = 2 * half / std::cbrt(double(kProbes));
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::max(lo[i] - spacing, focus[i] - half), hi[i] = std::min(hi[i] + spacing, focus[i] + half);
    out.box_min[i] = float(lo[i]), out.box_max[i] = float(hi[i]);
  }
  // 4. Rejection sampling inside the box. The region is at least 1/500 of the cube and fills a good
  // part of its own box, so the cap on draws is only a guard.
  out.xyz.reserve(3 * count);
  const uint64_t max_draws = 1000 * uint64_t(count) + 1000000;
  for (uint64_t d = 0; out.xyz.size() < 3 * count && d < max_draws; ++d) {
    double X[3];
    for (int i = 0; i < 3; ++i) X[i] = lo[i] + (hi[i] - lo[i]) * rng.uniform();
    if (seen_by(cams, X, near) < needed) continue;
    for (int i = 0; i < 3; ++i) out.xyz.push_back(float(X[i]));
  }
  if (out.xyz.size() < 3 * count)
    return Status(StatusCode::kInternal, "random points: only " + std::to_string(out.xyz.size() / 3) + " of " +
                                             std::to_string(count) + " points found in the cameras' common view");
  out.rgb.assign(3 * count, 128);
  return out;
}

}  // namespace

Expected<RandomPoints> random_points_in_common_view(const std::vector<Camera>& cameras, size_t count, uint64_t seed,
                                                    float near) {
  return detail::guarded("random points", [&]() { return draw(cameras, count, seed, near); });
}

}  // namespace gs::io
