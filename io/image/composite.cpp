// SPDX-License-Identifier: MIT
// Compositing a photo on a background through its mask (gs/io/composite.h).
#include "gs/io/composite.h"

#include <algorithm>
#include <cmath>

#include "gs/platform/thread_pool.h"

namespace gs::io {

namespace {

// Output rows [y0, y1) of composite_target: the image from source row y0 s on, as its own image.
void composite_rows(const Image8& image, const Image8& mask, int s, const float background[3], int y0, int y1,
                    float* out) {
  const int w = image.width, h = image.height, out_w = w / s;
  const size_t first = size_t(y0) * size_t(s) * size_t(w);  // the band's first source pixel
  float* band_out = out + size_t(y0) * size_t(out_w) * 3;
  if (mask.empty()) {
    box_downsample_rgb(image.pixels.data() + 3 * first, w, (y1 - y0) * s, s, band_out);
    return;
  }
  // Block sums of m * rgb (in 255 * 255 units) and of m (255 units): the composite is linear in
  // both, so the block mean of the composite is mean(m rgb) + background (1 - mean(m)).
  struct Sum {
    double m, c[3];
  };
  const uint8_t* rgb = image.pixels.data() + 3 * first;
  const uint8_t* m8 = mask.pixels.data() + first;
  const double norm = 1.0 / double(s * s);
  box_filter<Sum>(
      w, h - y0 * s, s, out_w, y1 - y0,
      [&](Sum& sum, int x, int y) {
        const size_t p = size_t(y) * size_t(w) + size_t(x);
        const double m = m8[p];
        sum.m += m;
        for (int c = 0; c < 3; ++c) sum.c[c] += m * rgb[3 * p + size_t(c)];
      },
      [&](size_t i, const Sum& sum) {
        const double cover = sum.m * norm / 255.0;
        for (int c = 0; c < 3; ++c)
          band_out[3 * i + size_t(c)] = float(sum.c[c] * norm / (255.0 * 255.0) + double(background[c]) * (1.0 - cover));
      });
}

}  // namespace

void composite_target(const Image8& image, const Image8& mask, int s, const float background[3], float* out,
                      platform::ThreadPool* pool) {
  const int out_h = image.height / s;
  // Bands of output rows: every output pixel is computed alone, so the split changes nothing.
  const size_t bands = pool && out_h >= 32 ? size_t(std::min(4 * pool->num_threads(), out_h / 8)) : 1;
  auto band = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i)
      composite_rows(image, mask, s, background, int(i * size_t(out_h) / bands), int((i + 1) * size_t(out_h) / bands),
                     out);
  };
  if (bands > 1)
    pool->parallel_for(bands, 1, band);
  else
    band(0, bands, 0);
}

void valid_target(const Image8& valid, int s, uint8_t* out) {
  const int w = valid.width, out_w = w / s, out_h = valid.height / s;
  for (int y = 0; y < out_h; ++y) {
    for (int x = 0; x < out_w; ++x) {
      bool all = true;
      for (int dy = 0; dy < s && all; ++dy)
        for (int dx = 0; dx < s && all; ++dx) all = valid.pixels[size_t(y * s + dy) * size_t(w) + size_t(x * s + dx)] != 0;
      out[size_t(y) * size_t(out_w) + size_t(x)] = all ? 255 : 0;
    }
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
