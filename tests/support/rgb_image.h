// SPDX-License-Identifier: MIT
// gs::test::rgb_image: a w x h RGB Image8 whose pixels come from a function of (x, y, channel), for
// tests that need a known pattern (decoded, resampled or measured and compared with the formula).
#pragma once

#include <cstddef>
#include <cstdint>

#include "gs/io/image.h"

namespace gs::test {

// texel(x, y, c) -> uint8_t for c in 0..2.
template <class Texel>
io::Image8 rgb_image(int width, int height, Texel texel) {
  io::Image8 img;
  img.width = width;
  img.height = height;
  img.channels = 3;
  img.pixels.resize(size_t(width) * size_t(height) * 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c) img.pixels[(size_t(y) * size_t(width) + size_t(x)) * 3 + size_t(c)] = texel(x, y, c);
  return img;
}

}  // namespace gs::test
