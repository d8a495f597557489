// SPDX-License-Identifier: MIT
// Camera pixel-format conversion kernels: packed YUYV (4:2:2) and semi-planar NV12 (4:2:0) to
// interleaved RGB24. BT.601 limited range ("studio swing", what UVC cameras and most V4L2
// drivers deliver), in 8-bit-fraction integer arithmetic so every variant is bit-identical to the
// reference. Chroma is nearest-sited (each chroma sample serves its 2x1 or 2x2 pixel block).
#pragma once

#include <cstdint>

namespace gs::simd {

// Strides are in bytes (rows may be padded); sizes in pixels; any width, height >= 1, odd included.
//   yuyv: [height, yuyv_stride] with yuyv_stride >= 4 * ceil(width / 2)
//   rgb:  [height, rgb_stride]  with rgb_stride >= 3 * width; only the first 3 * width bytes of a
//         row are written.
void yuyv_to_rgb_ref(int32_t width, int32_t height, const uint8_t* yuyv, int32_t yuyv_stride, uint8_t* rgb,
                     int32_t rgb_stride);
//   y:  [height, y_stride] with y_stride >= width
//   uv: [ceil(height / 2), uv_stride] with uv_stride >= 2 * ceil(width / 2), U then V
void nv12_to_rgb_ref(int32_t width, int32_t height, const uint8_t* y, int32_t y_stride, const uint8_t* uv,
                     int32_t uv_stride, uint8_t* rgb, int32_t rgb_stride);

}  // namespace gs::simd
