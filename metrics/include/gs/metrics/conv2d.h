// SPDX-License-Identifier: MIT
// The two CNN layers LPIPS needs: 2-D convolution + bias + ReLU, and 3x3/2 max pooling, on
// single-image CHW float tensors. conv2d_relu_f32 is the fast path (im2col over a chunk of output
// pixels, then one SGEMM per chunk with Eigen, chunks spread over a ThreadPool);
// conv2d_relu_ref is its slow, readable twin (direct loops, double accumulation) and the spec the
// tests compare against.
//
// Semantics are PyTorch's conv2d: cross-correlation (no kernel flip), square kernel, zero padding,
// out = floor((in + 2·pad - kernel) / stride) + 1. Weights are OIHW, [out_c, in_c, k, k], which is
// already the row-major [out_c, in_c·k·k] matrix the GEMM wants.
#pragma once

#include <cstddef>

namespace gs::platform { class ThreadPool; }

namespace gs::metrics {

struct Conv2dShape {
  int in_c = 0, in_h = 0, in_w = 0;
  int out_c = 0, kernel = 0, stride = 1, pad = 0;
  int out_h() const { return (in_h + 2 * pad - kernel) / stride + 1; }
  int out_w() const { return (in_w + 2 * pad - kernel) / stride + 1; }
  bool valid() const {
    return in_c > 0 && out_c > 0 && kernel > 0 && stride > 0 && pad >= 0 && in_h + 2 * pad >= kernel &&
           in_w + 2 * pad >= kernel;
  }
};

// y = max(0, conv(x, w) + b). pool may be null (runs on the calling thread). Allocates its im2col
// scratch (in_c·k·k floats per output pixel of a chunk) per call. Results do not depend on the
// number of threads: every output element is one GEMM dot product over the same K.
void conv2d_relu_f32(const Conv2dShape& s,
                     const float* x,  // [in_c, in_h, in_w]
                     const float* w,  // [out_c, in_c, kernel, kernel]
                     const float* b,  // [out_c]
                     float* y,        // [out_c, out_h, out_w]
                     platform::ThreadPool* pool);

// Reference: same result, double accumulation, no ReLU when relu is false (for tests of the
// pre-activation values).
void conv2d_relu_ref(const Conv2dShape& s,
                     const float* x,  // [in_c, in_h, in_w]
                     const float* w,  // [out_c, in_c, kernel, kernel]
                     const float* b,  // [out_c]
                     double* y,       // [out_c, out_h, out_w]
                     bool relu = true);

// 3x3 window, stride 2, no padding, floor rounding: out = (in - 3) / 2 + 1 per side (in >= 3).
inline int maxpool3s2_out(int in) { return (in - 3) / 2 + 1; }
void maxpool3s2_f32(int c, int h, int w,
                    const float* x,  // [c, h, w]
                    float* y);       // [c, maxpool3s2_out(h), maxpool3s2_out(w)]

}  // namespace gs::metrics
