// SPDX-License-Identifier: MIT
// SfM-based global pose initialisation: COLMAP reconstruction, centre Sim(3), ICP onto the dataset's
// points (see the header for why each step).
#include "gs/capture/sfm_pose_init.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include "gs/io/colmap.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"

namespace gs::capture {
namespace fs = std::filesystem;

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
  rep.registered_views.assign(cams->size(), 0);
  for (const auto& rp : rec_poses) rep.registered_views[rp.first] = 1;
  rep.consistency = crep.consistency;
  rep.chosen_seed = crep.chosen_seed;
  rep.first_run_suspect = crep.first_run_suspect;
  rep.suspect_views.assign(cams->size(), 0);
  rep.disagreement_deg.assign(cams->size(), 0.0);
  for (const ViewAgreement& v : crep.consistency.views) {
    auto it = view_of.find(v.name);
    if (it == view_of.end()) continue;
    rep.suspect_views[it->second] = v.suspect;
    rep.disagreement_deg[it->second] = v.rotation_deg;
  }
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
  frame = pose::icp_sim3(src.data(), src.size() / 3, dst.data(), npoints, frame, o.icp_iterations, o.icp_trim,
                   &rep.icp_median_before, &rep.icp_median_after, &rep.icp_pairs, &rep.icp_iterations);
  rep.frame = frame;
  for (const auto& [view, p] : rec_poses) (*cams)[view].pose = pose::transform_pose(frame, p);
  rep.seconds = platform::now_seconds() - t0;
  if (report != nullptr) *report = rep;
  return Status::Ok();
}

}  // namespace gs::capture
