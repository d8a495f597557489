// SPDX-License-Identifier: MIT
// Image-based anchor features: 8-bit pyramids of the training views, best-view selection and
// bilinear colour sampling (see gs/model/image_features.h for the definition of the 13 values).
#include "gs/model/image_features.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gs/bilinear.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/thread_pool.h"

namespace gs::model {

namespace {

// Bilinear sample at (u, v) (pixel centres at +0.5), clamped to the edge; RGB in [0, 1].
void sample_bilinear(const uint8_t* rgb, int w, int h, double u, double v, float out[3]) {
  double c[3];
  sample_bilinear_rgb(rgb, w, h, u, v, true, c);
  for (int k = 0; k < 3; ++k) out[k] = float(c[k] / 255.0);
}

}  // namespace

Status ImageFeatureBank::init(const std::vector<const Camera*>& cameras, const std::vector<const io::Image8*>& images) {
  if (cameras.empty()) return invalid_argument("image features: no training views");
  if (cameras.size() != images.size()) return invalid_argument("image features: camera and image counts differ");
  cameras_ = cameras;
  levels_.assign(cameras.size() * kImagePyramidLevels, Level{});
  storage_.assign(cameras.size() * (kImagePyramidLevels - 1), {});
  for (size_t i = 0; i < cameras.size(); ++i) {
    const io::Image8& img = *images[i];
    const PinholeIntrinsics& in = cameras[i]->intr;
    if (img.channels != 3 || img.width != in.width || img.height != in.height)
      return invalid_argument("image features: view " + std::to_string(i) + " has a " + std::to_string(img.width) + "x" +
                              std::to_string(img.height) + "x" + std::to_string(img.channels) + " image but its camera is " +
                              std::to_string(in.width) + "x" + std::to_string(in.height) + " RGB");
    Level* lv = &levels_[i * kImagePyramidLevels];
    lv[0] = {img.width, img.height, img.pixels.data()};
    for (int l = 1; l < kImagePyramidLevels; ++l) {
      const int w = std::max(1, lv[l - 1].width / 2), h = std::max(1, lv[l - 1].height / 2);
      std::vector<uint8_t>& buf = storage_[i * (kImagePyramidLevels - 1) + size_t(l - 1)];
      buf.assign(size_t(w) * size_t(h) * 3, 0);
      io::box_downsample_rgb8(lv[l - 1].rgb, lv[l - 1].width, lv[l - 1].height, 2, w, h, buf.data());
      lv[l] = {w, h, buf.data()};
    }
  }
  return Status::Ok();
}

// Projects a world point into view j: camera-frame point xc and pixel (u, v); true if z > 0.2 and
// (u, v) lies inside the image.
static bool project_inside(const Camera& cam, const float* p, double xc[3], double* u, double* v) {
  const float* R = cam.pose.R;
  for (int r = 0; r < 3; ++r)
    xc[r] = R[3 * r] * double(p[0]) + R[3 * r + 1] * double(p[1]) + R[3 * r + 2] * double(p[2]) + cam.pose.t[r];
  if (!(xc[2] > 0.2)) return false;
  *u = cam.intr.fx * xc[0] / xc[2] + cam.intr.cx;
  *v = cam.intr.fy * xc[1] / xc[2] + cam.intr.cy;
  return *u >= 0 && *u < cam.intr.width && *v >= 0 && *v < cam.intr.height;
}

int ImageFeatureBank::best_view(const float* p) const {
  int best = -1;
  double best_score = 0;
  for (size_t j = 0; j < cameras_.size(); ++j) {
    const Camera& cam = *cameras_[j];
    double xc[3], u, v;
    if (!project_inside(cam, p, xc, &u, &v)) continue;
    // Distance from the centre equals |xc|; the cosine to the optical axis is xc_z / |xc|.
    const double dist = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1] + xc[2] * xc[2]);
    const double score = dist / 200.0 + 1.1 - xc[2] / (dist + 1e-6);
    if (best < 0 || score < best_score) {
      best = int(j);
      best_score = score;
    }
  }
  return best;
}

void ImageFeatureBank::compute_one(const float* p, float* raw) const {
  std::fill(raw, raw + kImageRawDim, 0.0f);
  const int j = best_view(p);
  if (j < 0) return;
  const Camera& cam = *cameras_[size_t(j)];
  double xc[3], u = 0, v = 0;
  project_inside(cam, p, xc, &u, &v);
  const Level* lv = &levels_[size_t(j) * kImagePyramidLevels];
  for (int l = 0; l < kImagePyramidLevels; ++l) {
    // Level l pixel x covers level-0 pixels [2^l x, 2^l (x + 1)) (the box reduction drops an odd
    // last column), so continuous coordinates scale by exactly 2^-l.
    const double scale = 1.0 / double(1 << l);
    sample_bilinear(lv[l].rgb, lv[l].width, lv[l].height, u * scale, v * scale, raw + 3 * l);
  }
  const double n = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1] + xc[2] * xc[2]);
  raw[9] = float(xc[0] / n);
  raw[10] = float(xc[1] / n);
  raw[11] = float(xc[2] / n - 1.0);
  raw[12] = 1.0f;
}

void ImageFeatureBank::compute(const float* positions, size_t count, float* raw, platform::ThreadPool* pool) const {
  auto body = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) compute_one(positions + 3 * i, raw + i * kImageRawDim);
  };
  if (pool)
    pool->parallel_for(count, 256, body);
  else
    body(0, count, 0);
}

}  // namespace gs::model
