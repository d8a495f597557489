// SPDX-License-Identifier: MIT
// 8-bit images: decode (JPEG/PNG via stb_image, from memory), area downscale, PNG encode/write.
#pragma once

#include <algorithm>
#include <cstddef>
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
// channels = kChannelsAsStored keeps the file's alpha: RGBA (4) when the file has an alpha channel
// (grey + alpha is expanded to RGBA), RGB (3) otherwise.
constexpr int kChannelsAsStored = 0;
Expected<Image8> decode_image(const uint8_t* data, size_t size, int channels, const std::string& source);
Expected<Image8> read_image(const std::string& path, int channels = 3);
// Size and alpha of an image file from its header (the file is read, its pixels are not decoded).
struct ImageInfo {
  int width = 0, height = 0;
  bool has_alpha = false;  // grey + alpha or RGBA
};
Expected<ImageInfo> read_image_info(const std::string& path);
// Box-filter (area) downscale to any size (both <= the source size), fractional taps at the block
// borders; for an integer ratio it equals box_downsample_rgb8 (the rounded block mean).
Image8 resize_area(const Image8& src, int width, int height);
// The one integer box filter (s x s blocks) of 8-bit RGB [H, W, 3]: calls store(i, sum) with the
// sum of the block of each output value i of [out_h, out_w, 3]; block rows and columns past the
// image's edge reuse its last row / column (only when out_w * s > width, e.g. a 1 px image).
// Non-integer ratios: resize_area (fractional taps). No allocation.
template <class Store>
inline void box_filter_rgb(const uint8_t* rgb, int width, int height, int s, int out_w, int out_h, Store&& store) {
  for (int y = 0; y < out_h; ++y)
    for (int x = 0; x < out_w; ++x)
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int dy = 0; dy < s; ++dy) {
          const size_t row = size_t(std::min(y * s + dy, height - 1)) * size_t(width);
          for (int dx = 0; dx < s; ++dx) sum += rgb[(row + size_t(std::min(x * s + dx, width - 1))) * 3 + size_t(c)];
        }
        store((size_t(y) * size_t(out_w) + size_t(x)) * 3 + size_t(c), sum);
      }
}
// Mean of each s x s block of an 8-bit RGB image [H, W, 3] as floats in [0, 1], [H / s, W / s, 3]
// (remainder rows and columns dropped; the matching camera is gs::scaled_camera). No allocation.
inline void box_downsample_rgb(const uint8_t* rgb, int width, int height, int s, float* out) {
  const float norm = 1.0f / (255.0f * float(s * s));
  box_filter_rgb(rgb, width, height, s, width / s, height / s, [&](size_t i, int sum) { out[i] = float(sum) * norm; });
}
// The same mean rounded to 8 bits, [out_h, out_w, 3] (normally H / s, W / s; at least 1).
inline void box_downsample_rgb8(const uint8_t* rgb, int width, int height, int s, int out_w, int out_h, uint8_t* out) {
  const int n = s * s;
  box_filter_rgb(rgb, width, height, s, out_w, out_h, [&](size_t i, int sum) { out[i] = uint8_t((sum + n / 2) / n); });
}
// Encodes as PNG; writes atomically (temp file + rename).
Expected<std::vector<uint8_t>> encode_png(const Image8& image);
Status write_png(const std::string& path, const Image8& image);
// Baseline JPEG (1 or 3 channels; quality 1..100); writes atomically.
Expected<std::vector<uint8_t>> encode_jpeg(const Image8& image, int quality = 95);
Status write_jpeg(const std::string& path, const Image8& image, int quality = 95);
// float [H, W, 3] in [0, 1] (clamped) to 8-bit with rounding.
Image8 image_from_float_rgb(const float* rgb, int width, int height);

}  // namespace gs::io
