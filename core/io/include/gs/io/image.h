// SPDX-License-Identifier: MIT
// 8-bit images: decode (JPEG/PNG via stb_image, from memory), area downscale, PNG encode/write.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::io {

struct Image8 {
  int width = 0, height = 0, channels = 0;  // channels: 1, 3 or 4
  std::vector<uint8_t> pixels;              // [height, width, channels], row-major, no padding
  bool empty() const { return pixels.empty(); }
};

// Largest image hbgs accepts, per side; a header claiming more is rejected before allocation.
constexpr int kMaxImageSide = 16384;

// Decodes a PNG or JPEG held in memory into `channels` channels (3 = RGB). `source` names the file
// in error messages. Unknown formats, truncated data and absurd sizes give a clear error.
Expected<Image8> decode_image(const uint8_t* data, size_t size, int channels, const std::string& source);
Expected<Image8> read_image(const std::string& path, int channels = 3);
// Box-filter downscale to the given size (both <= the source size).
Image8 resize_area(const Image8& src, int width, int height);
// Mean of each s x s block of an 8-bit RGB image [H, W, 3] as floats in [0, 1], [H / s, W / s, 3]
// (remainder rows and columns dropped; the matching camera is gs::scaled_camera). No allocation.
inline void box_downsample_rgb(const uint8_t* rgb, int width, int height, int s, float* out) {
  const int w = width / s, h = height / s;
  const float norm = 1.0f / (255.0f * float(s * s));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int dy = 0; dy < s; ++dy)
          for (int dx = 0; dx < s; ++dx) sum += rgb[(size_t(y * s + dy) * size_t(width) + size_t(x * s + dx)) * 3 + size_t(c)];
        out[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(c)] = float(sum) * norm;
      }
}
// Encodes as PNG; writes atomically (temp file + rename).
Expected<std::vector<uint8_t>> encode_png(const Image8& image);
Status write_png(const std::string& path, const Image8& image);
// float [H, W, 3] in [0, 1] (clamped) to 8-bit with rounding.
Image8 image_from_float_rgb(const float* rgb, int width, int height);

}  // namespace gs::io
