// SPDX-License-Identifier: MIT
// Reference camera pixel-format conversion (YUYV 4:2:2 and NV12 4:2:0 to RGB24), the spec of
// simd/kernels/convert/. BT.601 limited range ("studio swing": Y in 16..235, U/V in 16..240 around
// 128) with the usual 8-bit fixed-point coefficients, i.e. the BT.601 matrix scaled by 256 and
// rounded: 298 = 255/219 * 256 (luma gain), 409 = 1.402 * 255/224 * 256 (V to R), 100 and 208 =
// 0.344 and 0.714 * 255/224 * 256 (U and V to G), 516 = 1.772 * 255/224 * 256 (U to B). Adding 128
// before the shift by 8 rounds to nearest. Chroma is nearest-sited: a chroma sample serves its
// whole 2x1 (YUYV) or 2x2 (NV12) block, which is what UVC/V4L2 drivers deliver and what makes odd
// widths and heights simple (the last column/row uses the half-used last chroma sample).
#include <cstdint>

#include "gs/simd/convert.h"

namespace gs::simd {
namespace {

uint8_t clamp_u8(int32_t v) { return uint8_t(v < 0 ? 0 : v > 255 ? 255 : v); }

// One pixel: luma y and chroma u, v (all 0..255) to R, G, B at out[0..2]. The sums stay within
// int32 (|298 * 239 + 516 * 127 + 128| < 2^18). A negative sum shifts arithmetically (GCC/Clang;
// C++20 guarantees it), and every negative sum clamps to 0 either way.
void yuv_pixel(int32_t y, int32_t u, int32_t v, uint8_t* out) {
  const int32_t c = y - 16, d = u - 128, e = v - 128;
  out[0] = clamp_u8((298 * c + 409 * e + 128) >> 8);
  out[1] = clamp_u8((298 * c - 100 * d - 208 * e + 128) >> 8);
  out[2] = clamp_u8((298 * c + 516 * d + 128) >> 8);
}

}  // namespace

void yuyv_to_rgb_ref(int32_t width, int32_t height, const uint8_t* yuyv, int32_t yuyv_stride, uint8_t* rgb,
                     int32_t rgb_stride) {
  for (int32_t row = 0; row < height; ++row) {
    const uint8_t* in = yuyv + int64_t(row) * yuyv_stride;  // Y0 U Y1 V per pixel pair
    uint8_t* out = rgb + int64_t(row) * rgb_stride;
    for (int32_t x = 0; x < width; ++x) {
      const uint8_t* pair = in + 4 * (x / 2);
      yuv_pixel(pair[2 * (x % 2)], pair[1], pair[3], out + 3 * x);
    }
  }
}

void nv12_to_rgb_ref(int32_t width, int32_t height, const uint8_t* y, int32_t y_stride, const uint8_t* uv,
                     int32_t uv_stride, uint8_t* rgb, int32_t rgb_stride) {
  for (int32_t row = 0; row < height; ++row) {
    const uint8_t* luma = y + int64_t(row) * y_stride;
    const uint8_t* chroma = uv + int64_t(row / 2) * uv_stride;  // U V per 2x2 block
    uint8_t* out = rgb + int64_t(row) * rgb_stride;
    for (int32_t x = 0; x < width; ++x) {
      const uint8_t* uv_pair = chroma + 2 * (x / 2);
      yuv_pixel(luma[x], uv_pair[0], uv_pair[1], out + 3 * x);
    }
  }
}

}  // namespace gs::simd
