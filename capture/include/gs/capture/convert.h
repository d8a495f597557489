// SPDX-License-Identifier: MIT
// Frame to RGB24 conversion for every PixelFormat: YUYV and NV12 through the SIMD kernel table
// (gs/simd/convert.h: BT.601 limited range, integer arithmetic, bit-identical to the reference),
// MJPEG through stb_image (with the standard Huffman tables inserted when a UVC camera leaves
// the DHT segment out), RGB24 as a strided copy.
#pragma once

#include <cstdint>
#include <vector>

#include "gs/capture/frame.h"
#include "gs/status.h"

namespace gs::capture {

// Converts frame into rgb [frame.height, rgb_stride bytes per row], rgb_stride >= 3 * width.
// MJPEG: the JPEG's size must equal the frame's; a corrupt JPEG is an error, not a black image.
Status frame_to_rgb(const FrameView& frame, uint8_t* rgb, int32_t rgb_stride);

// UVC MJPEG: returns jpeg with the default (ITU-T T.81 Annex K) DHT segment inserted before the
// first SOF/SOS when it has none; otherwise a plain copy.
std::vector<uint8_t> insert_default_huffman_tables(const uint8_t* jpeg, size_t size);

}  // namespace gs::capture
