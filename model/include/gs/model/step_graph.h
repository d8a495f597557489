// SPDX-License-Identifier: MIT
// One training step's computation graph, written once and templated on the scalar type and on a
// Backend that supplies the MLP, rendering and loss kernels:
//   visible anchors -> g = F(raw image features) -> X = [f ; g ; dir ; dist] -> three decoder MLPs
//   -> kept neural Gaussians -> render -> (1 - l) L1 + l (1 - SSIM) + volume -> all gradients.
// The trainer runs it in float with the SIMD kernels and gs::Renderer; the finite-difference tests
// run the same code in double with the scalar references and gs::ref (tests/model).
//
// Backend<T> must provide:
//   void mlp_fwd(const simd::MlpShape&, int32_t batch, const T* x, const T* params, T* hidden, T* y);
//   void mlp_bwd(const simd::MlpShape&, int32_t batch, const T* x, const T* params, const T* hidden,
//                const T* y, const T* v_y, T* v_x /*overwritten or null*/, T* v_params /*+=*/);
//   Status render_fwd(const Camera&, const NeuralGaussians<T>&, T* rgb);
//   Status render_bwd(const T* v_rgb, T* v_means, T* v_log_scales, T* v_quats, T* v_opacities,
//                     T* v_colors, T* v_means2d, double* v_pose /*[6] (rho, phi), +=*/);
//   void loss_bwd(int W, int H, const T* image, const T* target, T* v_image, double* l1, double* ssim);
// Memory: StepWorkspace is sized once by reserve(); the step itself allocates nothing.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "gs/camera.h"
#include "gs/model/decode.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/simd/loss.h"
#include "gs/stage_times.h"
#include "gs/status.h"

namespace gs::model {

// What a float Backend's render_fwd hands gs::Renderer: the decoded Gaussians (colours, no SH);
// render_bwd's arrays go through gs::colored_gaussian_grads.
inline GaussianParams gaussian_params(const NeuralGaussians<float>& ng) {
  GaussianParams gp;
  gp.count = ng.count;
  gp.means = ng.means;
  gp.log_scales = ng.log_scales;
  gp.quats = ng.quats;
  gp.opacities = ng.opacities;
  gp.colors = ng.colors;
  return gp;
}

template <class T>
struct ModelParamsT {
  AnchorParams<T> anchors;
  const T* image_raw = nullptr;  // [M, kImageRawDim] when image_feature_dim > 0
  int image_feature_dim = 0;     // G (0: mode none)
  const T* mlp[kMlpCount] = {nullptr, nullptr, nullptr, nullptr};
  simd::MlpShape shapes[kMlpCount];
};

// Gradient destinations, ACCUMULATED (+=); the caller zeroes them. Any may be null except the MLPs.
template <class T>
struct ModelGradsT {
  T* offsets = nullptr;     // [M, k, 3]
  T* log_scales = nullptr;  // [M, 6]
  T* features = nullptr;    // [M, F]
  T* mlp[kMlpCount] = {nullptr, nullptr, nullptr, nullptr};
  // [6] left twist (rho, phi) of the view's world-to-camera pose: through the rasteriser and through
  // the decoder's view-direction and distance inputs (ALGORITHM.md Part A items 4, 7, 14).
  double* pose = nullptr;
};

struct StepConfig {
  double ssim_lambda = simd::kLossLambda;  // (must match the backend's loss parameters)
  double volume_weight = 0.01;             // x mean over kept Gaussians of s_x s_y s_z
  // x mean over kept Gaussians of their opacity: an L1 push towards transparency that the
  // photometric loss must pay for, so Gaussians that do not earn their place fade (and the decoder
  // drops them once the opacity MLP's output is <= 0). 0: no term.
  double opacity_weight = 0;
};

struct StepResult {
  double loss = 0, l1 = 0, ssim = 0, volume = 0, opacity = 0;
  size_t visible_anchors = 0, gaussians = 0;
};

// Buffers of one training or render step. The kept neural Gaussians (ng and its arrays means ...
// source) come from NeuralGaussianBuffers.
// Memory follows the scene: only `rows` is sized for every anchor row (capacity); the buffers of
// the visible anchors (raw ... v_y) hold visible_capacity rows and those of the kept Gaussians
// (ng, v_means ...) gaussian_capacity, which the owner plans from what its views decode (a dry run
// or the counts seen so far). A view that decodes more grows them (ensure_visible /
// ensure_gaussians: with half again of headroom, never past capacity and capacity k; counted in
// replans) before anything is written, so its result is the one a full plan gives.
template <class T>
struct StepWorkspace : NeuralGaussianBuffers<T> {
  std::vector<uint32_t> rows;                         // [cap] visible anchor rows
  std::vector<T> raw, img_hidden, g, v_g;             // [V, R] [V, Hi] [V, G] [V, G]
  std::vector<T> X, v_X, v_x_tmp;                     // [V, D]
  std::vector<T> hidden[3], y[3], v_y[3];             // decoder MLPs: opacity, cov, colour
  std::vector<T> v_means, v_log_scales, v_quats, v_opacities, v_colors, v_means2d, v_ls_volume;
  std::vector<T> rgb, v_rgb;                          // [H, W, 3]
  size_t capacity = 0;           // anchor rows
  size_t visible_capacity = 0;   // visible anchors V the per-anchor buffers hold
  size_t gaussian_capacity = 0;  // kept Gaussians N the per-Gaussian buffers hold
  int replans = 0;               // times a view outgrew the plan (each one allocation)
  // Profiling: when set, decode_view and step_forward_backward add each stage's wall time here
  // (gs/stage_times.h; the renderer's stages are the backend's). Null: one branch per stage.
  StageTimes* stage_times = nullptr;
  // Set by the caller for one step: which pixels of the target exist ([H, W] at the step's size,
  // nonzero: yes; io::DatasetView::valid). Null: all do. step_forward_backward drops the others
  // from the loss (see there).
  const uint8_t* valid_pixels = nullptr;
  std::vector<T> target_filled;  // [H, W, 3] the target with the render in the missing pixels (valid_pixels only)

