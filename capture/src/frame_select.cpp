// SPDX-License-Identifier: MIT
// Sharpness and motion statistics per frame, and the selection of sharp, well-spread frames.
#include "gs/capture/frame_select.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gs/io/box_filter.h"
#include "gs/stats.h"

namespace gs::capture {
namespace {

constexpr int32_t kSharpWidth = 320;  // sharpness is measured at most this wide
constexpr int32_t kThumbW = 32, kThumbH = 24;

float grey_of(const uint8_t* p) { return 0.299f * float(p[0]) + 0.587f * float(p[1]) + 0.114f * float(p[2]); }

// Integer box factor so the grey image is at most kSharpWidth wide; a fixed factor keeps blur
// measured at the same scale for every frame of a video.
int32_t sharp_factor(int32_t width) { return std::max<int32_t>(1, (width + kSharpWidth - 1) / kSharpWidth); }

// Mean grey of f x f blocks of RGB rows `stride` bytes apart (float sums; remainder dropped).
void box_grey(const uint8_t* rgb, int32_t width, int32_t height, int32_t stride, int32_t f, float* out, int32_t* ow,
              int32_t* oh) {
  const int32_t w = width / f, h = height / f;
  const float norm = 1.0f / float(f * f);
  io::box_filter<float>(
      width, height, f, w, h, [&](float& sum, int x, int y) { sum += grey_of(rgb + size_t(y) * size_t(stride) + size_t(x) * 3); },
      [&](size_t i, float sum) { out[i] = sum * norm; });
  *ow = w;
  *oh = h;
}

// Area-averaged kThumbW x kThumbH thumbnail of the grey image, values 0..1.
void thumbnail(const float* grey, int32_t w, int32_t h, float* thumb) {
  struct Mean {
    double sum;
    int n;
  };
  io::box_filter<Mean>(
      io::SpanAxis{w, kThumbW}, io::SpanAxis{h, kThumbH}, kThumbW, kThumbH,
      [&](Mean& m, int x, int y) { m.sum += grey[size_t(y) * size_t(w) + size_t(x)], ++m.n; },
      [&](size_t i, const Mean& m) { thumb[i] = m.n > 0 ? float(m.sum / m.n / 255.0) : 0.0f; });
}

// Stretches with no usable frame (fast motion, a blurred burst) leave the count short; top it up
// with the sharp frames farthest along the path from every kept one (still at least min_motion
// apart), so spacing stays as even as the video allows.
void fill_to_target(const std::vector<double>& along, const std::vector<bool>& sharp, size_t target,
                    double min_motion, std::vector<size_t>* kept) {
  const size_t n = along.size();
  std::vector<bool> taken(n, false);
  for (size_t k : *kept) taken[k] = true;
  while (kept->size() < target) {
    size_t best = n;
    double best_gap = -1.0;
    for (size_t i = 0; i < n; ++i) {
      if (!sharp[i] || taken[i]) continue;
      double gap = 1e300;
      for (size_t k : *kept) gap = std::min(gap, std::fabs(along[i] - along[k]));
      if (!kept->empty() && gap < min_motion) continue;
      if (gap > best_gap) {
        best_gap = gap;
        best = i;
      }
    }
    if (best == n) break;
    taken[best] = true;
    kept->push_back(best);
  }
  std::sort(kept->begin(), kept->end());
}

}  // namespace

double laplacian_variance(const float* grey, int32_t width, int32_t height) {
  if (width < 3 || height < 3) return 0.0;
  double sum = 0, sum2 = 0;
  const size_t n = size_t(width - 2) * size_t(height - 2);
  for (int32_t y = 1; y + 1 < height; ++y) {
    const float* r = grey + size_t(y) * size_t(width);
    for (int32_t x = 1; x + 1 < width; ++x) {
      const double lap = double(r[x - 1]) + double(r[x + 1]) + double(r[x - width]) + double(r[x + width]) - 4.0 * double(r[x]);
      sum += lap;
      sum2 += lap * lap;
    }
  }
  const double mean = sum / double(n);
  return std::max(0.0, sum2 / double(n) - mean * mean);
}

Expected<FrameAnalyzer> FrameAnalyzer::create(int32_t max_width, int32_t max_height) {
  if (max_width < 8 || max_height < 8)
    return invalid_argument("frame analyser: frames of " + std::to_string(max_width) + "x" + std::to_string(max_height) +
                            " are too small (at least 8x8)");
  FrameAnalyzer a;
  a.max_width_ = max_width;
  a.max_height_ = max_height;
  const int32_t f = sharp_factor(max_width);
  a.grey_.assign(size_t(max_width / f + 1) * size_t(max_height / f + 1), 0.0f);
  a.thumb_.assign(size_t(kThumbW * kThumbH), 0.0f);
  a.prev_thumb_ = a.thumb_;
  return a;
}

Expected<FrameStats> FrameAnalyzer::add(const uint8_t* rgb, int32_t width, int32_t height, int32_t rgb_stride,
                                        int64_t index, int64_t timestamp_ns) {
  if (width > max_width_ || height > max_height_ || width < 8 || height < 8 || rgb_stride < 3 * width)
    return invalid_argument("frame " + std::to_string(index) + " is " + std::to_string(width) + "x" +
                            std::to_string(height) + ", planned for at most " + std::to_string(max_width_) + "x" +
                            std::to_string(max_height_));
  int32_t w = 0, h = 0;
  box_grey(rgb, width, height, rgb_stride, sharp_factor(width), grey_.data(), &w, &h);
  FrameStats s;
  s.index = index;
  s.timestamp_ns = timestamp_ns;
  s.sharpness = laplacian_variance(grey_.data(), w, h);
  thumbnail(grey_.data(), w, h, thumb_.data());
  if (have_prev_) {
    double diff = 0;
    for (size_t i = 0; i < thumb_.size(); ++i) diff += std::fabs(double(thumb_[i]) - double(prev_thumb_[i]));
    s.motion = diff / double(thumb_.size());
  }
  std::swap(thumb_, prev_thumb_);
  have_prev_ = true;
  return s;
}

std::vector<size_t> select_frames(const std::vector<FrameStats>& stats, const SelectOptions& o, SelectReport* report) {
  const size_t n = stats.size();
  std::vector<bool> sharp(n, true);
  std::vector<double> window;
  int blurred = 0;
  for (size_t i = 0; i < n; ++i) {
    const size_t lo = i >= size_t(o.blur_window) ? i - size_t(o.blur_window) : 0;
    const size_t hi = std::min(n, i + size_t(o.blur_window) + 1);
    window.clear();
    for (size_t j = lo; j < hi; ++j) window.push_back(stats[j].sharpness);
    if (stats[i].sharpness < o.blur_ratio * upper_median_in_place(window)) {
      sharp[i] = false;
      ++blurred;
    }
  }

  // Summed motion up to each frame: the frame's position along the camera path.
  std::vector<double> along(n, 0.0);
  for (size_t i = 1; i < n; ++i) along[i] = along[i - 1] + stats[i].motion;
  const double total = n > 0 ? along[n - 1] : 0.0;
  const size_t target = size_t(std::max(1, o.target_count));

  std::vector<size_t> kept;
  if (total <= 0.0) {
    // No measurable motion (a single frame, or a still camera): spread evenly in time instead.
    for (size_t i = 0; i < n; ++i) along[i] = double(i);
  }
  const double length = total > 0.0 ? total : double(n > 0 ? n - 1 : 0);
  const double stretch = length / double(target);
  size_t i = 0;
  for (size_t s = 0; s < target && i < n; ++s) {
    const double end = s + 1 == target ? length + 1.0 : stretch * double(s + 1);
    size_t best = n;
    for (; i < n && along[i] < end; ++i) {
      if (!sharp[i]) continue;
      if (!kept.empty() && along[i] - along[kept.back()] < o.min_motion) continue;
      if (best == n || stats[i].sharpness > stats[best].sharpness) best = i;
    }
    if (best != n) kept.push_back(best);
  }
  fill_to_target(along, sharp, target, o.min_motion, &kept);
  if (report != nullptr) {
    report->total = int(n);
    report->blurred = blurred;
    report->kept = int(kept.size());
    report->total_motion = total;
  }
  return kept;
}

}  // namespace gs::capture
