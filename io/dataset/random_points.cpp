// SPDX-License-Identifier: MIT
// Initial points for datasets without SfM points (NeRF's synthetic scenes): uniform in the region
// all (or most) cameras see, or, when every view has a mask, on the surface of the visual hull the
// masks carve out of that region. 3DGS draws 100,000 points in a fixed [-1.3, 1.3]^3 box that
// suits those scenes only; the region the cameras share fits any object capture's scale and
// keeps points out of space no training view constrains.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

#include "../io_util.h"
#include "gs/constants.h"
#include "gs/io/transforms.h"
#include "gs/random.h"

namespace gs::io {
namespace {

constexpr size_t kProbes = 65536;
// A threshold is usable when at least 1 in 500 of the cube's probes passes it (131 probes).
constexpr size_t kMinPassingProbes = kProbes / 500;
// Carving: voxels along the common region's longest side, and the share of the views that see a
// voxel which may see it outside their mask (1 in kMissFraction, rounded down) before it is carved.
constexpr int kCarveResolution = 128;
constexpr size_t kMissFraction = 20;
// Photo-consistency of a carved point: the neighbouring views (within this angle) and the colour
// tolerance (8-bit levels, mean over the channels).
constexpr double kNeighbourDegrees = 45.0;
constexpr int kColourTolerance = 16;

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

// The region most cameras see (steps 1-3 of random_points_in_common_view), probed with rng.
struct CommonRegion {
  std::vector<CameraRays> cams;
  size_t needed = 0;        // cameras that must see a point of the region
  double fraction = 0;      // needed as a fraction of the cameras
  double lo[3], hi[3];      // the region's box
};

Expected<CommonRegion> common_region(const std::vector<Camera>& cameras, SplitMix64& rng, float near) {
  if (cameras.empty()) return invalid_argument("random points: no cameras");
  if (!(near >= 0) || !std::isfinite(near)) return invalid_argument("random points: near must be finite and >= 0");
  CommonRegion region;
  std::vector<CameraRays>& cams = region.cams;
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
  region.needed = needed;
  region.fraction = fraction;
  // 3. The box of the passing probes, one probe spacing larger on every side, inside the cube.
  double* lo = region.lo;
  double* hi = region.hi;
  for (int i = 0; i < 3; ++i) lo[i] = 1e300, hi[i] = -1e300;
  for (size_t p = 0; p < kProbes; ++p) {
    if (seen[p] < needed) continue;
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], probe[3 * p + size_t(i)]), hi[i] = std::max(hi[i], probe[3 * p + size_t(i)]);
  }
  const double spacing = 2 * half / std::cbrt(double(kProbes));
  for (int i = 0; i < 3; ++i) lo[i] = std::max(lo[i] - spacing, focus[i] - half), hi[i] = std::min(hi[i] + spacing, focus[i] + half);
  return region;
}

Expected<RandomPoints> draw(const std::vector<Camera>& cameras, size_t count, uint64_t seed, float near) {
  SplitMix64 rng{mix64(seed ^ 0x7a4d0e5ull)};
  Expected<CommonRegion> found = common_region(cameras, rng, near);
  if (!found.ok()) return found.status();
  const CommonRegion& region = *found;
  const std::vector<CameraRays>& cams = region.cams;
  const size_t needed = region.needed;
  const double* lo = region.lo;
  const double* hi = region.hi;
  RandomPoints out;
  out.min_view_fraction = region.fraction;
  for (int i = 0; i < 3; ++i) out.box_min[i] = float(lo[i]), out.box_max[i] = float(hi[i]);
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

// A view's mask as inside / outside flags, dilated by one pixel (3x3): a voxel whose centre
// projects next to the silhouette is kept, so the carving errs on the side of the object.
std::vector<uint8_t> dilated_inside(const Image8& mask) {
  const int w = mask.width, h = mask.height;
  std::vector<uint8_t> out(size_t(w) * size_t(h), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (mask.pixels[size_t(y) * size_t(w) + size_t(x)] < 128) continue;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int u = x + dx, v = y + dy;
          if (u >= 0 && u < w && v >= 0 && v < h) out[size_t(v) * size_t(w) + size_t(u)] = 1;
        }
    }
  return out;
}

// Pixel of X in a camera, or -1 when X is behind the near plane or outside the image.
long pixel_of(const CameraRays& c, const double X[3], double near) {
  double p[3];
  for (int i = 0; i < 3; ++i) p[i] = c.R[3 * i] * X[0] + c.R[3 * i + 1] * X[1] + c.R[3 * i + 2] * X[2] + c.t[i];
  if (!(p[2] > near)) return -1;
  const double u = c.fx * p[0] / p[2] + c.cx, v = c.fy * p[1] / p[2] + c.cy;
  if (!(u >= 0 && u < c.width && v >= 0 && v < c.height)) return -1;
  return long(v) * long(c.width) + long(u);
}