  // gradients = false: the forward buffers only (rendering and registration decode but never
  // differentiate the decoder), about a third of the bytes. visible / gaussians: the plan for the
  // visible anchors and kept Gaussians of a view (0: every row, cap and cap k; a small plan grows
  // on the first view that needs more).
  void reserve(size_t cap, int k, const simd::MlpShape shapes[kMlpCount], int G, int width, int height,
               bool gradients = true, size_t visible = 0, size_t gaussians = 0) {
    capacity = cap;
    k_ = k;
    G_ = G;
    gradients_ = gradients;
    for (int m = 0; m < kMlpCount; ++m) shapes_[m] = shapes[m];
    rows.assign(cap, 0);
    plan_visible(visible == 0 ? cap : std::min(visible, cap));
    plan_gaussians(gaussians == 0 ? cap * size_t(k) : std::min(gaussians, cap * size_t(k)));
    rgb.assign(size_t(width) * size_t(height) * 3, T(0));
    v_rgb.assign(gradients ? rgb.size() : 0, T(0));
  }
  // The per-visible-anchor buffers for V anchors (contents are not kept).
  void plan_visible(size_t V) {
    visible_capacity = V;
    const size_t D = size_t(shapes_[kMlpOpacity].in), gV = gradients_ ? V : 0;
    if (G_ > 0) {
      raw.assign(V * size_t(kImageRawDim), T(0));
      img_hidden.assign(V * size_t(shapes_[kMlpImage].hidden), T(0));
      g.assign(V * size_t(G_), T(0));
      v_g.assign(gV * size_t(G_), T(0));
    }
    X.assign(V * D, T(0));
    v_X.assign(gV * D, T(0));
    v_x_tmp.assign(gV * D, T(0));
    // Without gradients no MLP's hidden layer is read after its forward: the three share hidden[0].
    size_t shared_hidden = 0;
    for (int m = 0; m < 3; ++m) shared_hidden = std::max(shared_hidden, size_t(shapes_[m].hidden));
    for (int m = 0; m < 3; ++m) {
      hidden[m].assign(gradients_ ? V * size_t(shapes_[m].hidden) : m == 0 ? V * shared_hidden : 0, T(0));
      y[m].assign(V * size_t(shapes_[m].out), T(0));
      v_y[m].assign(gV * size_t(shapes_[m].out), T(0));
    }
  }
  // Frees the gradient buffers (a training run's last evaluation renders without them); reserve()
  // must run again before the next backward step.
  void release_gradients() {
    for (std::vector<T>* v : {&v_g, &v_X, &v_x_tmp, &v_y[0], &v_y[1], &v_y[2], &v_means, &v_log_scales, &v_quats,
                              &v_opacities, &v_colors, &v_means2d, &v_ls_volume, &v_rgb})
      std::vector<T>().swap(*v);
  }
  // The hidden-layer buffer decoder MLP m (opacity, cov, colour) writes in its forward.
  T* hidden_of(int m) { return hidden[gradients_ ? m : 0].data(); }
  // The per-kept-Gaussian buffers for N Gaussians (contents are not kept).
  void plan_gaussians(size_t N) {
    gaussian_capacity = N;
    const size_t gN = gradients_ ? N : 0;
    this->assign_rows(N);
    for (auto* v : {&v_means, &v_log_scales, &v_colors, &v_ls_volume}) v->assign(gN * 3, T(0));
    v_quats.assign(gN * 4, T(0));
    v_opacities.assign(gN, T(0));
    v_means2d.assign(gN * 2, T(0));
  }
  // Grows the plan when a view has more visible anchors / kept Gaussians than it holds.
  void ensure_visible(size_t V) {
    if (V <= visible_capacity) return;
    plan_visible(std::min(capacity, V + V / 2));
    ++replans;
  }
  void ensure_gaussians(size_t N) {
    if (N <= gaussian_capacity) return;
    plan_gaussians(std::min(capacity * size_t(k_), N + N / 2));
    ++replans;
  }

