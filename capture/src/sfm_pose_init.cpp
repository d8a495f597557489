// SPDX-License-Identifier: MIT
// SfM-based global pose initialisation: COLMAP reconstruction, centre Sim(3), ICP onto the dataset's
// points (see the header for why each step).
#include "gs/capture/sfm_pose_init.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <unordered_map>

#include "gs/io/colmap.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/stats.h"

namespace gs::capture {
namespace fs = std::filesystem;
namespace {

// Uniform grid over the target points for nearest-neighbour queries within a search radius.
class PointGrid {
 public:
  PointGrid(const double* pts, size_t n, double cell) : pts_(pts), cell_(cell) {
    for (size_t i = 0; i < n; ++i) cells_[key_of(pts + 3 * i)].push_back(uint32_t(i));
  }
  // Nearest target point to p within the 27 cells around it; false when none.
  bool nearest(const double p[3], size_t* index, double* dist) const {
    const int64_t cx = coord(p[0]), cy = coord(p[1]), cz = coord(p[2]);
    double best = 1e300;
    size_t best_i = 0;
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(key(cx + dx, cy + dy, cz + dz));
          if (it == cells_.end()) continue;
          for (uint32_t i : it->second) {
            const double* q = pts_ + 3 * size_t(i);
            const double d = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
            if (d < best) best = d, best_i = i;
          }
        }
    if (best == 1e300) return false;
    *index = best_i;
    *dist = std::sqrt(best);
    return true;
  }

 private:
  int64_t coord(double v) const { return int64_t(std::floor(v / cell_)); }
  static uint64_t key(int64_t x, int64_t y, int64_t z) {
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  }
  uint64_t key_of(const double* p) const { return key(coord(p[0]), coord(p[1]), coord(p[2])); }
  const double* pts_;
  double cell_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
};

// Extent of a point set: RMS distance from its mean.
double rms_spread(const double* p, size_t n) {
  double m[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) m[k] += p[3 * i + k] / double(n);
  double s = 0;
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) s += (p[3 * i + k] - m[k]) * (p[3 * i + k] - m[k]);
  return std::sqrt(s / double(std::max<size_t>(n, 1)));
}

}  // namespace

pose::Sim3 icp_sim3(const double* source, size_t ns, const double* target, size_t nt, const pose::Sim3& initial,
                    int iterations, double trim, double* median_before, double* median_after, int* pairs_out,
                    int* iterations_run) {
  pose::Sim3 T = initial;
  // Search radius: start wide (the initial frame may be off by a few % of the scene), shrink to a
  // few times the median pair distance as ICP converges; the grid cell equals the radius.
  double radius = 0.1 * rms_spread(target, nt);
  std::vector<double> moved(3 * ns), x, y, dists;
  int it = 0;
  double first_median = -1, last_median = 0;
  int pairs = 0;
  for (; it < iterations; ++it) {
    const PointGrid grid(target, nt, radius);
    for (size_t i = 0; i < ns; ++i) pose::transform_point(T, source + 3 * i, moved.data() + 3 * i);
    x.clear(), y.clear(), dists.clear();
    std::vector<size_t> match(ns, size_t(-1));
    std::vector<double> md(ns, 0);
    for (size_t i = 0; i < ns; ++i) {
      size_t j;
      double d;
      if (grid.nearest(moved.data() + 3 * i, &j, &d) && d <= radius) {
        match[i] = j, md[i] = d;
        dists.push_back(d);
      }
    }
    if (dists.size() < 10) break;
    const double med = median(dists);
    if (first_median < 0) first_median = med;
    last_median = med;
    for (size_t i = 0; i < ns; ++i)
      if (match[i] != size_t(-1) && md[i] <= trim * med) {
        x.insert(x.end(), source + 3 * i, source + 3 * i + 3);
        y.insert(y.end(), target + 3 * match[i], target + 3 * match[i] + 3);
      }
    pairs = int(x.size() / 3);
    pose::Sim3 next;
    if (!pose::fit_sim3(x.data(), y.data(), nullptr, x.size() / 3, &next)) break;
    const double change = std::fabs(next.s / T.s - 1.0) + std::fabs(next.t[0] - T.t[0]) + std::fabs(next.t[1] - T.t[1]) +
                          std::fabs(next.t[2] - T.t[2]);
    T = next;
    radius = std::max(3.0 * trim * med, 1e-9);
    if (change < 1e-9 * (1.0 + std::fabs(T.s))) {
      ++it;
      break;
    }
  }
  if (median_before != nullptr) *median_before = first_median;
  if (median_after != nullptr) *median_after = last_median;
  if (pairs_out != nullptr) *pairs_out = pairs;
  if (iterations_run != nullptr) *iterations_run = it;
  return T;
}

