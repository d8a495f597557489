// SPDX-License-Identifier: MIT
// Global pose initialisation by structure from motion, for training views whose given poses are
// wrong by more than a photometric method can fix (several degrees, e.g. BARF's sigma 0.15 noise):
//   1. COLMAP reconstructs the training images on its own (SIFT features, exhaustive matching,
//      mapping with the dataset's intrinsics held fixed), ignoring the given poses entirely;
//   2. its arbitrary frame is brought into the dataset's frame by a Sim(3) fitted on camera centres,
//      reconstructed against given; noise on the given centres averages out over the views;
//   3. the Sim(3) is refined by trimmed point-to-point ICP (pose::icp_sim3) between COLMAP's points
//      and the dataset's SfM points, which fixes the frame to the precision of the geometry.
// Views COLMAP could not register keep their given pose. The photometric stages (point alignment,
// joint bundle adjustment) then refine from there.
#pragma once

#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/capture/colmap_sfm.h"
#include "gs/io/image.h"
#include "gs/pose/pose.h"
#include "gs/status.h"

namespace gs::capture {

struct SfmPoseInitOptions {
  ColmapOptions colmap;        // matcher defaults to exhaustive here (photos need not be in order)
  int icp_iterations = 40;
  double icp_trim = 2.5;       // pairs farther than this x the median pair distance are dropped
};

struct SfmPoseInitReport {
  int views = 0, registered = 0;
  std::vector<uint8_t> registered_views;  // [views] 1 where COLMAP registered the view (its pose was replaced)
  // The SfM consistency check (colmap_sfm.h, ColmapOptions::check_runs) by view: 1 where it found the
  // view suspect, and the largest rotation difference between the reconstructions (degrees; 0 for
  // a view COLMAP did not register). consistency holds the rest (names are view_<index>.png).
  std::vector<uint8_t> suspect_views;
  std::vector<double> disagreement_deg;
  SfmConsistency consistency;
  int chosen_seed = 0, first_run_suspect = 0;  // ColmapReport's: the mapping used, the first one's doubts
  int colmap_points = 0;
  double centre_fit_rms = 0;   // RMS of the centre fit residuals, dataset units
  double icp_median_before = 0, icp_median_after = 0;  // median NN distance of COLMAP's points, dataset units
  int icp_pairs = 0, icp_iterations = 0;
  double seconds = 0;
  pose::Sim3 frame;            // COLMAP frame -> dataset frame
};

// images[i] is the view with camera cams[i]; names[i] its (unique) name. All views share one
// PINHOLE camera (cams[0].intr). points_xyz: the dataset's SfM points [npoints, 3]. On success the
// registered views' poses in cams are replaced. work_dir is created and kept (images, database,
// log at work_dir/colmap.log).
Status init_poses_by_sfm(const std::vector<const io::Image8*>& images, const std::vector<std::string>& names,
                         std::vector<Camera>* cams, const float* points_xyz, size_t npoints, const std::string& work_dir,
                         const SfmPoseInitOptions& options, const ProgressFn& progress, SfmPoseInitReport* report);

}  // namespace gs::capture
