// SPDX-License-Identifier: MIT
// Private to gs_model: the float Backend of the step graph (gs/model/step_graph.h) used by the
// trainer and the model renderer: SIMD MLP kernels split over the thread pool in a fixed number of
// row chunks (so results do not depend on the thread count), gs::Renderer and the SIMD loss.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "gs/model/decode.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/quant_decoder.h"
#include "gs/model/step_graph.h"
#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"

namespace gs::model::detail {

// The step graph's view of a model's live anchors and MLPs.
inline ModelParamsT<float> model_params(const HybridModel& model) {
  ModelParamsT<float> p;
  const bool paper = uses_image_features(model.config.image_features);
  p.anchors.count = model.anchor_count;
  p.anchors.k = model.config.k;
  p.anchors.feature_dim = model.config.feature_dim;
  p.anchors.positions = model.positions.data();
  p.anchors.offsets = model.offsets.data();
  p.anchors.log_scales = model.log_scales.data();
  p.anchors.features = model.features.data();
  p.image_raw = paper ? model.image_raw.data() : nullptr;
  p.image_feature_dim = paper ? model.config.image_feature_dim : 0;
  for (int i = 0; i < kMlpCount; ++i) {
    p.mlp[i] = model.mlps[i].params.empty() ? nullptr : model.mlps[i].params.data();
    p.shapes[i] = model.mlps[i].shape;
  }
  return p;
}

// Renderer::forward that re-plans the tile pairs once when a view needs more than planned: their
// count depends on the Gaussians' screen sizes, which training changes, so a view that needs more
// re-plans with 1.5x headroom (a rare allocation, not a per-step one) instead of failing the run.
// Counts the re-plans in *replans (may be null).
inline Status forward_replanning(Renderer* renderer, platform::ThreadPool* pool, const simd::KernelTable* kernels,
                                 const Camera& cam, const GaussianParams& gp, const RenderOptions& ro, float* rgb,
                                 float* depth, int* replans) {
  Status st = renderer->forward(cam, gp, ro, rgb, depth);
  const uint64_t needed = renderer->stats().isects;
  if (st.code() == StatusCode::kCapacityExceeded && needed > renderer->capacity().max_isects && needed < (uint64_t(1) << 31)) {
    RenderCapacity rc = renderer->capacity();
    rc.max_isects = size_t(std::min<uint64_t>(needed + needed / 2, (uint64_t(1) << 31) - 1));
    GS_RETURN_IF_ERROR(renderer->init(rc, pool, kernels));
    if (replans) ++*replans;
    st = renderer->forward(cam, gp, ro, rgb, depth);
  }
  return st;
}

class FloatBackend {
 public:
  static constexpr int kChunks = 8;        // fixed MLP row partition (thread-count independent)
  static constexpr int kMinChunkRows = 64;

  // max_mlp_params: the largest MLP's parameter count (per-chunk gradient buffers). max_height:
  // the tallest image loss_bwd runs on in bands of rows (taller ones, or 0, run in one call).
  void init(Renderer* renderer, const simd::KernelTable* kernels, platform::ThreadPool* pool, size_t max_mlp_params,
            int max_width, int max_height = 0) {
    renderer_ = renderer;
    kt_ = kernels;
    pool_ = pool;
    loss_params_ = simd::make_loss_params();
    loss_scratch_stride_ = simd::loss_scratch_floats(max_width, 1);
    loss_scratch_.assign(loss_scratch_stride_ * size_t(pool ? pool->num_threads() : 1), 0.0f);
    loss_rows_.assign(2 * size_t(std::max(max_height, 0)), 0.0);
    chunk_grads_.assign(2 * size_t(kChunks) * max_mlp_params, 0.0f);  // two MLPs at once (mlp_bwd_decoders)
    max_mlp_params_ = max_mlp_params;
  }

  void mlp_fwd(const simd::MlpShape& s, int32_t batch, const float* x, const float* p, float* hidden, float* y) {
    for (int id = 0; id < kMlpCount; ++id)
      if (int8_ && int8_->mlps[id].present && p == int8_keys_[id]) return mlp_fwd_int8(int8_->mlps[id], batch, x, y);
    const int chunks = chunk_count(batch);
    auto body = [&](size_t b, size_t e, int) {
      for (size_t c = b; c < e; ++c) fwd_chunk(s, batch, chunks, int(c), x, p, hidden, y);
    };
    run(size_t(chunks), body);
  }

