// SPDX-License-Identifier: MIT
// `hbgs train --pose-init sfm`: the training job's SfM pose initialiser (gs/jobs/train.h
// SfmPoseInitializer) through gs_capture's COLMAP driver. It lives in the program, not in gs_jobs,
// so that the jobs library and the on-device programs built on it link no capture code; hbgs passes
// it in TrainRunOptions::sfm_pose_init, hbgs-device is built without this file.
#pragma once

#include "gs/jobs/train.h"

namespace hbgs::cli {

// COLMAP on the training images (or a larger copy, TrainRunOptions::sfm_images: auto picks the
// dataset's largest images* folder up to 1600 px), exhaustive matching, then the reconstruction
// brought into the dataset's frame (Sim(3) on camera centres, ICP onto the SfM points). One
// instance for the program's lifetime; stateless, so any thread may use it.
const gs::jobs::SfmPoseInitializer& colmap_pose_initializer();

}  // namespace hbgs::cli
