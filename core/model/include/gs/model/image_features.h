// SPDX-License-Identifier: MIT
// Image-based anchor features (ALGORITHM.md Part A item 3): for each anchor, the training view that
// sees it best, its colour at three pyramid levels around the projection and the deviation of the
// viewing ray from that camera's optical axis. The result is the raw input of the learned MLP F.
//
// Memory: the pyramid (levels 1 and 2, 8-bit) is built once per training view at set-up; refresh()
// allocates nothing, so it may run inside the training loop.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::model {

class ImageFeatureBank {
 public:
  // views: the training views' cameras and 8-bit RGB images (not owned; level 0 is read from them,
  // so they must outlive the bank). Errors: no views, an image whose size differs from its camera.
  Status init(const std::vector<const Camera*>& cameras, const std::vector<const io::Image8*>& images);

  // Recomputes raw features [count, kImageRawDim] for anchors at positions [count, 3] using the
  // current cameras (poses may have moved since init; the pointers given to init are re-read).
  void compute(const float* positions, size_t count, float* raw, platform::ThreadPool* pool) const;

  // The chosen view of one anchor, or -1 when no training view sees it (in front, z > 0.2, inside).
  int best_view(const float* position) const;
  size_t view_count() const { return cameras_.size(); }

 private:
  struct Level {
    int width = 0, height = 0;
    const uint8_t* rgb = nullptr;  // level 0 points into the caller's image
  };
  void compute_one(const float* position, float* raw) const;
  std::vector<const Camera*> cameras_;
  std::vector<Level> levels_;            // [view, level]
  std::vector<std::vector<uint8_t>> storage_;  // levels 1.. per view
};

}  // namespace gs::model
