// SPDX-License-Identifier: MIT
// Compositing a photo on a background through its mask (gs/io/composite.h).
#include "gs/io/composite.h"

#include <cmath>

namespace gs::io {

void composite_target(const Image8& image, const Image8& mask, int s, const float background[3], float* out) {
  if (mask.empty()) {
    box_downsample_rgb(image.pixels.data(), image.width, image.height, s, out);
    return;
  }
  // Block sums of m * rgb (in 255 * 255 units) and of m (255 units): the composite is linear in
  // both, so the block mean of the composite is mean(m rgb) + background (1 - mean(m)).
  const int w = image.width, h = image.height, ow = w / s, oh = h / s;
  const double norm = 1.0 / double(s * s);
  for (int y = 0; y < oh; ++y)
    for (int x = 0; x < ow; ++x) {
      double m_sum = 0, c_sum[3] = {0, 0, 0};
      for (int dy = 0; dy < s; ++dy) {
        const size_t row = size_t(y * s + dy) * size_t(w);
        for (int dx = 0; dx < s; ++dx) {
          const size_t p = row + size_t(x * s + dx);
          const double m = mask.pixels[p];
          m_sum += m;
          for (int c = 0; c < 3; ++c) c_sum[c] += m * image.pixels[3 * p + size_t(c)];
        }
      }
      const double cover = m_sum * norm / 255.0;
      float* o = out + 3 * (size_t(y) * size_t(ow) + size_t(x));
      for (int c = 0; c < 3; ++c)
        o[c] = float(c_sum[c] * norm / (255.0 * 255.0) + double(background[c]) * (1.0 - cover));
    }
}

Image8 composite_rgb8(const Image8& image, const Image8& mask, const float background[3]) {
  if (mask.empty()) return image;
  Image8 out;
  out.width = image.width;
  out.height = image.height;
  out.channels = 3;
  out.pixels.resize(image.pixels.size());
  const size_t n = size_t(image.width) * size_t(image.height);
  for (size_t p = 0; p < n; ++p) {
    const double m = mask.pixels[p] / 255.0;
    for (int c = 0; c < 3; ++c) {
      const double v = image.pixels[3 * p + size_t(c)] * m + 255.0 * double(background[c]) * (1.0 - m);
      out.pixels[3 * p + size_t(c)] = uint8_t(std::lround(std::fmin(255.0, std::fmax(0.0, v))));
    }
  }
  return out;
}

}  // namespace gs::io