// Whether the views near view c (their cameras within kNeighbourDegrees of c's, seen from X) that
// see X inside their masks mostly see c's colour there: at least half of them, and at least two,
// within kColourTolerance (mean absolute difference over the channels, 8-bit levels). A point on
// the surface c sees passes unless most neighbours see it occluded; a point of the hull in front
// of that surface (empty space the masks cannot carve) projects onto other surfaces in other views.
bool photo_consistent(const std::vector<const DatasetView*>& views, const std::vector<CameraRays>& cams, size_t c,
                      const uint8_t colour[3], const double X[3], double near) {
  double to_c[3], nc = 0;
  for (int i = 0; i < 3; ++i) to_c[i] = cams[c].centre[i] - X[i], nc += to_c[i] * to_c[i];
  nc = std::sqrt(nc);
  const double min_cos = std::cos(kNeighbourDegrees * kPi / 180.0);
  size_t near_views = 0, agree = 0;
  for (size_t j = 0; j < cams.size(); ++j) {
    if (j == c) continue;
    double to_j[3], nj = 0, dot = 0;
    for (int i = 0; i < 3; ++i) to_j[i] = cams[j].centre[i] - X[i], nj += to_j[i] * to_j[i], dot += to_j[i] * to_c[i];
    if (!(dot >= min_cos * nc * std::sqrt(nj))) continue;
    const long px = pixel_of(cams[j], X, near);
    if (px < 0 || views[j]->mask.pixels[size_t(px)] < 128) continue;
    ++near_views;
    const uint8_t* q = &views[j]->image.pixels[3 * size_t(px)];
    const int diff = std::abs(int(q[0]) - int(colour[0])) + std::abs(int(q[1]) - int(colour[1])) + std::abs(int(q[2]) - int(colour[2]));
    agree += diff <= 3 * kColourTolerance ? 1 : 0;
  }
  return agree >= 2 && 2 * agree >= near_views;
}