Status init_poses_by_sfm(const std::vector<const io::Image8*>& images, const std::vector<std::string>& names,
                         std::vector<Camera>* cams, const float* points_xyz, size_t npoints, const std::string& work_dir,
                         const SfmPoseInitOptions& o, const ProgressFn& progress, SfmPoseInitReport* report) {
  const double t0 = platform::now_seconds();
  if (images.size() != cams->size() || names.size() != cams->size() || cams->size() < 3)
    return invalid_argument("SfM pose initialisation needs at least 3 views with one image and name each");
  if (npoints < 10) return invalid_argument("SfM pose initialisation needs the dataset's SfM points (found " +
                                            std::to_string(npoints) + ")");
  SfmPoseInitReport rep;
  rep.views = int(cams->size());
  const std::string frames = work_dir + "/images";
  std::error_code ec;
  fs::remove_all(work_dir, ec);
  GS_RETURN_IF_ERROR(platform::make_dirs(frames));
  // COLMAP names images by file; index-based names keep odd dataset names out of its way.
  std::map<std::string, size_t> view_of;
  for (size_t i = 0; i < images.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "view_%05zu.png", i);
    GS_RETURN_IF_ERROR(io::write_png(frames + "/" + name, *images[i]));
    view_of[name] = i;
  }
  ColmapOptions copt = o.colmap;
  const PinholeIntrinsics& in = (*cams)[0].intr;
  copt.camera_model = "PINHOLE";
  copt.permissive_registration = true;
  char params[160];
  std::snprintf(params, sizeof params, "%.9g,%.9g,%.9g,%.9g", double(in.fx), double(in.fy), double(in.cx), double(in.cy));
  copt.camera_params = params;
  ColmapReport crep;
  std::string model_dir;
  GS_RETURN_IF_ERROR(
      run_colmap_reconstruction(frames, work_dir, work_dir + "/colmap.log", copt, progress, &crep, &model_dir));
  Expected<io::ColmapModel> model = io::read_colmap_model(model_dir);
  if (!model.ok()) return model.status();

  // Centres: reconstructed (COLMAP frame) against given (dataset frame).
  std::vector<double> c_rec, c_given;
  std::vector<std::pair<size_t, Pose>> rec_poses;
  for (const io::ColmapImage& im : model->images) {
    auto it = view_of.find(im.name);
    if (it == view_of.end()) continue;
    const Pose p = io::pose_from_colmap(im.qvec, im.tvec);
    double a[3], b[3];
    pose::centre(p, a);
    pose::centre((*cams)[it->second].pose, b);
    c_rec.insert(c_rec.end(), a, a + 3);
    c_given.insert(c_given.end(), b, b + 3);
    rec_poses.emplace_back(it->second, p);
  }
  rep.registered = int(rec_poses.size());
  rep.colmap_points = int(model->points.size());
  pose::Sim3 frame;
  if (!pose::fit_sim3(c_rec.data(), c_given.data(), nullptr, rec_poses.size(), &frame))
    return invalid_argument("SfM pose initialisation: the registered camera centres are degenerate (collinear)");
  double sq = 0;
  for (size_t i = 0; i < rec_poses.size(); ++i) {
    double m[3];
    pose::transform_point(frame, c_rec.data() + 3 * i, m);
    for (int k = 0; k < 3; ++k) sq += (m[k] - c_given[3 * i + k]) * (m[k] - c_given[3 * i + k]);
  }
  rep.centre_fit_rms = std::sqrt(sq / double(rec_poses.size()));

  std::vector<double> src, dst(3 * npoints);
  for (const io::ColmapPoint3D& p : model->points) src.insert(src.end(), p.xyz, p.xyz + 3);
  for (size_t i = 0; i < 3 * npoints; ++i) dst[i] = double(points_xyz[i]);
  if (progress) progress("      aligning COLMAP's frame to the dataset's points (ICP)");
  frame = icp_sim3(src.data(), src.size() / 3, dst.data(), npoints, frame, o.icp_iterations, o.icp_trim,
                   &rep.icp_median_before, &rep.icp_median_after, &rep.icp_pairs, &rep.icp_iterations);
  rep.frame = frame;
  for (const auto& [view, p] : rec_poses) (*cams)[view].pose = pose::transform_pose(frame, p);
  rep.seconds = platform::now_seconds() - t0;
  if (report != nullptr) *report = rep;
  return Status::Ok();
}

}  // namespace gs::capture