 private:
  int k_ = 1, G_ = 0;
  bool gradients_ = true;
  simd::MlpShape shapes_[kMlpCount];
};

namespace detail {

// The Backend's thread pool (Backend::pool()), or null for a backend without one (the scalar
// references of the tests): the step graph's own loops then run on the calling thread.
template <class Backend>
auto backend_pool(Backend& be, int) -> decltype(be.pool()) {
  return be.pool();
}
template <class Backend>
platform::ThreadPool* backend_pool(Backend&, long) {
  return nullptr;
}

// The three decoder MLPs forward on the same input rows: in one pass when the Backend has
// mlp_fwd_group (FloatBackend), else one after another.
template <class Backend, class T>
auto decoder_mlps_fwd(Backend& be, int, const simd::MlpShape* sh, int32_t V, const T* X, const T* const* params,
                      std::vector<T>* hidden, std::vector<T>* y)
    -> decltype(be.mlp_fwd_group(3, static_cast<const simd::MlpShape* const*>(nullptr), V, X, params,
                                 static_cast<T* const*>(nullptr), static_cast<T* const*>(nullptr))) {
  const simd::MlpShape* shapes[3] = {&sh[0], &sh[1], &sh[2]};
  T* const h[3] = {hidden[0].data(), hidden[1].data(), hidden[2].data()};
  T* const out[3] = {y[0].data(), y[1].data(), y[2].data()};
  return be.mlp_fwd_group(3, shapes, V, X, params, h, out);
}
template <class Backend, class T>
void decoder_mlps_fwd(Backend& be, long, const simd::MlpShape* sh, int32_t V, const T* X, const T* const* params,
                      std::vector<T>* hidden, std::vector<T>* y) {
  for (int m = 0; m < 3; ++m) be.mlp_fwd(sh[m], V, X, params[m], hidden[m].data(), y[m].data());
}

// Splits [0, n) into `parts` contiguous ranges (part i is [i n / parts, (i + 1) n / parts)).
inline size_t part_begin(size_t n, size_t parts, size_t i) { return i * n / parts; }

// How many ranges a loop of n items is split into: a few per thread (they are claimed
// dynamically), none smaller than min_items, at most kMaxParts. Every loop split this way writes
// disjoint outputs or joins its ranges in order, so results do not depend on the split.
constexpr size_t kMaxParts = 64;
inline size_t part_count(platform::ThreadPool* pool, size_t n, size_t min_items) {
  if (!pool || pool->num_threads() <= 1 || n < 2 * min_items) return 1;
  return std::min({kMaxParts, size_t(4 * pool->num_threads()), n / min_items});
}

// f(part, begin, end) for each of `parts` ranges of [0, n), on the pool when there is one.
template <class F>
void for_parts(platform::ThreadPool* pool, size_t n, size_t parts, F&& f) {
  auto body = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) f(i, part_begin(n, parts, i), part_begin(n, parts, i + 1));
  };
  if (pool && parts > 1)
    pool->parallel_for(parts, 1, body);
  else
    body(0, parts, 0);
}