Expected<CarvedPoints> carve(const std::vector<const DatasetView*>& views, size_t count, uint64_t seed, float near) {
  if (views.empty()) return invalid_argument("carved points: no views");
  if (count == 0) return invalid_argument("carved points: count must be at least 1");
  std::vector<Camera> cameras;
  std::vector<std::vector<uint8_t>> inside;
  for (const DatasetView* v : views) {
    const Image8& m = v->mask;
    if (m.empty() || m.channels != 1 || m.width != v->camera.intr.width || m.height != v->camera.intr.height)
      return invalid_argument("carved points: view '" + v->name + "' has no mask of its camera's size");
    if (v->image.empty() || v->image.channels != 3 || v->image.width != m.width || v->image.height != m.height)
      return invalid_argument("carved points: view '" + v->name + "' has no RGB image of its mask's size");
    cameras.push_back(v->camera);
    inside.push_back(dilated_inside(m));
  }
  SplitMix64 rng{mix64(seed ^ 0xc4a7ed5ull)};
  Expected<CommonRegion> found = common_region(cameras, rng, near);
  if (!found.ok()) return Status(found.status().code(), "carved points: " + found.status().message());
  const CommonRegion& region = *found;
  const std::vector<CameraRays>& cams = region.cams;
  // The grid: cubic voxels, kCarveResolution along the region box's longest side.
  double longest = 0;
  for (int i = 0; i < 3; ++i) longest = std::max(longest, region.hi[i] - region.lo[i]);
  const double voxel = longest / kCarveResolution;
  if (!(voxel > 0) || !std::isfinite(voxel)) return invalid_argument("carved points: the cameras' common region is empty");
  int n[3];
  for (int i = 0; i < 3; ++i) n[i] = std::max(1, std::min(kCarveResolution, int(std::ceil((region.hi[i] - region.lo[i]) / voxel))));
  const size_t cells = size_t(n[0]) * size_t(n[1]) * size_t(n[2]);
  // A voxel is kept when enough cameras see it (as for the random points) and at most 1 in 20 of
  // them, rounded down, sees it outside its mask (a tolerance for masks that miss a thin part).
  std::vector<uint8_t> kept(cells, 0);
  const size_t max_misses_any = cams.size() / kMissFraction;
  for (int z = 0; z < n[2]; ++z)
    for (int y = 0; y < n[1]; ++y)
      for (int x = 0; x < n[0]; ++x) {
        const double X[3] = {region.lo[0] + (x + 0.5) * voxel, region.lo[1] + (y + 0.5) * voxel, region.lo[2] + (z + 0.5) * voxel};
        size_t seen = 0, misses = 0;
        for (size_t c = 0; c < cams.size() && misses <= max_misses_any; ++c) {
          const long px = pixel_of(cams[c], X, near);
          if (px < 0) continue;
          ++seen;
          misses += inside[c][size_t(px)] ? 0 : 1;
        }
        kept[(size_t(z) * size_t(n[1]) + size_t(y)) * size_t(n[0]) + size_t(x)] =
            seen >= region.needed && misses <= seen / kMissFraction ? 1 : 0;
      }
  auto kept_at = [&](const double X[3]) {
    size_t cell = 0;
    for (int i = 2; i >= 0; --i) {
      const double g = std::floor((X[i] - region.lo[i]) / voxel);
      if (!(g >= 0 && g < n[i])) return false;
      cell = cell * size_t(n[i]) + size_t(g);
    }
    return kept[cell] != 0;
  };
  std::vector<std::vector<uint32_t>> mask_pixels(views.size());
  size_t hull_voxels = size_t(std::count(kept.begin(), kept.end(), uint8_t(1)));
  for (size_t c = 0; c < views.size(); ++c)
    for (size_t px = 0; px < views[c]->mask.pixels.size(); ++px)
      if (views[c]->mask.pixels[px] >= 128) mask_pixels[c].push_back(uint32_t(px));
  if (hull_voxels == 0)
    return invalid_argument("carved points: the masks of the " + std::to_string(views.size()) +
                            " views leave nothing of the region the cameras share (do the masks cover the subject?)");
  CarvedPoints out;
  out.voxel = voxel;
  out.hull_voxels = hull_voxels;
  for (int i = 0; i < 3; ++i) out.grid[i] = n[i], out.box_min[i] = float(region.lo[i]), out.box_max[i] = float(region.hi[i]);
  out.xyz.reserve(3 * count);
  out.rgb.reserve(3 * count);
  // Each point: a random training view, a random point of a random pixel inside its mask, and the
  // ray from the camera through it marched in half-voxel steps (from a random phase) to where it
  // first enters the hull: the part of the hull the views see, coloured by that pixel.
  const uint64_t max_rays = 100 * uint64_t(count) + 1000;
  for (uint64_t ray = 0; out.xyz.size() < 3 * count && ray < max_rays; ++ray) {
    const size_t c = size_t(rng.next() % views.size());
    if (mask_pixels[c].empty()) continue;
    const uint32_t px = mask_pixels[c][size_t(rng.next() % mask_pixels[c].size())];
    const CameraRays& cam = cams[c];
    const uint32_t w = uint32_t(cam.width);
    const double u = double(px % w) + rng.uniform(), v = double(px / w) + rng.uniform();
    const double dc[3] = {(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0};
    double d[3];
    for (int i = 0; i < 3; ++i) d[i] = cam.R[i] * dc[0] + cam.R[3 + i] * dc[1] + cam.R[6 + i] * dc[2];  // R^T dc
    // The ray's stretch inside the region's box (slab test), beyond the near plane.
    double t0 = near, t1 = 1e300;
    for (int i = 0; i < 3 && t1 > t0; ++i) {
      if (std::fabs(d[i]) < 1e-12) {
        if (cam.centre[i] < region.lo[i] || cam.centre[i] > region.hi[i]) t1 = -1;
        continue;
      }
      double a = (region.lo[i] - cam.centre[i]) / d[i], b = (region.hi[i] - cam.centre[i]) / d[i];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a), t1 = std::min(t1, b);
    }
    const double step = 0.5 * voxel / std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const uint8_t* colour = &views[c]->image.pixels[3 * size_t(px)];
    // Along the ray inside the hull, the first depth whose colour the neighbouring views agree
    // with (photo-consistency); when none does, where the ray enters the hull.
    double entry = -1, found = -1;
    for (double t = t0 + step * rng.uniform(); t < t1; t += step) {
      const double X[3] = {cam.centre[0] + t * d[0], cam.centre[1] + t * d[1], cam.centre[2] + t * d[2]};
      if (!kept_at(X)) {
        if (entry >= 0) break;  // left the hull
        continue;
      }
      if (entry < 0) entry = t;
      if (photo_consistent(views, cams, c, colour, X, near)) {
        found = t;
        break;
      }
    }
    if (entry < 0) continue;
    const double t = found >= 0 ? found : entry;
    out.consistent += found >= 0 ? 1 : 0;
    for (int i = 0; i < 3; ++i) out.xyz.push_back(float(cam.centre[i] + t * d[i]));
    for (int ch = 0; ch < 3; ++ch) out.rgb.push_back(colour[ch]);
  }
  if (out.xyz.size() < 3 * count)
    return Status(StatusCode::kInternal, "carved points: only " + std::to_string(out.xyz.size() / 3) + " of " +
                                             std::to_string(count) + " rays through the masks met the hull");
  return out;
}

}  // namespace

Expected<CarvedPoints> carve_points_from_masks(const std::vector<const DatasetView*>& views, size_t count, uint64_t seed,
                                               float near) {
  return detail::guarded("carved points", [&]() { return carve(views, count, seed, near); });
}

Expected<RandomPoints> random_points_in_common_view(const std::vector<Camera>& cameras, size_t count, uint64_t seed,
                                                    float near) {
  return detail::guarded("random points", [&]() { return draw(cameras, count, seed, near); });
}

}  // namespace gs::io
