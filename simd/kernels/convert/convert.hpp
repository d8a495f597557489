// SPDX-License-Identifier: MIT
// xsimd camera pixel-format conversion (YUYV and NV12 to RGB24), templated on the architecture;
// the spec is simd/ref/convert_ref.cpp and every result is bit-identical to it. All arithmetic is
// exact int32 (sums stay below 2^18), so the only freedom is how bytes reach and leave the lanes:
//   - a lane holds one little-endian 32-bit word of input: for YUYV one pixel pair (Y0 U Y1 V),
//     for NV12 four luma bytes plus the matching four chroma bytes (U0 V0 U1 V1), i.e. 4 pixels;
//     bytes are peeled off with shift and mask, so no byte shuffles are needed on any ISA;
//   - results are packed back into 32-bit words (R G B R, G B R G, B R G B) and leave through a
//     small aligned stack buffer, because 6 or 12 output bytes per lane do not map to a store.
// Multiplications by the BT.601 constants are shift-and-add sums (exact, and SSE2 has no 32-bit
// multiply: xsimd would fall back to scalar lanes there).
// Columns that do not fill a whole batch (the right-hand strip of the image, fewer than 2N or 4N
// pixels) go through the reference itself, so inputs are never read past a row's valid bytes and
// outputs never written past 3 * width bytes of a row.
//
// Included only by the per-ISA translation units in ../variants/.
#pragma once

#include <cstdint>
#include <cstring>
#include <xsimd/xsimd.hpp>

#include "gs/simd/isa.h"

#include "gs/simd/convert.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the word packing below assumes little-endian bytes");

template <class Arch>
struct ConvertKernels {
  using I = xsimd::batch<int32_t, Arch>;
  using U8 = xsimd::batch<uint8_t, Arch>;
  static constexpr int N = int(I::size);
  static_assert(int(U8::size) == 4 * N, "one byte batch must fill one int32 batch");

  // yuyv: [height, yuyv_stride bytes]; rgb: [height, rgb_stride bytes] (see gs/simd/convert.h)
  static void yuyv_to_rgb(int32_t width, int32_t height, const uint8_t* yuyv, int32_t yuyv_stride, uint8_t* rgb,
                          int32_t rgb_stride) {
    const int32_t vec_width = width / (2 * N) * (2 * N);  // columns done here; the rest by the reference
    for (int32_t row = 0; row < height && vec_width > 0; ++row) {
      const uint8_t* in = yuyv + int64_t(row) * yuyv_stride;
      uint8_t* out = rgb + int64_t(row) * rgb_stride;
      for (int32_t x = 0; x < vec_width; x += 2 * N) {
        const I w = load_words(in + 2 * x);  // N pixel pairs, Y0 | U << 8 | Y1 << 16 | V << 24
        const Chroma c = chroma(byte<1>(w), byte<3>(w));
        const Rgb p0 = pixel(byte<0>(w), c), p1 = pixel(byte<2>(w), c);
        alignas(64) int32_t t0[N], t1[N];
        (p0.r | (p0.g << 8) | (p0.b << 16) | (p1.r << 24)).store_aligned(t0);
        (p1.g | (p1.b << 8)).store_aligned(t1);
        for (int j = 0; j < N; ++j) {
          std::memcpy(out + 3 * x + 6 * j, &t0[j], 4);
          std::memcpy(out + 3 * x + 6 * j + 4, &t1[j], 2);
        }
      }
    }
    if (vec_width < width)  // vec_width is even, so the strip starts on a pixel pair
      yuyv_to_rgb_ref(width - vec_width, height, yuyv + 2 * vec_width, yuyv_stride, rgb + 3 * vec_width, rgb_stride);
  }

  // y: [height, y_stride]; uv: [ceil(height / 2), uv_stride]; rgb: [height, rgb_stride] (bytes)
  static void nv12_to_rgb(int32_t width, int32_t height, const uint8_t* y, int32_t y_stride, const uint8_t* uv,
                          int32_t uv_stride, uint8_t* rgb, int32_t rgb_stride) {
    const int32_t vec_width = width / (4 * N) * (4 * N);
    for (int32_t row = 0; row < height && vec_width > 0; ++row) {
      const uint8_t* luma = y + int64_t(row) * y_stride;
      const uint8_t* chroma_row = uv + int64_t(row / 2) * uv_stride;
      uint8_t* out = rgb + int64_t(row) * rgb_stride;
      for (int32_t x = 0; x < vec_width; x += 4 * N) {
        const I wy = load_words(luma + x);         // 4 pixels per lane: Ya Yb Yc Yd
        const I wc = load_words(chroma_row + x);   // their 2 chroma pairs: U0 V0 U1 V1
        const Chroma c0 = chroma(byte<0>(wc), byte<1>(wc)), c1 = chroma(byte<2>(wc), byte<3>(wc));
        const Rgb a = pixel(byte<0>(wy), c0), b = pixel(byte<1>(wy), c0);
        const Rgb c = pixel(byte<2>(wy), c1), d = pixel(byte<3>(wy), c1);
        alignas(64) int32_t t[3][N];
        (a.r | (a.g << 8) | (a.b << 16) | (b.r << 24)).store_aligned(t[0]);
        (b.g | (b.b << 8) | (c.r << 16) | (c.g << 24)).store_aligned(t[1]);
        (c.b | (d.r << 8) | (d.g << 16) | (d.b << 24)).store_aligned(t[2]);
        for (int j = 0; j < N; ++j)
          for (int k = 0; k < 3; ++k) std::memcpy(out + 3 * x + 12 * j + 4 * k, &t[k][j], 4);
      }
    }
    if (vec_width < width)  // vec_width is a multiple of 4: the strip starts on a chroma pair
      nv12_to_rgb_ref(width - vec_width, height, y + vec_width, y_stride, uv + vec_width, uv_stride,
                      rgb + 3 * vec_width, rgb_stride);
  }

 private:
  struct Chroma {
    I r, g, b;  // 409 E + 128, -100 D - 208 E + 128, 516 D + 128 (the reference's chroma terms + rounding)
  };
  struct Rgb {
    I r, g, b;  // 0..255
  };

  // 4 N bytes as N little-endian int32 words (unaligned; no read past p + 4 N).
  static I load_words(const uint8_t* p) { return xsimd::bitwise_cast<I>(U8::load_unaligned(p)); }

  template <int K>
  static I byte(const I& w) {
    return (w >> (8 * K)) & I(0xff);
  }

  // x * K for a constant K > 0 as one shifted copy of x per set bit of K (exact in int32 here).
  template <int K, int Bit = 0>
  static I times(const I& x) {
    static_assert(K > 0, "constant factors only");
    if constexpr (K == 1)
      return x << Bit;
    else if constexpr ((K & 1) == 0)
      return times<(K >> 1), Bit + 1>(x);
    else
      return (x << Bit) + times<(K >> 1), Bit + 1>(x);
  }

  static Chroma chroma(const I& u, const I& v) {
    const I d = u - I(128), e = v - I(128), half(128);
    return {times<409>(e) + half, half - times<100>(d) - times<208>(e), times<516>(d) + half};
  }

  static I clamp_u8(const I& sum) { return xsimd::min(xsimd::max(sum >> 8, I(0)), I(255)); }

  static Rgb pixel(const I& y, const Chroma& c) {
    const I l = times<298>(y - I(16));
    return {clamp_u8(l + c.r), clamp_u8(l + c.g), clamp_u8(l + c.b)};
  }
};

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