// f(begin, end) over [0, n) split by part_count.
template <class F>
void parallel_ranges(platform::ThreadPool* pool, size_t n, size_t min_items, F&& f) {
  if (n == 0) return;
  for_parts(pool, n, part_count(pool, n, min_items), [&](size_t, size_t b, size_t e) { f(b, e); });
}

// The three decoder MLPs backward: weight gradients accumulate into v_p[m]; the input gradient
// ws.v_X = (v_x of 0 + v_x of 1) + v_x of 2. In two pool passes when the Backend has
// mlp_bwd_decoders (FloatBackend), else MLP by MLP with the sums in between.
template <class Backend, class T>
auto decoder_mlps_bwd(Backend& be, int, platform::ThreadPool*, const simd::MlpShape* sh, int32_t V, size_t,
                      const T* const* params, StepWorkspace<T>& ws, T* const* v_p)
    -> decltype(be.mlp_bwd_decoders(static_cast<const simd::MlpShape* const*>(nullptr), V, ws.X.data(), params,
                                    static_cast<const T* const*>(nullptr), static_cast<const T* const*>(nullptr),
                                    static_cast<const T* const*>(nullptr), ws.v_X.data(), ws.v_x_tmp.data(), v_p)) {
  const simd::MlpShape* shapes[3] = {&sh[0], &sh[1], &sh[2]};
  const T* const hidden[3] = {ws.hidden[0].data(), ws.hidden[1].data(), ws.hidden[2].data()};
  const T* const y[3] = {ws.y[0].data(), ws.y[1].data(), ws.y[2].data()};
  const T* const v_y[3] = {ws.v_y[0].data(), ws.v_y[1].data(), ws.v_y[2].data()};
  return be.mlp_bwd_decoders(shapes, V, ws.X.data(), params, hidden, y, v_y, ws.v_X.data(), ws.v_x_tmp.data(), v_p);
}
template <class Backend, class T>
void decoder_mlps_bwd(Backend& be, long, platform::ThreadPool* pool, const simd::MlpShape* sh, int32_t V, size_t D,
                      const T* const* params, StepWorkspace<T>& ws, T* const* v_p) {
  for (int m = 0; m < 3; ++m) {
    T* v_x = m == 0 ? ws.v_X.data() : ws.v_x_tmp.data();
    be.mlp_bwd(sh[m], V, ws.X.data(), params[m], ws.hidden[m].data(), ws.y[m].data(), ws.v_y[m].data(), v_x, v_p[m]);
    if (m > 0) {
      T* v_X = ws.v_X.data();
      const T* v_tmp = ws.v_x_tmp.data();
      parallel_ranges(pool, size_t(V) * D, 8192, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) v_X[i] += v_tmp[i];
      });
    }
  }
}

}  // namespace detail

// volume_fwd_bwd into v_log_scales (zeroed first), exactly: on a pool the volumes (the exps) are
// computed in parallel ranges into `scratch` (bytes, at least 8 N; the caller lends a buffer that
// is free at this point) and summed afterwards in index order, the serial pass's sum.
template <class T>
double volume_term(platform::ThreadPool* pool, size_t N, const T* log_scales, double weight, T* v_log_scales,
                   void* scratch, size_t scratch_bytes) {
  if (!pool || pool->num_threads() <= 1 || weight == 0 || N < 4096 || scratch_bytes < N * sizeof(double)) {
    std::fill(v_log_scales, v_log_scales + 3 * N, T(0));
    return volume_fwd_bwd(N, log_scales, weight, v_log_scales);
  }
  unsigned char* volumes = static_cast<unsigned char*>(scratch);
  const double w = weight / double(N);
  detail::parallel_ranges(pool, N, 2048, [&](size_t b, size_t e) {
    for (size_t n = b; n < e; ++n) {
      const double vol =
          std::exp(double(log_scales[3 * n]) + double(log_scales[3 * n + 1]) + double(log_scales[3 * n + 2]));
      std::memcpy(volumes + n * sizeof(double), &vol, sizeof(double));
      for (int l = 0; l < 3; ++l) v_log_scales[3 * n + l] = T(0) + T(w * vol);  // volume_fwd_bwd's 0 += ...
    }
  });
  double sum = 0;
  for (size_t n = 0; n < N; ++n) {
    double vol;
    std::memcpy(&vol, volumes + n * sizeof(double), sizeof(double));
    sum += vol;
  }
  return w * sum;
}