  // mlp_fwd of `count` MLPs on the same rows in one pass over the pool (count x the fixed chunks
  // claimed together, so the threads meet once, not once per MLP); each chunk's output is mlp_fwd's.
  void mlp_fwd_group(int count, const simd::MlpShape* const* s, int32_t batch, const float* x, const float* const* p,
                     float* const* hidden, float* const* y) {
    bool any_int8 = false;
    for (int m = 0; m < count; ++m)
      for (int id = 0; id < kMlpCount; ++id) any_int8 |= int8_ && int8_->mlps[id].present && p[m] == int8_keys_[id];
    if (any_int8) {  // the int8 path's row scratch is shared by the MLPs: one at a time
      for (int m = 0; m < count; ++m) mlp_fwd(*s[m], batch, x, p[m], hidden[m], y[m]);
      return;
    }
    const int chunks = chunk_count(batch);
    auto body = [&](size_t b, size_t e, int) {
      for (size_t item = b; item < e; ++item) {
        const int m = int(item) / chunks;
        fwd_chunk(*s[m], batch, chunks, int(item) % chunks, x, p[m], hidden[m], y[m]);
      }
    };
    run(size_t(count) * size_t(chunks), body);
  }

  void mlp_bwd(const simd::MlpShape& s, int32_t batch, const float* x, const float* p, const float* hidden,
               const float* y, const float* v_y, float* v_x, float* v_p) {
    const int chunks = chunk_count(batch);
    auto body = [&](size_t b, size_t e, int) {
      for (size_t c = b; c < e; ++c)
        bwd_chunk(s, batch, chunks, int(c), x, p, hidden, y, v_y, v_x, chunk_grads_.data() + c * max_mlp_params_);
    };
    run(size_t(chunks), body);
    sum_chunk_grads(Mlp::param_count(s), chunks, 0, v_p);
  }

  // The three decoder MLPs backward on the same rows x, as mlp_bwd(m = 0), mlp_bwd(1) into v_tmp,
  // v_x += v_tmp, mlp_bwd(2) into v_tmp, v_x += v_tmp, with the same results, in two passes over
  // the pool instead of five: MLPs 0 and 1 together (2 x the fixed chunks), then per chunk of MLP 2
  // its rows' first sum, its backward and the second sum (a chunk's input-gradient rows are its own).
  void mlp_bwd_decoders(const simd::MlpShape* const* s, int32_t batch, const float* x, const float* const* p,
                        const float* const* hidden, const float* const* y, const float* const* v_y, float* v_x,
                        float* v_tmp, float* const* v_p) {
    const int chunks = chunk_count(batch);
    const size_t in = size_t(s[0]->in);
    auto chunk_bwd = [&](int m, int c, float* v_out, float* g) {
      bwd_chunk(*s[m], batch, chunks, c, x, p[m], hidden[m], y[m], v_y[m], v_out, g);
    };
    auto sum_chunks = [&](int m, size_t first) { sum_chunk_grads(Mlp::param_count(*s[m]), chunks, first, v_p[m]); };
    auto add_rows = [&](int c) {
      int32_t r0, r1;
      chunk_rows(batch, chunks, c, &r0, &r1);
      for (size_t i = size_t(r0) * in; i < size_t(r1) * in; ++i) v_x[i] += v_tmp[i];
    };
    auto pass01 = [&](size_t b, size_t e, int) {
      for (size_t item = b; item < e; ++item) {
        const int m = int(item) / chunks, c = int(item) % chunks;
        chunk_bwd(m, c, m == 0 ? v_x : v_tmp, chunk_grads_.data() + item * max_mlp_params_);
      }
    };
    run(2 * size_t(chunks), pass01);
    sum_chunks(0, 0);
    sum_chunks(1, size_t(chunks));
    auto pass2 = [&](size_t b, size_t e, int) {
      for (size_t c = b; c < e; ++c) {
        add_rows(int(c));
        chunk_bwd(2, int(c), v_tmp, chunk_grads_.data() + c * max_mlp_params_);
        add_rows(int(c));
      }
    };
    run(size_t(chunks), pass2);
    sum_chunks(2, 0);
  }

