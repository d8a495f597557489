// SPDX-License-Identifier: MIT
// 8-bit images: decode (JPEG/PNG via stb_image, from memory), area downscale, PNG encode/write.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gs/io/box_filter.h"
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
// A folder's image files as frame sources play them: the names (not paths) of its .png, .jpg and
// .jpeg files (any letter case; no hidden files, no sub-folders), sorted byte-wise, so zero-padded
// names come out in sequence. An empty folder gives an empty list; an unreadable one an io_error
// "cannot list: <reason>" (callers name the folder).
bool is_image_file_name(const std::string& name);
Expected<std::vector<std::string>> list_image_files(const std::string& folder);
// Box-filter (area) downscale to any size (both <= the source size), fractional taps at the cell
// borders; for an integer ratio it equals box_downsample_rgb8 (the rounded block mean). Both are
// gs/io/box_filter.h, the one box filter.
Image8 resize_area(const Image8& src, int width, int height);
// Integer channel sums of 8-bit RGB pixels for box_filter (exact: any summation order).
using RgbSum = std::array<int, 3>;
inline auto add_rgb(const uint8_t* rgb, int width) {
  return [rgb, width](RgbSum& sum, int x, int y) {
    const uint8_t* p = rgb + (size_t(y) * size_t(width) + size_t(x)) * 3;
    for (size_t c = 0; c < 3; ++c) sum[c] += p[c];
  };
}
// Mean of each s x s block of an 8-bit RGB image [H, W, 3] as floats in [0, 1], [H / s, W / s, 3]
// (remainder rows and columns dropped; the matching camera is gs::scaled_camera). No allocation.
inline void box_downsample_rgb(const uint8_t* rgb, int width, int height, int s, float* out) {
  const float norm = 1.0f / (255.0f * float(s * s));
  box_filter<RgbSum>(width, height, s, width / s, height / s, add_rgb(rgb, width),
                     [&](size_t i, const RgbSum& sum) {
                       for (size_t c = 0; c < 3; ++c) out[3 * i + c] = float(sum[c]) * norm;
                     });
}
// Mean of each s x s block of a float image [H, W, c], c <= 3 channels, into [H / s, W / s, c]
// (remainder dropped; float sums in row-major block order). No allocation.
inline void box_downsample_float(const float* src, int width, int height, int channels, int s, float* out) {
  const float norm = 1.0f / float(s * s);
  const size_t nc = size_t(channels);
  box_filter<std::array<float, 3>>(
      width, height, s, width / s, height / s,
      [&](std::array<float, 3>& sum, int x, int y) {
        const float* p = src + (size_t(y) * size_t(width) + size_t(x)) * nc;
        for (size_t k = 0; k < nc; ++k) sum[k] += p[k];
      },
      [&](size_t i, const std::array<float, 3>& sum) {
        for (size_t k = 0; k < nc; ++k) out[i * nc + k] = sum[k] * norm;
      });
}
// The same mean rounded to 8 bits, [out_h, out_w, 3] (normally H / s, W / s; at least 1: a block
// past the image's edge reuses its last row / column).
inline void box_downsample_rgb8(const uint8_t* rgb, int width, int height, int s, int out_w, int out_h, uint8_t* out) {
  const int n = s * s;
  box_filter<RgbSum>(width, height, s, out_w, out_h, add_rgb(rgb, width), [&](size_t i, const RgbSum& sum) {
    for (size_t c = 0; c < 3; ++c) out[3 * i + c] = uint8_t((sum[c] + n / 2) / n);
  });
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
