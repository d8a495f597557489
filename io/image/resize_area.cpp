// SPDX-License-Identifier: MIT
// Area (box-filter) resampling: every output pixel is the mean of the source area it covers,
// with fractional weights at the borders of that area, so non-integer ratios are handled and an
// integer ratio k gives exactly the rounded mean of each k x k block (gs/io/box_filter.h).
#include <array>
#include <cmath>

#include "gs/io/image.h"

namespace gs::io {
namespace {

// C channels known at compile time, so the sums stay in registers.
template <int C>
void resize_channels(const Image8& src, Image8* dst) {
  // Exact (k * k) for an integer ratio k, so ties round the same way as integer arithmetic.
  const double area = double(src.width) * double(src.height) / (double(dst->width) * double(dst->height));
  // Separable weights: each tapped source row's weighted sum, then the rows weighted.
  struct Sum {
    std::array<double, C> row, total;
  };
  const uint8_t* px = src.pixels.data();
  uint8_t* out = dst->pixels.data();
  const size_t stride = size_t(src.width) * C;
  area_filter<Sum>(
      FractionalAxis(src.width, dst->width), FractionalAxis(src.height, dst->height), dst->width, dst->height,
      [&](Sum& s, int x, int y, double wx) {
        const uint8_t* p = px + size_t(y) * stride + size_t(x) * C;
        for (int ch = 0; ch < C; ++ch) s.row[ch] += wx * p[ch];
      },
      [&](Sum& s, double wy) {
        for (int ch = 0; ch < C; ++ch) s.total[ch] += wy * s.row[ch], s.row[ch] = 0;
      },
      [&](size_t i, const Sum& s) {
        for (int ch = 0; ch < C; ++ch) {
          const double v = std::floor(s.total[ch] / area + 0.5);
          out[i * C + size_t(ch)] = uint8_t(v < 0 ? 0 : (v > 255 ? 255 : v));
        }
      });
}

}  // namespace

Image8 resize_area(const Image8& src, int width, int height) {
  const int c = src.channels;
  if (width <= 0 || height <= 0 || src.width <= 0 || src.height <= 0 || c <= 0 || c > 4 ||
      src.pixels.size() != size_t(src.width) * size_t(src.height) * size_t(c))
    return Image8{};
  if (width == src.width && height == src.height) return src;
  try {
    Image8 dst;
    dst.width = width;
    dst.height = height;
    dst.channels = c;
    dst.pixels.resize(size_t(width) * size_t(height) * size_t(c));
    if (c == 1) resize_channels<1>(src, &dst);
    else if (c == 2) resize_channels<2>(src, &dst);
    else if (c == 3) resize_channels<3>(src, &dst);
    else resize_channels<4>(src, &dst);
    return dst;
  } catch (...) {
    return Image8{};
  }
}

}  // namespace gs::io