  Status render_fwd(const Camera& cam, const NeuralGaussians<float>& ng, float* rgb) {
    return render_params(cam, gaussian_params(ng), rgb);
  }
  // The same for any Gaussians with colours (plain Gaussians: gs/model/cloud_decode.h).
  Status render_params(const Camera& cam, const GaussianParams& gp, float* rgb) {
    RenderOptions ro;
#ifdef NDEBUG
    ro.validate_inputs = false;  // decoded values are finite by construction; debug builds check
#endif
    ro.fixed_point = fixed_point_raster;
    for (int c = 0; c < 3; ++c) ro.background[c] = background[c];
    return forward_replanning(renderer_, pool_, kt_, cam, gp, ro, rgb, nullptr, &replans_);
  }
  int replans() const { return replans_; }
  // The pool the step graph's own loops (decode, gradient scatter) run on (null: the calling thread).
  platform::ThreadPool* pool() const { return pool_; }

  // The on-device decode: MLPs whose float parameters are keys[id] run as int8 (qmlp_fwd) with the
  // scratch planned for `rows` rows; null turns it off. The outputs are the float path's (final
  // activation applied), so decoding continues unchanged.
  void set_int8_decoder(const QuantDecoder* qd, const float* const keys[kMlpCount], size_t rows) {
    int8_ = qd;
    for (int id = 0; id < kMlpCount; ++id) int8_keys_[id] = keys ? keys[id] : nullptr;
    if (qd) plan_int8_rows(rows);
  }
  void set_int8_keys(const float* const keys[kMlpCount]) {
    for (int id = 0; id < kMlpCount; ++id) int8_keys_[id] = keys[id];
  }
  // render_fwd blends with the fixed-point tile kernel (RenderOptions::fixed_point): the on-device
  // render path; training never sets it.
  bool fixed_point_raster = false;
  // The colour behind the Gaussians (gs/model/background.h); a training step may change it.
  float background[3] = {0, 0, 0};

  Status render_bwd(const float* v_rgb, float* v_means, float* v_log_scales, float* v_quats, float* v_opacities,
                    float* v_colors, float* v_means2d, double* v_pose) {
    GaussianGrads g = colored_gaussian_grads(v_means, v_log_scales, v_quats, v_opacities, v_colors, v_means2d);
    GS_RETURN_IF_ERROR(renderer_->backward(v_rgb, &g));
    for (int i = 0; i < 6; ++i) v_pose[i] += g.v_pose[i];
    return Status::Ok();
  }

  // In bands of rows over the pool, each with its worker's scratch; the per-row sums are added in
  // row order, so l1 and ssim are the one-call kernel's for any number of bands (loss.h).
  void loss_bwd(int W, int H, const float* image, const float* target, float* v_image, double* l1, double* ssim) {
    if (size_t(H) * 2 > loss_rows_.size()) {
      kt_->loss_bwd(&loss_params_, W, H, image, target, 1.0, loss_scratch_.data(), v_image, l1, ssim);
      return;
    }
    double* row_l1 = loss_rows_.data();
    double* row_ssim = row_l1 + H;
    const int bands = pool_ ? std::max(1, std::min(pool_->num_threads(), H / 32)) : 1;
    auto body = [&](size_t b, size_t e, int worker) {
      for (size_t i = b; i < e; ++i)
        kt_->loss_bwd_rows(&loss_params_, W, H, int32_t(int64_t(H) * int64_t(i) / bands),
                           int32_t(int64_t(H) * int64_t(i + 1) / bands), image, target, 1.0,
                           loss_scratch_.data() + size_t(worker) * loss_scratch_stride_, v_image, row_l1, row_ssim);
    };
    run(size_t(bands), body);
    double sum_l1 = 0, sum_ssim = 0;
    for (int r = 0; r < H; ++r) {
      sum_l1 += row_l1[r];
      sum_ssim += row_ssim[r];
    }
    const double count = double(3 * size_t(W)) * double(H);
    *l1 = sum_l1 / count;
    *ssim = sum_ssim / count;
  }

