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
  struct Sum {
    double m, c[3];
  };
  const int w = image.width, h = image.height;
  const double norm = 1.0 / double(s * s);
  box_filter<Sum>(
      w, h, s, w / s, h / s,
      [&](Sum& sum, int x, int y) {
        const size_t p = size_t(y) * size_t(w) + size_t(x);
        const double m = mask.pixels[p];
        sum.m += m;
        for (int c = 0; c < 3; ++c) sum.c[c] += m * image.pixels[3 * p + size_t(c)];
      },
      [&](size_t i, const Sum& sum) {
        const double cover = sum.m * norm / 255.0;
        for (int c = 0; c < 3; ++c)
          out[3 * i + size_t(c)] = float(sum.c[c] * norm / (255.0 * 255.0) + double(background[c]) * (1.0 - cover));
      });
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