// Forward up to the kept neural Gaussians of one view (ws.ng); returns N and sets *visible = V.
// The anchor loops run over the backend's pool (if any) with the results of one thread:
// visibility and decoding are done per range and joined in range order.
template <class T, class Backend>
size_t decode_view(Backend& be, const ModelParamsT<T>& p, const Camera& cam, StepWorkspace<T>& ws, size_t* visible) {
  const AnchorParams<T>& a = p.anchors;
  const int G = p.image_feature_dim;
  const int k = a.k;
  const simd::MlpShape* sh = p.shapes;
  StageClock clock(ws.stage_times);
  platform::ThreadPool* pool = detail::backend_pool(be, 0);
  uint32_t* rows = ws.rows.data();
  size_t part_size[detail::kMaxParts];

  // Visible anchors: each range writes its rows from its own first index on, then the ranges are
  // moved together in order (a range's rows never move past its start, so memmove in order is safe).
  size_t parts = detail::part_count(pool, a.count, 2048);
  detail::for_parts(pool, a.count, parts, [&](size_t i, size_t b, size_t e) {
    part_size[i] = select_visible_anchor_range(cam, a, b, e, rows + b);
  });
  size_t V = parts > 0 && a.count > 0 ? part_size[0] : 0;
  for (size_t i = 1; i < parts; ++i) {
    const size_t b = detail::part_begin(a.count, parts, i);
    if (part_size[i] > 0 && V != b) std::copy(rows + b, rows + b + part_size[i], rows + V);
    V += part_size[i];
  }
  clock.lap(kStageAnchorSelect);
  ws.ensure_visible(V);

  double centre[3];
  camera_centre(cam.pose, centre);
  const T* raw_src = p.image_raw;
  T* raw = ws.raw.data();
  if (G > 0) {
    detail::parallel_ranges(pool, V, 1024, [&](size_t b, size_t e) {
      for (size_t v = b; v < e; ++v)
        std::copy(raw_src + size_t(rows[v]) * kImageRawDim, raw_src + (size_t(rows[v]) + 1) * kImageRawDim,
                  raw + v * kImageRawDim);
    });
    be.mlp_fwd(sh[kMlpImage], int32_t(V), ws.raw.data(), p.mlp[kMlpImage], ws.img_hidden.data(), ws.g.data());
    clock.lap(kStageImageMlpFwd);
  }
  const T* g = G > 0 ? ws.g.data() : static_cast<const T*>(nullptr);
  detail::parallel_ranges(pool, V, 512, [&](size_t b, size_t e) {
    build_decoder_input_range(a, rows, b, e, g, G, centre, ws.X.data());
  });
  clock.lap(kStageDecoderInput);
  if (ws.hidden_of(1) != ws.hidden_of(0)) {  // own hidden layers (training): the three MLPs run together
    detail::decoder_mlps_fwd(be, 0, sh, int32_t(V), ws.X.data(), p.mlp, ws.hidden, ws.y);
  } else {  // no gradients: the three share one hidden buffer, so one after another
    for (int m = 0; m < 3; ++m) be.mlp_fwd(sh[m], int32_t(V), ws.X.data(), p.mlp[m], ws.hidden_of(m), ws.y[m].data());
  }
  clock.lap(kStageDecoderMlpFwd);
  *visible = V;

  // Kept Gaussians: count per range, then each range decodes from its offset (the order of one pass).
  const T* y_op = ws.y[kMlpOpacity].data();
  const T* y_cov = ws.y[kMlpCov].data();
  const T* y_col = ws.y[kMlpColor].data();
  parts = detail::part_count(pool, V, 256);
  if (parts <= 1) {
    if (V * size_t(k) > ws.gaussian_capacity) ws.ensure_gaussians(count_kept_range(k, 0, V, y_op, y_cov));
    ws.ng.count = decode_fwd_range(a, rows, 0, V, y_op, y_cov, y_col, 0, &ws.ng);
    clock.lap(kStageDecodeFwd);
    return ws.ng.count;
  }
  detail::for_parts(pool, V, parts, [&](size_t i, size_t b, size_t e) {
    part_size[i] = count_kept_range(k, b, e, y_op, y_cov);
  });
  size_t part_offset[detail::kMaxParts];
  size_t N = 0;
  for (size_t i = 0; i < parts; ++i) {
    part_offset[i] = N;
    N += part_size[i];
  }
  ws.ensure_gaussians(N);
  detail::for_parts(pool, V, parts, [&](size_t i, size_t b, size_t e) {
    decode_fwd_range(a, rows, b, e, y_op, y_cov, y_col, part_offset[i], &ws.ng);
  });
  ws.ng.count = N;
  clock.lap(kStageDecodeFwd);
  return N;
}