  void loss_fwd(int W, int H, const float* image, const float* target, double* l1, double* ssim) {
    kt_->loss_fwd(&loss_params_, W, H, image, target, loss_scratch_.data(), l1, ssim);
  }

 private:
  static int chunk_count(int32_t batch) { return std::max(1, std::min(kChunks, int(batch / kMinChunkRows))); }
  static void chunk_rows(int32_t batch, int chunks, int c, int32_t* r0, int32_t* r1) {
    *r0 = int32_t(int64_t(batch) * c / chunks);
    *r1 = int32_t(int64_t(batch) * (c + 1) / chunks);
  }
  // One fixed chunk of rows of an MLP forward (x: batch x in, hidden: batch x hidden, y: batch x out).
  void fwd_chunk(const simd::MlpShape& s, int32_t batch, int chunks, int c, const float* x, const float* p,
                 float* hidden, float* y) const {
    int32_t r0, r1;
    chunk_rows(batch, chunks, c, &r0, &r1);
    if (r1 > r0)
      kt_->mlp_fwd(&s, r1 - r0, x + size_t(r0) * size_t(s.in), p, p + Mlp::off_b1(s), p + Mlp::off_W2(s),
                   p + Mlp::off_b2(s), hidden + size_t(r0) * size_t(s.hidden), y + size_t(r0) * size_t(s.out));
  }
  // One fixed chunk of rows of an MLP backward: the chunk's parameter gradient into g (zeroed first,
  // param_count(s) floats), its input-gradient rows into v_x (nullptr: not wanted).
  void bwd_chunk(const simd::MlpShape& s, int32_t batch, int chunks, int c, const float* x, const float* p,
                 const float* hidden, const float* y, const float* v_y, float* v_x, float* g) const {
    std::fill(g, g + Mlp::param_count(s), 0.0f);
    int32_t r0, r1;
    chunk_rows(batch, chunks, c, &r0, &r1);
    if (r1 <= r0) return;
    kt_->mlp_bwd(&s, r1 - r0, x + size_t(r0) * size_t(s.in), p, p + Mlp::off_b1(s), p + Mlp::off_W2(s),
                 p + Mlp::off_b2(s), hidden + size_t(r0) * size_t(s.hidden), y + size_t(r0) * size_t(s.out),
                 v_y + size_t(r0) * size_t(s.out), v_x ? v_x + size_t(r0) * size_t(s.in) : nullptr, g,
                 g + Mlp::off_b1(s), g + Mlp::off_W2(s), g + Mlp::off_b2(s));
  }
  // v_p += the per-chunk gradients chunk_grads_[first .. first + chunks), in a fixed order (the sum
  // does not depend on the thread count).
  void sum_chunk_grads(size_t np, int chunks, size_t first, float* v_p) const {
    for (int c = 0; c < chunks; ++c) {
      const float* g = chunk_grads_.data() + (first + size_t(c)) * max_mlp_params_;
      for (size_t i = 0; i < np; ++i) v_p[i] += g[i];
    }
  }
  template <class F>
  void run(size_t n, F& body) {
    if (pool_ && n > 1)
      pool_->parallel_for(n, 1, body);
    else
      body(0, n, 0);
  }

  void plan_int8_rows(size_t rows) {
    q_rows_ = rows;
    q_x_.assign(rows * size_t(int8_->max_in), 0);
    q_h_.assign(rows * size_t(int8_->max_hidden), 0);
    q_y_.assign(rows * size_t(int8_->max_out), 0);
  }

