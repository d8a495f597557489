// SPDX-License-Identifier: MIT
// Image-based anchor features: 8-bit pyramids of the training views, best-view selection and
// bilinear colour sampling (see gs/model/image_features.h for the definition of the 13 values).
#include "gs/model/image_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
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

// How well a view sees a point at camera coordinates xc (lower is better; the reference code's rule):
// the distance from the centre, |xc|, over 200, plus 1.1 minus the cosine to the optical axis,
// xc_z / |xc|.
double view_score(const double xc[3]) {
  const double dist = std::sqrt(xc[0] * xc[0] + xc[1] * xc[1] + xc[2] * xc[2]);
  return dist / 200.0 + 1.1 - xc[2] / (dist + 1e-6);
}

}  // namespace

Status ImageFeatureBank::init(const std::vector<const Camera*>& cameras, const std::vector<const io::Image8*>& images,
                              ImageFeatureMode mode) {
  if (cameras.empty()) return invalid_argument("image features: no training views");
  mode_ = mode;
  have_depth_ = false;
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
    const double score = view_score(xc);
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

void ImageFeatureBank::set_occluders(const float* positions, size_t count, float radius, platform::ThreadPool* pool) {
  if (mode_ != ImageFeatureMode::kVisible) return;
  depth_.resize(cameras_.size());
  auto body = [&](size_t b, size_t e, int) {
    for (size_t j = b; j < e; ++j) {
      const Level& lv = levels_[j * kImagePyramidLevels + kImagePyramidLevels - 1];
      const double s = 1.0 / double(1 << (kImagePyramidLevels - 1));  // level-2 pixels per level-0 pixel
      std::vector<float>& z = depth_[j];
      z.assign(size_t(lv.width) * size_t(lv.height), std::numeric_limits<float>::infinity());
      const Camera& cam = *cameras_[j];
      for (size_t i = 0; i < count; ++i) {
        double xc[3], u, v;
        if (!project_inside(cam, positions + 3 * i, xc, &u, &v)) continue;
        const double r = std::max(0.5, double(radius) * cam.intr.fx * s / xc[2]);  // disc radius, level-2 px
        const int x0 = std::max(0, int(std::floor(u * s - r))), x1 = std::min(lv.width - 1, int(std::floor(u * s + r)));
        const int y0 = std::max(0, int(std::floor(v * s - r))), y1 = std::min(lv.height - 1, int(std::floor(v * s + r)));
        for (int y = y0; y <= y1; ++y)
          for (int x = x0; x <= x1; ++x) {
            float& d = z[size_t(y) * size_t(lv.width) + size_t(x)];
            d = std::min(d, float(xc[2]));
          }
      }
    }
  };
  if (pool)
    pool->parallel_for(cameras_.size(), 1, body);
  else
    body(0, cameras_.size(), 0);
  have_depth_ = true;
}

bool ImageFeatureBank::visible_in(size_t view, const double xc[3], double u, double v) const {
  if (!have_depth_) return true;
  const Level& lv = levels_[view * kImagePyramidLevels + kImagePyramidLevels - 1];
  const double s = 1.0 / double(1 << (kImagePyramidLevels - 1));
  const int x = std::min(lv.width - 1, int(u * s)), y = std::min(lv.height - 1, int(v * s));
  return xc[2] <= double(depth_[view][size_t(y) * size_t(lv.width) + size_t(x)]) * (1.0 + kOcclusionMargin);
}

void ImageFeatureBank::compute_one_visible(const float* p, float* raw) const {
  std::fill(raw, raw + kImageRawDim, 0.0f);
  // The kVisibleViews views with the best (lowest) score among those that see the anchor unhidden.
  int best[kVisibleViews];
  double score[kVisibleViews], uv[kVisibleViews][2];
  int n = 0;
  for (size_t j = 0; j < cameras_.size(); ++j) {
    double xc[3], u, v;
    if (!project_inside(*cameras_[j], p, xc, &u, &v) || !visible_in(j, xc, u, v)) continue;
    const double sc = view_score(xc);
    int at = n < kVisibleViews ? n++ : kVisibleViews;  // insertion into the sorted short list
    while (at > 0 && score[at - 1] > sc) {
      if (at < kVisibleViews) best[at] = best[at - 1], score[at] = score[at - 1], uv[at][0] = uv[at - 1][0], uv[at][1] = uv[at - 1][1];
      --at;
    }
    if (at < kVisibleViews) best[at] = int(j), score[at] = sc, uv[at][0] = u, uv[at][1] = v;
  }
  if (n == 0) return;
  double sum[9] = {}, sq[3] = {};
  for (int m = 0; m < n; ++m) {
    const Level* lv = &levels_[size_t(best[m]) * kImagePyramidLevels];
    for (int l = 0; l < kImagePyramidLevels; ++l) {
      const double s = 1.0 / double(1 << l);
      float c[3];
      sample_bilinear(lv[l].rgb, lv[l].width, lv[l].height, uv[m][0] * s, uv[m][1] * s, c);
      for (int k = 0; k < 3; ++k) {
        sum[3 * l + k] += c[k];
        if (l == 0) sq[k] += double(c[k]) * c[k];
      }
    }
  }
  for (int i = 0; i < 9; ++i) raw[i] = float(sum[i] / n);
  for (int k = 0; k < 3; ++k) raw[9 + k] = float(std::sqrt(std::max(0.0, sq[k] / n - (sum[k] / n) * (sum[k] / n))));
  raw[12] = 1.0f;
}

void ImageFeatureBank::compute(const float* positions, size_t count, float* raw, platform::ThreadPool* pool) const {
  auto body = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) {
      if (mode_ == ImageFeatureMode::kVisible) compute_one_visible(positions + 3 * i, raw + i * kImageRawDim);
      else compute_one(positions + 3 * i, raw + i * kImageRawDim);
    }
  };
  if (pool)
    pool->parallel_for(count, 256, body);
  else
    body(0, count, 0);
}

}  // namespace gs::model