// Drops the pixels ws.valid_pixels marks missing from the loss: the loss runs on a target that
// holds the render itself there (their L1 terms are 0, and an SSIM window wholly inside them is 1),
// their cotangents are zeroed, and the loss becomes the mean over the valid pixels: the others'
// gradients and l1 scale by all / valid pixels, and 1 - ssim too (so ssim is the mean over the
// valid pixels when the missing ones' SSIM is 1; windows straddling the edge see the render in
// place of the missing target). All missing: no gradient, l1 = 0, ssim = 1.
namespace detail {
template <class T>
const T* fill_missing_target(const T* target, const T* rgb, const uint8_t* valid, size_t pixels, std::vector<T>* filled,
                             size_t* valid_count) {
  if (filled->size() < 3 * pixels) filled->assign(3 * pixels, T(0));
  size_t count = 0;
  for (size_t p = 0; p < pixels; ++p) {
    const T* from = valid[p] ? target + 3 * p : rgb + 3 * p;
    count += valid[p] ? 1 : 0;
    for (size_t c = 0; c < 3; ++c) (*filled)[3 * p + c] = from[c];
  }
  *valid_count = count;
  return filled->data();
}
template <class T>
void scale_to_valid(const uint8_t* valid, size_t pixels, size_t valid_count, T* v_rgb, double* l1, double* ssim) {
  const double scale = valid_count ? double(pixels) / double(valid_count) : 0.0;
  for (size_t p = 0; p < pixels; ++p)
    for (size_t c = 0; c < 3; ++c) v_rgb[3 * p + c] = valid[p] ? T(v_rgb[3 * p + c] * scale) : T(0);
  *l1 *= scale;
  *ssim = 1 - (1 - *ssim) * scale;
}
}  // namespace detail

