// SPDX-License-Identifier: MIT
// conv2d + ReLU as im2col + SGEMM (Eigen's product over our buffers), its direct double-precision
// reference, and 3x3/2 max pooling. See gs/metrics/conv2d.h.
#include "gs/metrics/conv2d.h"

#include <Eigen/Core>
#include <algorithm>
#include <vector>

#include "gs/platform/thread_pool.h"
#include "gs/status.h"

namespace gs::metrics {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Output pixels per GEMM chunk. Large enough that the GEMM's packed panels are reused (Eigen packs
// the weight matrix once per call), small enough that conv1's 6984 pixels spread over the workers
// and the im2col block (K x kChunk floats; K = 1600 for conv2 -> 1.6 MB) stays near L2.
constexpr int kChunk = 256;

// cols[r, j] for r = (ci, ky, kx) and output pixel p0 + j: the input sample that multiplies weight
// column r, zero where the window reaches into the padding.
void im2col(const Conv2dShape& s, const float* x, int p0, int n, float* cols /* [K, n] */) {
  const int ow = s.out_w(), k = s.kernel;
  for (int ci = 0; ci < s.in_c; ++ci) {
    const float* xc = x + size_t(ci) * s.in_h * s.in_w;
    for (int ky = 0; ky < k; ++ky) {
      for (int kx = 0; kx < k; ++kx) {
        float* row = cols + (size_t(ci * k + ky) * k + kx) * n;
        int oy = p0 / ow, ox = p0 % ow;
        for (int j = 0; j < n; ++j) {
          const int iy = oy * s.stride - s.pad + ky, ix = ox * s.stride - s.pad + kx;
          row[j] = (iy >= 0 && iy < s.in_h && ix >= 0 && ix < s.in_w) ? xc[size_t(iy) * s.in_w + ix] : 0.0f;
          if (++ox == ow) ox = 0, ++oy;
        }
      }
    }
  }
}

}  // namespace

void conv2d_relu_f32(const Conv2dShape& s, const float* x, const float* w, const float* b, float* y,
                     platform::ThreadPool* pool) {
  GS_DCHECK(s.valid());
  const int K = s.in_c * s.kernel * s.kernel;
  const int N = s.out_h() * s.out_w();
  const int n_chunks = (N + kChunk - 1) / kChunk;
  auto run = [&](size_t c_begin, size_t c_end, int /*worker*/) {
    std::vector<float> cols(size_t(K) * kChunk);
    for (size_t c = c_begin; c < c_end; ++c) {
      const int p0 = int(c) * kChunk, n = std::min(kChunk, N - p0);
      im2col(s, x, p0, n, cols.data());
      Eigen::Map<const RowMatrix> W(w, s.out_c, K);
      Eigen::Map<const RowMatrix> C(cols.data(), K, n);
      Eigen::Map<RowMatrix, 0, Eigen::OuterStride<>> Y(y + p0, s.out_c, n, Eigen::OuterStride<>(N));
      Y.noalias() = W * C;
      for (int o = 0; o < s.out_c; ++o) {
        float* yo = y + size_t(o) * N + p0;
        for (int j = 0; j < n; ++j) yo[j] = std::max(yo[j] + b[o], 0.0f);
      }
    }
  };
  if (pool && n_chunks > 1) {
    pool->parallel_for(size_t(n_chunks), 1, run);
  } else {
    run(0, size_t(n_chunks), 0);
  }
}

void conv2d_relu_ref(const Conv2dShape& s, const float* x, const float* w, const float* b, double* y, bool relu) {
  const int oh = s.out_h(), ow = s.out_w(), k = s.kernel;
  for (int o = 0; o < s.out_c; ++o) {
    for (int oy = 0; oy < oh; ++oy) {
      for (int ox = 0; ox < ow; ++ox) {
        double acc = b[o];
        for (int ci = 0; ci < s.in_c; ++ci) {
          for (int ky = 0; ky < k; ++ky) {
            const int iy = oy * s.stride - s.pad + ky;
            if (iy < 0 || iy >= s.in_h) continue;
            for (int kx = 0; kx < k; ++kx) {
              const int ix = ox * s.stride - s.pad + kx;
              if (ix < 0 || ix >= s.in_w) continue;
              acc += double(w[((size_t(o) * s.in_c + ci) * k + ky) * k + kx]) *
                     double(x[(size_t(ci) * s.in_h + iy) * s.in_w + ix]);
            }
          }
        }
        y[(size_t(o) * oh + oy) * ow + ox] = relu ? std::max(acc, 0.0) : acc;
      }
    }
  }
}

void maxpool3s2_f32(int c, int h, int w, const float* x, float* y) {
  const int oh = maxpool3s2_out(h), ow = maxpool3s2_out(w);
  for (int ch = 0; ch < c; ++ch) {
    const float* xc = x + size_t(ch) * h * w;
    float* yc = y + size_t(ch) * oh * ow;
    for (int oy = 0; oy < oh; ++oy) {
      for (int ox = 0; ox < ow; ++ox) {
        const float* p = xc + size_t(2 * oy) * w + 2 * ox;
        float m = p[0];
        for (int dy = 0; dy < 3; ++dy)
          for (int dx = 0; dx < 3; ++dx) m = std::max(m, p[size_t(dy) * w + dx]);
        yc[size_t(oy) * ow + ox] = m;
      }
    }
  }
}

}  // namespace gs::metrics