  void mlp_fwd_int8(const QuantMlpKernel& k, int32_t batch, const float* x, float* y) {
    // A view with more visible anchors than planned (the workspace grew too): half again of headroom.
    if (size_t(batch) > q_rows_) plan_int8_rows(size_t(batch) + size_t(batch) / 2);
    const int chunks = chunk_count(batch);
    const simd::QMlpParams qp = k.params();
    const size_t I = size_t(k.in), H = size_t(k.hidden), O = size_t(k.out);
    auto body = [&](size_t b, size_t e, int) {
      for (size_t c = b; c < e; ++c) {
        int32_t r0, r1;
        chunk_rows(batch, chunks, int(c), &r0, &r1);
        if (r1 <= r0) continue;
        int16_t* xq = q_x_.data() + size_t(r0) * I;
        const float* xr = x + size_t(r0) * I;
        for (size_t i = 0; i < size_t(r1 - r0) * I; ++i) {
          const float v = std::nearbyint(xr[i] * k.in_inv_scale);
          xq[i] = int16_t(v > 32767.0f ? 32767 : (v < -32767.0f ? -32767 : int(v)));
        }
        int16_t* yq = q_y_.data() + size_t(r0) * O;
        kt_->qmlp_fwd(&qp, r1 - r0, xq, q_h_.data() + size_t(r0) * H, yq);
        float* yr = y + size_t(r0) * O;
        for (size_t i = 0; i < size_t(r1 - r0) * O; ++i) yr[i] = simd::mlp_act2<float>(k.act2, float(yq[i]) * k.out_scale);
      }
    };
    run(size_t(chunks), body);
  }

  Renderer* renderer_ = nullptr;
  const simd::KernelTable* kt_ = nullptr;
  platform::ThreadPool* pool_ = nullptr;
  simd::LossParams loss_params_{};
  std::vector<float> loss_scratch_;  // [workers, loss_scratch_stride_]
  size_t loss_scratch_stride_ = 0;
  std::vector<double> loss_rows_;     // [2, max_height] per-row sums of |d| and of the SSIM map
  std::vector<float> chunk_grads_;
  size_t max_mlp_params_ = 0;
  int replans_ = 0;
  const QuantDecoder* int8_ = nullptr;
  const float* int8_keys_[kMlpCount] = {};
  std::vector<int16_t> q_x_, q_h_, q_y_;
  size_t q_rows_ = 0;  // rows the int8 scratch holds
};

// Tile pairs planned per Gaussian of capacity where the renderer is used through
// FloatBackend::render_params (it re-plans with 1.5x headroom when a view needs more): the trainer
// and ModelRenderer. Training snowmiku_plush at 393 px used at most 1.5 (130k pairs for 88k
// Gaussians of capacity); 8 cost 85 MB of arena per renderer for nothing.
constexpr size_t kReplannedIsectsPerGaussian = 3;

// Plans what rendering a model takes, for `rows` anchor rows and images up to max_width x
// max_height: the renderer (k Gaussians per row, isects_per_gaussian tile pairs each: callers that
// render through FloatBackend::render_params, which re-plans with headroom when a view needs more,
// plan for what views use (training snowmiku_plush: at most 1.5 per row x k); callers that cannot
// re-plan keep 8), the float
// backend and a step workspace whose image buffers are ws_width x ws_height, its visible-anchor and
// kept-Gaussian buffers planned for visible_rows and gaussians (0: rows and rows k; a view that
// needs more grows them, StepWorkspace::ensure_visible). Returns the renderer's capacity (for the
// byte count).
inline Expected<RenderCapacity> plan_model_pipeline(const HybridModel& model, size_t rows, int max_width, int max_height,
                                                    int ws_width, int ws_height, platform::ThreadPool* pool,
                                                    const simd::KernelTable* kernels, Renderer* renderer,
                                                    FloatBackend* backend, StepWorkspace<float>* ws,
                                                    bool training = true, size_t isects_per_gaussian = 8,
                                                    size_t visible_rows = 0, size_t gaussians = 0) {
  const size_t K = size_t(model.config.k);
  RenderCapacity rc;
  rc.max_gaussians = rows * K;
  rc.max_isects = rows * K * isects_per_gaussian;
  rc.max_width = max_width;
  rc.max_height = max_height;
  rc.max_sh_degree = 0;
  GS_RETURN_IF_ERROR(renderer->init(rc, pool, kernels));
  size_t max_params = 0;
  for (const Mlp& m : model.mlps) max_params = std::max(max_params, m.params.size());
  backend->init(renderer, kernels, pool, max_params, max_width, max_height);
  const ModelParamsT<float> p = model_params(model);
  ws->reserve(rows, model.config.k, p.shapes, p.image_feature_dim, ws_width, ws_height, training, visible_rows, gaussians);
  return rc;
}

}  // namespace gs::model::detail
