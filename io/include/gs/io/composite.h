// SPDX-License-Identifier: MIT
// A view's photo composited on a background colour through its mask (object captures): what a
// render "as rendered" is compared with in training and evaluation. coverage m = mask / 255 (1 with
// no mask): composite = image * m + background * (1 - m).
#pragma once

#include <cstdint>

#include "gs/io/image.h"

namespace gs::platform {
class ThreadPool;
}

namespace gs::io {

// Training target at resolution divisor s: the mean of each s x s block of the composite, floats in
// [0, 1], [H / s, W / s, 3] (the grid of box_downsample_rgb; equal to it without a mask).
// image: RGB; mask: 1 channel of the image's size, or empty. background: [3] in [0, 1]. No
// allocation. pool: bands of rows in parallel (same result; null: the calling thread).
void composite_target(const Image8& image, const Image8& mask, int s, const float background[3], float* out,
                      platform::ThreadPool* pool = nullptr);

// Which pixels of the training target at resolution divisor s exist ([H / s, W / s], the grid of
// composite_target): 255 where every pixel of the s x s block is valid, else 0. valid: 1 channel
// (io::DatasetView::valid, not empty). No allocation.
void valid_target(const Image8& valid, int s, uint8_t* out);

// The composite at full resolution rounded to 8 bits (what evaluation compares renders with); the
// image itself (a copy) without a mask.
Image8 composite_rgb8(const Image8& image, const Image8& mask, const float background[3]);

}  // namespace gs::io