// Runs the graph forward and, if grads != nullptr, backward. target: [H, W, 3] in [0, 1]; pixels
// ws.valid_pixels marks missing are dropped from the loss (detail::fill_missing_target).
template <class T, class Backend>
Status step_forward_backward(Backend& be, const ModelParamsT<T>& p, const Camera& cam, const T* target,
                             const StepConfig& cfg, StepWorkspace<T>& ws, ModelGradsT<T>* grads, StepResult* out) {
  const AnchorParams<T>& a = p.anchors;
  if (a.count > ws.capacity) return capacity_exceeded("training step: more anchors than the workspace plan");
  const int W = cam.intr.width, H = cam.intr.height;
  if (size_t(W) * size_t(H) * 3 > ws.rgb.size()) return capacity_exceeded("training step: image larger than planned");
  const int G = p.image_feature_dim, F = a.feature_dim;
  const simd::MlpShape* sh = p.shapes;
  const size_t D = size_t(sh[kMlpOpacity].in);
  platform::ThreadPool* pool = detail::backend_pool(be, 0);

  size_t V = 0;
  const size_t N = decode_view(be, p, cam, ws, &V);
  const uint32_t* rows = ws.rows.data();
  GS_RETURN_IF_ERROR(be.render_fwd(cam, ws.ng, ws.rgb.data()));
  StageClock clock(ws.stage_times);  // after the renderer's own stages
  double l1 = 0, ssim = 0;
  const size_t pixels = size_t(W) * size_t(H);
  size_t valid_count = pixels;
  const T* loss_target =
      ws.valid_pixels ? detail::fill_missing_target(target, ws.rgb.data(), ws.valid_pixels, pixels, &ws.target_filled, &valid_count)
                      : target;
  be.loss_bwd(W, H, ws.rgb.data(), loss_target, ws.v_rgb.data(), &l1, &ssim);
  if (ws.valid_pixels) detail::scale_to_valid(ws.valid_pixels, pixels, valid_count, ws.v_rgb.data(), &l1, &ssim);
  out->l1 = l1;
  out->ssim = ssim;
  out->visible_anchors = V;
  out->gaussians = N;
  out->volume = volume_term(pool, N, ws.log_scales.data(), cfg.volume_weight, ws.v_ls_volume.data(),
                            ws.v_means2d.data(), ws.v_means2d.size() * sizeof(T));
  out->opacity = 0;
  if (cfg.opacity_weight != 0 && N > 0) {
    double sum = 0;  // serial, in index order: the same bits on any pool
    for (size_t n = 0; n < N; ++n) sum += double(ws.opacities[n]);
    out->opacity = cfg.opacity_weight * sum / double(N);
  }
  out->loss = (1 - cfg.ssim_lambda) * l1 + cfg.ssim_lambda * (1 - ssim) + out->volume + out->opacity;
  clock.lap(kStageLoss);
  if (!grads) return Status::Ok();

  // Backward through the renderer (the volume term adds to its log-scale gradient, the opacity term
  // weight / N to every kept Gaussian's opacity gradient).
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
  GS_RETURN_IF_ERROR(be.render_bwd(ws.v_rgb.data(), ws.v_means.data(), ws.v_log_scales.data(), ws.v_quats.data(),
                                   ws.v_opacities.data(), ws.v_colors.data(), ws.v_means2d.data(), v_pose));
  clock.restart();
  {
    T* v_ls = ws.v_log_scales.data();
    const T* v_vol = ws.v_ls_volume.data();
    detail::parallel_ranges(pool, 3 * N, 8192, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) v_ls[i] += v_vol[i];
    });
    if (cfg.opacity_weight != 0 && N > 0) {
      const T v_op = T(cfg.opacity_weight / double(N));
      T* v_opacities = ws.v_opacities.data();
      for (size_t n = 0; n < N; ++n) v_opacities[n] += v_op;
    }
  }
  clock.lap(kStageLoss);

  // Decode backward: MLP output gradients and the anchor offset / log-scale gradients (ranges of
  // visible anchors own distinct rows, so they run in parallel with the serial pass's sums).
  const GaussianGradsT<T> gg{ws.v_means.data(), ws.v_log_scales.data(), ws.v_quats.data(), ws.v_opacities.data(),
                             ws.v_colors.data()};
  detail::parallel_ranges(pool, V, 256, [&](size_t b, size_t e) {
    decode_bwd_range(a, rows, b, e, ws.y[kMlpCov].data(), ws.ng, gg, ws.v_y[kMlpOpacity].data(),
                     ws.v_y[kMlpCov].data(), ws.v_y[kMlpColor].data(), grads->offsets, grads->log_scales);
  });
  clock.lap(kStageDecodeBwd);

  // Decoder MLPs: weight gradients accumulate; input gradients sum over the three.
  detail::decoder_mlps_bwd(be, 0, pool, sh, int32_t(V), D, p.mlp, ws, grads->mlp);
  clock.lap(kStageMlpBwd);

  // The pose: the rasteriser's twist plus the view-direction / distance inputs through the centre.
  if (grads->pose) {
    double centre[3], v_centre[3] = {0, 0, 0};
    camera_centre(cam.pose, centre);
    decoder_input_centre_bwd(a, rows, V, G, centre, ws.v_X.data(), v_centre);
    centre_grad_to_pose(cam.pose, v_centre, v_pose);
    for (int i = 0; i < 6; ++i) grads->pose[i] += v_pose[i];
    clock.lap(kStageDecodeBwd);  // the decoder input's camera-centre gradient
  }
  // Anchor features and the image-feature MLP.
  // (Per visible anchor: the rows are distinct, so ranges run in parallel.)
  const T* v_X = ws.v_X.data();
  if (grads->features) {
    T* features = grads->features;
    detail::parallel_ranges(pool, V, 512, [&](size_t b, size_t e) {
      for (size_t v = b; v < e; ++v) {
        T* dst = features + size_t(rows[v]) * size_t(F);
        const T* src = v_X + v * D;
        for (int c = 0; c < F; ++c) dst[c] += src[c];
      }
    });
  }
  if (G > 0) {
    T* v_g = ws.v_g.data();
    detail::parallel_ranges(pool, V, 1024, [&](size_t b, size_t e) {
      for (size_t v = b; v < e; ++v) std::copy(v_X + v * D + F, v_X + v * D + F + G, v_g + v * size_t(G));
    });
    be.mlp_bwd(sh[kMlpImage], int32_t(V), ws.raw.data(), p.mlp[kMlpImage], ws.img_hidden.data(), ws.g.data(),
               ws.v_g.data(), static_cast<T*>(nullptr), grads->mlp[kMlpImage]);
  }
  clock.lap(kStageMlpBwd);
  return Status::Ok();
}

}  // namespace gs::model
