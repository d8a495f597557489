// SPDX-License-Identifier: MIT
// LPIPS-Alex v0.1 (Zhang et al., "The Unreasonable Effectiveness of Deep Features as a Perceptual
// Metric", CVPR 2018): the perceptual distance 3DGS papers report next to PSNR and SSIM. It is the
// value of lpips.LPIPS(net='alex', version='0.1', spatial=False), computed on the CPU in float32
// (reductions in double) from the weights in ../shared/data/lpips_alex (see its README.md).
//
// Pipeline for one image (all tensors CHW float):
//   RGB in [0, 1] -> x = 2·v - 1 -> scaling layer (x - shift[c]) / scale[c]          [3, H, W]
//   conv1 11x11/4 pad 2 + ReLU -> relu1                                            [64, h1, w1]
//   maxpool 3/2, conv2 5x5 pad 2 + ReLU -> relu2                                  [192, h2, w2]
//   maxpool 3/2, conv3 3x3 pad 1 + ReLU -> relu3                                  [384, h3, w3]
//   conv4 3x3 pad 1 + ReLU -> relu4, conv5 3x3 pad 1 + ReLU -> relu5         [256, h3, w3] each
// with h1 = (H - 7) / 4 + 1, h2 = (h1 - 3) / 2 + 1, h3 = (h2 - 3) / 2 + 1 (integer division), so
// 393x293 gives 97x72, 48x35 and 23x17. For two images and each layer k:
//   n(f) = f / (||f||_channels + 1e-10)   (eps added to the norm, not under the root)
//   L_k = mean over pixels of sum_c lin_k[c] · (n(f0) - n(f1))²,   LPIPS = L_1 + ... + L_5.
// Inputs must be at least 31x31 (the second max pool needs a 3x3 input).
//
// Lifecycle: load() reads weights.bin once (9,883,392 bytes; size checked, values checked finite)
// and builds a ThreadPool; distance() then allocates its activations per call (about 4 MB per
// image at 393x293). The cost is ~1.5 GMAC per 393x293 image, almost all in the conv GEMMs: about
// 0.34 s of CPU time per pair in a baseline x86-64 build (Eigen's SSE2 kernels), split over the
// pool's threads. Calls from several threads are safe (the object is not modified); their
// convolutions queue on the shared pool.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::metrics {

// Activations of the five tapped ReLUs for one image, kept so a reference image's features can be
// computed once and compared against many renders.
struct LpipsFeatures {
  int width = 0, height = 0;                  // input size, pixels
  double scaled_input_sum = 0;                // sum of the scaled input, a debugging aid
  std::array<std::array<int, 3>, 5> shape{};  // per layer {C, h, w}
  std::array<std::vector<float>, 5> relu;     // per layer [C, h, w]
};

// Per-layer breakdown of one distance, named like goldens.json's fields.
struct LpipsLayerStats {
  int channels = 0, height = 0, width = 0;
  double norm_diff_sum = 0;  // sum over c, y, x of (n0 - n1)²
  double weighted_sum = 0;   // sum over y, x of sum_c lin[c] (n0 - n1)²
  double contribution = 0;   // weighted_sum / (h·w) = L_k
};
struct LpipsDetails {
  double distance = 0;  // sum of the 5 contributions
  std::array<LpipsLayerStats, 5> layers;
};

class LpipsAlex {
 public:
  // The name to print and to use as a JSON key, so results are never confused with LPIPS-VGG.
  static constexpr const char* kLabel = "LPIPS-Alex";
  static constexpr int kMinSide = 31;                // pixels; smaller inputs are refused
  static constexpr size_t kWeightFloats = 2470848;   // float32 values in weights.bin
  static constexpr size_t kWeightBytes = 4 * kWeightFloats;

  // Reads folder/weights.bin (little-endian float32 tensors back to back, the layout in the
  // folder's index.json, which is not read: the layout is fixed by the model). A missing or
  // unreadable file is kIoError; a wrong size or non-finite values are kParseError. num_threads as
  // for platform::ThreadPool (<= 0: every CPU this process may use; 1: the calling thread only).
  static Expected<LpipsAlex> load(const std::string& folder, int num_threads = 0);

  LpipsAlex();  // empty: every call returns an error until a loaded instance is moved in
  ~LpipsAlex();
  LpipsAlex(LpipsAlex&&) noexcept;
  LpipsAlex& operator=(LpipsAlex&&) noexcept;

  // a, b: [H, W, 3] interleaved RGB. 8-bit values are divided by 255; float values are in [0, 1]
  // (not clamped, as lpips with normalize=True). Errors: not loaded, null pointers, W or H below
  // kMinSide (kInvalidArgument).
  Expected<double> distance(const uint8_t* a, const uint8_t* b, int W, int H) const;
  Expected<double> distance(const float* a, const float* b, int W, int H) const;
  Expected<LpipsDetails> distance_details(const uint8_t* a, const uint8_t* b, int W, int H) const;

  Expected<LpipsFeatures> features(const uint8_t* rgb, int W, int H) const;  // rgb: [H, W, 3]
  Expected<LpipsFeatures> features(const float* rgb, int W, int H) const;    // rgb: [H, W, 3]
  // Distance between two feature sets of the same input size (kInvalidArgument otherwise).
  Expected<LpipsDetails> compare(const LpipsFeatures& f0, const LpipsFeatures& f1) const;

 private:
  Status check_ready(const void* a, const void* b, int W, int H) const;
  Expected<LpipsFeatures> forward(std::vector<float> scaled, int W, int H) const;  // scaled: [3, H, W]

  std::vector<float> weights_;                    // all of weights.bin, [kWeightFloats]
  std::unique_ptr<platform::ThreadPool> pool_;
};

}  // namespace gs::metrics
