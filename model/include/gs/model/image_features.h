// SPDX-License-Identifier: MIT
// Image-based anchor features (ALGORITHM.md Part A item 3), the raw input of the learned MLP F, in
// two designs (gs/model/hybrid_model.h ImageFeatureMode):
//   paper:   the training view that sees the anchor best (the reference code's score), its colour at
//            three pyramid levels around the projection and the deviation of the viewing ray from
//            that camera's optical axis, plus a valid flag (13 values).
//   visible: the same colours averaged over the (up to kVisibleViews) best views in which the anchor
//            is not hidden by another anchor, the spread of the level-0 colour across those views
//            (a view-dependence hint), plus the flag. The best view of the paper's rule often
//            looks at the anchor through whatever stands in front of it (its score ignores
//            occlusion), and one view's colour carries that view's highlights; a per-view depth
//            buffer of all anchors (set_occluders) removes the first, the mean the second.
//
// Memory: the pyramid (levels 1 and 2, 8-bit) is built once per training view at set-up, and for
// visible a depth buffer per view at level 2 (float); compute() allocates nothing, so it may run
// inside the training loop; set_occluders() does not allocate after the first call either.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::model {

// visible mode: views averaged per anchor, and the relative depth margin within which another
// anchor does not hide it (anchors on one surface lie at about the same depth).
constexpr int kVisibleViews = 4;
constexpr double kOcclusionMargin = 0.05;

class ImageFeatureBank {
 public:
  // views: the training views' cameras and 8-bit RGB images (not owned; level 0 is read from them,
  // so they must outlive the bank). Errors: no views, an image whose size differs from its camera.
  Status init(const std::vector<const Camera*>& cameras, const std::vector<const io::Image8*>& images,
              ImageFeatureMode mode = ImageFeatureMode::kPaper);

  // visible mode: rebuilds the per-view depth buffers from every anchor (positions [count, 3]),
  // each splatted as a disc of radius `radius` world units at its depth; later compute() calls
  // test visibility against them (new anchors of a growth step against the last buffers). Does
  // nothing in paper mode.
  void set_occluders(const float* positions, size_t count, float radius, platform::ThreadPool* pool);

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
  void compute_one_visible(const float* position, float* raw) const;
  bool visible_in(size_t view, const double xc[3], double u, double v) const;
  ImageFeatureMode mode_ = ImageFeatureMode::kPaper;
  std::vector<const Camera*> cameras_;
  std::vector<std::vector<float>> depth_;  // [view][level-2 pixels] nearest anchor depth (visible mode)
  bool have_depth_ = false;
  std::vector<Level> levels_;            // [view, level]
  std::vector<std::vector<uint8_t>> storage_;  // levels 1.. per view
};

}  // namespace gs::model
