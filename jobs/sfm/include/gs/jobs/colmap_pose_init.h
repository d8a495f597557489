// SPDX-License-Identifier: MIT
// The training job's SfM pose initialiser through COLMAP (gs/capture/sfm_pose_init.h): what
// `hbgs train --pose-init sfm` uses. A library of its own (hbgs::jobs_sfm) above the jobs and the
// capture library, so that the jobs library, and the on-device programs built on it, link no
// capture code. Usage:
//   gs::jobs::TrainRunOptions o;
//   o.pose_init = "sfm";
//   o.optimize_poses = true;
//   o.sfm_pose_init = &gs::jobs::colmap_pose_initializer();
#pragma once

#include "gs/jobs/train.h"

namespace gs::jobs {

// COLMAP on the training images (or a larger copy, TrainRunOptions::sfm_images: auto picks the
// dataset's largest images* folder up to 1600 px), exhaustive matching, then the reconstruction
// brought into the dataset's frame (Sim(3) on camera centres, ICP onto the SfM points). One
// instance for the program's lifetime; stateless, so any thread may use it.
const SfmPoseInitializer& colmap_pose_initializer();

}  // namespace gs::jobs
