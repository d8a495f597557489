// SPDX-License-Identifier: MIT
// Area (box-filter) resampling: every output pixel is the mean of the source area it covers,
// with fractional weights at the borders of that area, so non-integer ratios are handled and an
// integer ratio k gives exactly the rounded mean of each k x k block.
#include <algorithm>
#include <cmath>
#include <vector>

#include "gs/io/image.h"

namespace gs::io {
namespace {

struct Tap {
  int src;
  double weight;  // overlap length in source pixels
};

// For each of `dst` output cells, the source pixels it overlaps and by how much.
// Output cell i covers [i * s, (i + 1) * s) in source pixels, s = src / dst.
std::vector<std::vector<Tap>> axis_taps(int src, int dst) {
  std::vector<std::vector<Tap>> taps(static_cast<size_t>(dst));
  const double s = double(src) / double(dst);
  for (int i = 0; i < dst; ++i) {
    const double a = i * s, b = (i + 1) * s;
    const int first = int(std::floor(a));
    const int last = std::min(src - 1, int(std::ceil(b)) - 1);
    for (int j = first; j <= last; ++j) {
      const double w = std::min(b, double(j + 1)) - std::max(a, double(j));
      if (w > 0) taps[size_t(i)].push_back({j, w});
    }
  }
  return taps;
}

}  // namespace

Image8 resize_area(const Image8& src, int width, int height) {
  const int c = src.channels;
  if (width <= 0 || height <= 0 || src.width <= 0 || src.height <= 0 || c <= 0 ||
      src.pixels.size() != size_t(src.width) * size_t(src.height) * size_t(c))
    return Image8{};
  if (width == src.width && height == src.height) return src;
  try {
    const auto xt = axis_taps(src.width, width);
    const auto yt = axis_taps(src.height, height);
    // Exact (k * k) for an integer ratio k, so ties round the same way as integer arithmetic.
    const double area = double(src.width) * double(src.height) / (double(width) * double(height));

    Image8 dst;
    dst.width = width;
    dst.height = height;
    dst.channels = c;
    dst.pixels.resize(size_t(width) * size_t(height) * size_t(c));
    // Horizontal pass per source row on demand: row[x * c + ch] = sum over the x taps.
    std::vector<double> row(size_t(width) * size_t(c));
    std::vector<double> acc(size_t(width) * size_t(c));
    for (int y = 0; y < height; ++y) {
      std::fill(acc.begin(), acc.end(), 0.0);
      for (const Tap& ty : yt[size_t(y)]) {
        const uint8_t* s = &src.pixels[size_t(ty.src) * size_t(src.width) * size_t(c)];
        for (int x = 0; x < width; ++x) {
          for (int ch = 0; ch < c; ++ch) {
            double sum = 0;
            for (const Tap& tx : xt[size_t(x)]) sum += tx.weight * s[size_t(tx.src) * size_t(c) + size_t(ch)];
            row[size_t(x) * size_t(c) + size_t(ch)] = sum;
          }
        }
        for (size_t i = 0; i < acc.size(); ++i) acc[i] += ty.weight * row[i];
      }
      uint8_t* d = &dst.pixels[size_t(y) * size_t(width) * size_t(c)];
      for (size_t i = 0; i < acc.size(); ++i) {
        const double v = std::floor(acc[i] / area + 0.5);
        d[i] = uint8_t(v < 0 ? 0 : (v > 255 ? 255 : v));
      }
    }
    return dst;
  } catch (...) {
    return Image8{};
  }
}

}  // namespace gs::io
