// SPDX-License-Identifier: MIT
// LPIPS-Alex v0.1: weight loading, AlexNet features up to relu5, and the per-layer normalised
// distance (see gs/metrics/lpips.h and ../shared/data/lpips_alex/README.md for the formula).
#include "gs/metrics/lpips.h"

#include <cmath>
#include <cstring>
#include <utility>

#include "gs/metrics/conv2d.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"

namespace gs::metrics {
namespace {

// One AlexNet stage: [maxpool 3/2], conv + ReLU, tapped for LPIPS. Offsets are in floats into
// weights.bin (index.json's "offset"); lin is the LPIPS head for this tap, [out_c], no bias.
struct Stage {
  int in_c, out_c, kernel, stride, pad;
  bool pool_before;
  size_t w_off, b_off, lin_off;
};
constexpr Stage kStages[5] = {
    {3, 64, 11, 4, 2, false, 0, 23232, 2469696},
    {64, 192, 5, 1, 2, true, 23296, 330496, 2469760},
    {192, 384, 3, 1, 1, true, 330688, 994240, 2469952},
    {384, 256, 3, 1, 1, false, 994624, 1879360, 2470336},
    {256, 256, 3, 1, 1, false, 1879616, 2469440, 2470592},
};

// The tensors are back to back: conv weights and biases, then the five lin heads.
constexpr bool offsets_consistent() {
  size_t at = 0;
  for (const Stage& s : kStages) {
    if (s.w_off != at) return false;
    at += size_t(s.out_c) * s.in_c * s.kernel * s.kernel;
    if (s.b_off != at) return false;
    at += size_t(s.out_c);
  }
  for (const Stage& s : kStages) {
    if (s.lin_off != at) return false;
    at += size_t(s.out_c);
  }
  return at == LpipsAlex::kWeightFloats;
}
static_assert(offsets_consistent(), "LPIPS-Alex weight table does not tile weights.bin");

// LPIPS v0.1 scaling layer, applied to inputs in [-1, 1], channels R, G, B.
constexpr double kShift[3] = {-0.030, -0.088, -0.188};
constexpr double kScale[3] = {0.458, 0.448, 0.450};
constexpr double kNormEps = 1e-10;  // added to the channel norm (not under the sqrt), as lpips does
constexpr int kMaxSide = 16384;     // keeps every pixel count well inside int

bool host_is_little_endian() {
  const uint32_t one = 1;
  uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// [H, W, 3] values in [0, 1] (v = raw · to_unit) -> scaling layer output [3, H, W].
template <class T>
std::vector<float> scale_input(const T* rgb, int W, int H, double to_unit) {
  const size_t hw = size_t(W) * H;
  std::vector<float> out(3 * hw);
  for (size_t p = 0; p < hw; ++p) {
    for (int c = 0; c < 3; ++c) {
      const double x = 2.0 * (double(rgb[p * 3 + c]) * to_unit) - 1.0;
      out[c * hw + p] = float((x - kShift[c]) / kScale[c]);
    }
  }
  return out;
}

}  // namespace

LpipsAlex::LpipsAlex() = default;
LpipsAlex::~LpipsAlex() = default;
LpipsAlex::LpipsAlex(LpipsAlex&&) noexcept = default;
LpipsAlex& LpipsAlex::operator=(LpipsAlex&&) noexcept = default;

Expected<LpipsAlex> LpipsAlex::load(const std::string& folder, int num_threads) {
  const std::string path = folder + "/weights.bin";
  auto bytes = platform::read_file(path, uint64_t(kWeightBytes) * 2);
  if (!bytes.ok()) return Status(bytes.status().code(), "LPIPS-Alex weights: " + bytes.status().message());
  if (bytes->size() != kWeightBytes) {
    return parse_error("LPIPS-Alex weights: " + path + " is " + std::to_string(bytes->size()) + " bytes, expected " +
                       std::to_string(kWeightBytes) + " (" + std::to_string(kWeightFloats) +
                       " little-endian float32, LPIPS-Alex v0.1)");
  }
  LpipsAlex m;
  m.weights_.resize(kWeightFloats);
  if (!host_is_little_endian()) {
    for (size_t i = 0; i < bytes->size(); i += 4) std::swap((*bytes)[i], (*bytes)[i + 3]), std::swap((*bytes)[i + 1], (*bytes)[i + 2]);
  }
  std::memcpy(m.weights_.data(), bytes->data(), kWeightBytes);
  for (size_t i = 0; i < kWeightFloats; ++i) {
    if (!std::isfinite(m.weights_[i])) {
      return parse_error("LPIPS-Alex weights: " + path + " has a non-finite value at float " + std::to_string(i));
    }
  }
  m.pool_ = std::make_unique<platform::ThreadPool>(num_threads);
  return m;
}

Status LpipsAlex::check_ready(const void* a, const void* b, int W, int H) const {
  if (weights_.empty()) return invalid_argument("LPIPS-Alex: no weights loaded (use LpipsAlex::load)");
  if (!a || !b) return invalid_argument("LPIPS-Alex: null image pointer");
  if (W < kMinSide || H < kMinSide || W > kMaxSide || H > kMaxSide) {
    return invalid_argument("LPIPS-Alex: image is " + std::to_string(W) + "x" + std::to_string(H) +
                            "; each side must be in [" + std::to_string(kMinSide) + ", " + std::to_string(kMaxSide) +
                            "] (AlexNet's second max pool needs a 3x3 input)");
  }
  return Status::Ok();
}

Expected<LpipsFeatures> LpipsAlex::features(const uint8_t* rgb, int W, int H) const {
  GS_RETURN_IF_ERROR(check_ready(rgb, rgb, W, H));
  return forward(scale_input(rgb, W, H, 1.0 / 255.0), W, H);
}

Expected<LpipsFeatures> LpipsAlex::features(const float* rgb, int W, int H) const {
  GS_RETURN_IF_ERROR(check_ready(rgb, rgb, W, H));
  return forward(scale_input(rgb, W, H, 1.0), W, H);
}

Expected<LpipsFeatures> LpipsAlex::forward(std::vector<float> scaled, int W, int H) const {
  LpipsFeatures f;
  f.width = W, f.height = H;
  for (float v : scaled) f.scaled_input_sum += v;
  std::vector<float> pooled;
  const float* in = scaled.data();
  int c = 3, h = H, w = W;
  for (int k = 0; k < 5; ++k) {
    const Stage& st = kStages[k];
    if (st.pool_before) {
      pooled.resize(size_t(c) * maxpool3s2_out(h) * maxpool3s2_out(w));
      maxpool3s2_f32(c, h, w, in, pooled.data());
      h = maxpool3s2_out(h), w = maxpool3s2_out(w), in = pooled.data();
    }
    Conv2dShape s;
    s.in_c = c, s.in_h = h, s.in_w = w, s.out_c = st.out_c, s.kernel = st.kernel, s.stride = st.stride, s.pad = st.pad;
    GS_DCHECK(s.valid() && st.in_c == c);
    f.relu[k].resize(size_t(s.out_c) * s.out_h() * s.out_w());
    conv2d_relu_f32(s, in, weights_.data() + st.w_off, weights_.data() + st.b_off, f.relu[k].data(), pool_.get());
    f.shape[k] = {s.out_c, s.out_h(), s.out_w()};
    c = s.out_c, h = s.out_h(), w = s.out_w(), in = f.relu[k].data();
  }
  return f;
}

Expected<LpipsDetails> LpipsAlex::compare(const LpipsFeatures& f0, const LpipsFeatures& f1) const {
  if (weights_.empty()) return invalid_argument("LPIPS-Alex: no weights loaded (use LpipsAlex::load)");
  if (f0.width != f1.width || f0.height != f1.height || f0.shape != f1.shape) {
    return invalid_argument("LPIPS-Alex: images differ in size (" + std::to_string(f0.width) + "x" +
                            std::to_string(f0.height) + " vs " + std::to_string(f1.width) + "x" +
                            std::to_string(f1.height) + ")");
  }
  LpipsDetails d;
  std::vector<double> inv0, inv1;
  for (int k = 0; k < 5; ++k) {
    const int C = f0.shape[k][0];
    const size_t hw = size_t(f0.shape[k][1]) * f0.shape[k][2];
    if (f0.relu[k].size() != C * hw || f1.relu[k].size() != C * hw) {
      return invalid_argument("LPIPS-Alex: features of layer " + std::to_string(k + 1) + " do not match their shape");
    }
    const float* a = f0.relu[k].data();
    const float* b = f1.relu[k].data();
    // 1 / (||f||_c + eps) per pixel; channel-outer loops keep the CHW reads contiguous.
    inv0.assign(hw, 0.0), inv1.assign(hw, 0.0);
    for (int c = 0; c < C; ++c) {
      for (size_t p = 0; p < hw; ++p) {
        const double u = a[c * hw + p], v = b[c * hw + p];
        inv0[p] += u * u, inv1[p] += v * v;
      }
    }
    for (size_t p = 0; p < hw; ++p) inv0[p] = 1.0 / (std::sqrt(inv0[p]) + kNormEps), inv1[p] = 1.0 / (std::sqrt(inv1[p]) + kNormEps);
    const float* lin = weights_.data() + kStages[k].lin_off;
    LpipsLayerStats& L = d.layers[k];
    L.channels = C, L.height = f0.shape[k][1], L.width = f0.shape[k][2];
    for (int c = 0; c < C; ++c) {
      double plain = 0;
      for (size_t p = 0; p < hw; ++p) {
        const double e = double(a[c * hw + p]) * inv0[p] - double(b[c * hw + p]) * inv1[p];
        plain += e * e;
      }
      L.norm_diff_sum += plain;
      L.weighted_sum += double(lin[c]) * plain;
    }
    L.contribution = L.weighted_sum / double(hw);
    d.distance += L.contribution;
  }
  return d;
}

Expected<LpipsDetails> LpipsAlex::distance_details(const uint8_t* a, const uint8_t* b, int W, int H) const {
  auto f0 = features(a, W, H);
  if (!f0.ok()) return f0.status();
  auto f1 = features(b, W, H);
  if (!f1.ok()) return f1.status();
  return compare(*f0, *f1);
}

Expected<double> LpipsAlex::distance(const uint8_t* a, const uint8_t* b, int W, int H) const {
  auto d = distance_details(a, b, W, H);
  if (!d.ok()) return d.status();
  return d->distance;
}

Expected<double> LpipsAlex::distance(const float* a, const float* b, int W, int H) const {
  auto f0 = features(a, W, H);
  if (!f0.ok()) return f0.status();
  auto f1 = features(b, W, H);
  if (!f1.ok()) return f1.status();
  auto d = compare(*f0, *f1);
  if (!d.ok()) return d.status();
  return d->distance;
}

}  // namespace gs::metrics
