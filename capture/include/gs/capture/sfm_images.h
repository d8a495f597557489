// SPDX-License-Identifier: MIT
// Which images `hbgs train --pose-init sfm` gives COLMAP: the training images as loaded, or the
// same photos at a higher resolution when the dataset keeps a larger copy (images_800/ and the
// like). SIFT on more pixels places the cameras better: snowmiku_plush's 84 training views came
// within 0.127 deg mean from its 786x586 copies against 0.25 deg from the 393x293 training images.
#pragma once

#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/colmap.h"
#include "gs/status.h"

namespace gs::capture {

struct SfmImages {
  std::string folder;             // where they came from ("" = the training images as loaded)
  std::vector<io::Image8> images; // [views] when folder is set, else empty
  std::vector<Camera> cameras;    // [views]: the views' cameras with intrinsics at the images' size
  std::string note;               // auto only: why a larger folder was passed over, if one was
};

// Checks that an explicit folder exists, without reading it (for validation before any work).
Status check_sfm_images_choice(const std::string& dataset, const std::string& choice);

// choice: "train" (the loaded images), "auto" (the largest images* folder of the dataset, at most
// max_size px on the long side, that holds every view at a larger size with the same aspect; else
// the loaded images), or a folder (inside the dataset, or a path) that must hold every view.
// Errors (explicit folder only): missing file, an image whose size is not the view's scaled
// uniformly (within a pixel).
Expected<SfmImages> choose_sfm_images(const std::string& dataset, const std::string& choice,
                                      const std::vector<const io::DatasetView*>& views, int max_size);

}  // namespace gs::capture
