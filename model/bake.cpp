// SPDX-License-Identifier: MIT
// Baking the anchor model into plain Gaussians with SH colour (gs/model/bake.h): the least-squares
// fit over the cameras, then the optional distillation against the model's renders.
#include "gs/model/bake.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Dense>

#include "float_backend.h"
#include "gs/metrics/image_metrics.h"
#include "gs/model/decode.h"
#include "gs/model/model_renderer.h"
#include "gs/optim/adam.h"
#include "gs/platform/clock.h"
#include "gs/random.h"
#include "gs/render.h"
#include "gs/scene_init.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/ref.h"
#include "gs/stats.h"

namespace gs::model {
namespace {

// Stage 1 accumulators per anchor row (normal matrix of the SH basis over the views that see it)
// and per candidate (right-hand sides, opacity and shape sums).
struct FitSums {
  size_t K = 1, k = 1;
  std::vector<int32_t> views;   // [M] views that see the anchor
  std::vector<double> AtA;      // [M, K, K]
  std::vector<double> Atb;      // [M, k, K, 3] basis x (colour - 0.5)
  std::vector<double> opacity;  // [M, k] sum of max(decoded opacity, 0)
  std::vector<double> weight;   // [M, k] the same sum where it is > 0 (the shape means' weight)
  std::vector<double> log_scale;  // [M, k, 3] opacity-weighted
  std::vector<double> quat;       // [M, k, 4] opacity-weighted, sign-aligned with the running sum
};

// Adds one view: the decoded MLP outputs of its V visible anchors (ws.rows, ws.y).
void accumulate_view(const HybridModel& model, const Camera& cam, size_t V, const StepWorkspace<float>& ws, int degree,
                     FitSums* f) {
  const size_t K = f->K, k = f->k;
  double C[3];
  camera_centre(cam.pose, C);
  const float* y_op = ws.y[kMlpOpacity].data();
  const float* y_cov = ws.y[kMlpCov].data();
  const float* y_col = ws.y[kMlpColor].data();
  for (size_t v = 0; v < V; ++v) {
    const size_t row = ws.rows[v];
    const float* a = &model.positions[3 * row];
    double d[3] = {double(a[0]) - C[0], double(a[1]) - C[1], double(a[2]) - C[2]};
    const double norm = std::max(std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1e-12);
    for (double& x : d) x /= norm;
    double b[16];
    simd::sh_basis_ref<double>(degree, d, b);
    ++f->views[row];
    double* A = &f->AtA[row * K * K];
    for (size_t r = 0; r < K; ++r)
      for (size_t c = 0; c < K; ++c) A[r * K + c] += b[r] * b[c];
    const float* ls = &model.log_scales[6 * row];
    for (size_t j = 0; j < k; ++j) {
      const size_t s = v * k + j, cand = row * k + j;
      double* rhs = &f->Atb[cand * K * 3];
      for (size_t r = 0; r < K; ++r)
        for (int c = 0; c < 3; ++c) rhs[r * 3 + size_t(c)] += b[r] * (double(y_col[3 * s + size_t(c)]) - 0.5);
      const double w = std::max(0.0, double(y_op[s]));
      f->opacity[cand] += w;
      if (!(w > 0)) continue;
      const float* cov = y_cov + 7 * s;
      double q[4] = {cov[3], cov[4], cov[5], cov[6]};
      const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      if (!(qn > 1e-12)) continue;
      f->weight[cand] += w;
      for (int l = 0; l < 3; ++l) f->log_scale[3 * cand + size_t(l)] += w * (double(ls[3 + l]) + double(log_sigmoid(cov[l])));
      double* qs = &f->quat[4 * cand];
      const double dot = qs[0] * q[0] + qs[1] * q[1] + qs[2] * q[2] + qs[3] * q[3];
      const double sign = dot < 0 ? -1.0 : 1.0;  // q and -q are one rotation
      for (int l = 0; l < 4; ++l) qs[l] += w * sign * q[l] / qn;
    }
  }
}

// Turns the sums into the cloud (candidates seen by some view and at least min_opacity).
GaussianCloud solve_fit(const HybridModel& model, const FitSums& f, const BakeOptions& o, BakeStats* st) {
  const size_t K = f.K, k = f.k, M = model.anchor_count;
  GaussianCloud cloud;
  cloud.sh_degree = o.sh_degree;
  Eigen::MatrixXd A(K, K), rhs(K, 3);
  for (size_t row = 0; row < M; ++row) {
    const int32_t n = f.views[row];
    if (n == 0) continue;
    st->seen += k;
    for (size_t r = 0; r < K; ++r)
      for (size_t c = 0; c < K; ++c) A(Eigen::Index(r), Eigen::Index(c)) = f.AtA[(row * K + r) * K + c];
    // Ridge on the directional terms (scaled by the sample count, so its strength does not depend
    // on how many views see the anchor), and a trace of it on the constant so A is never singular.
    for (size_t r = 0; r < K; ++r) A(Eigen::Index(r), Eigen::Index(r)) += (r == 0 ? 1e-9 : o.sh_ridge) * double(n);
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
    const float* pos = &model.positions[3 * row];
    const float* ls = &model.log_scales[6 * row];
    for (size_t j = 0; j < k; ++j) {
      const size_t cand = row * k + j;
      const double opacity = f.opacity[cand] / double(n);
      if (!(opacity >= double(o.min_opacity)) || !(f.weight[cand] > 0)) continue;
      for (size_t r = 0; r < K; ++r)
        for (int c = 0; c < 3; ++c) rhs(Eigen::Index(r), c) = f.Atb[(cand * K + r) * 3 + size_t(c)];
      const Eigen::MatrixXd coef = ldlt.solve(rhs);
      const float* off = &model.offsets[3 * cand];
      for (int l = 0; l < 3; ++l) cloud.means.push_back(pos[l] + off[l] * std::exp(ls[l]));
      for (int l = 0; l < 3; ++l) cloud.log_scales.push_back(float(f.log_scale[3 * cand + size_t(l)] / f.weight[cand]));
      const double* q = &f.quat[4 * cand];
      const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      for (int l = 0; l < 4; ++l) cloud.quats.push_back(qn > 0 ? float(q[l] / qn) : (l == 0 ? 1.0f : 0.0f));
      const double p = std::clamp(opacity, 1e-6, 1.0 - 1e-6);
      cloud.opacity_logits.push_back(float(std::log(p / (1.0 - p))));
      for (size_t r = 0; r < K; ++r)
        for (int c = 0; c < 3; ++c) cloud.sh.push_back(float(coef(Eigen::Index(r), c)));
    }
  }
  st->kept = cloud.size();
  return cloud;
}

// Stage 2 state: the cloud's renderer, gradients and Adam moments per parameter group.
struct Distiller {
  struct Group {
    float* param;
    size_t n;
    double lr;
    std::vector<float> grad, m, v;
  };
  GaussianCloud* cloud = nullptr;
  Renderer renderer;
  RenderCapacity cap;
  std::vector<float> opacity, rgb, v_rgb, target, loss_scratch;
  std::vector<float> v_opacity;  // [N] with respect to the activated opacity
  std::vector<Group> groups;     // means, log_scales, quats, opacity logits, SH DC, SH rest
  simd::LossParams loss_params{};

  Status init(GaussianCloud* c, int max_w, int max_h, const simd::KernelTable* kt, platform::ThreadPool* pool,
              double extent) {
    cloud = c;
    const size_t N = c->size();
    cap.max_gaussians = std::max<size_t>(N, 1);
    cap.max_isects = cap.max_gaussians * 16;
    cap.max_width = max_w;
    cap.max_height = max_h;
    cap.max_sh_degree = c->sh_degree;
    GS_RETURN_IF_ERROR(renderer.init(cap, pool, kt));
    const size_t px = size_t(max_w) * size_t(max_h);
    rgb.assign(3 * px, 0.0f);
    v_rgb.assign(3 * px, 0.0f);
    target.assign(3 * px, 0.0f);
    v_opacity.assign(N, 0.0f);
    loss_params = simd::make_loss_params();
    loss_scratch.assign(simd::loss_scratch_floats(max_w, 1), 0.0f);
    // 3DGS's rates late in its schedule (the cloud starts close to its target).
    auto add = [&](float* p, size_t n, double lr) { groups.push_back({p, n, lr, std::vector<float>(n), std::vector<float>(n), std::vector<float>(n)}); };
    add(c->means.data(), 3 * N, 1.6e-5 * extent);
    add(c->log_scales.data(), 3 * N, 5e-3);
    add(c->quats.data(), 4 * N, 1e-3);
    add(c->opacity_logits.data(), N, 0.025);
    add(c->sh.data(), c->sh.size(), 2.5e-3);  // DC; the rest at 1/20 (step())
    return Status::Ok();
  }

  // Renders the cloud for cam into rgb (re-planning once when the tile pairs outgrow the plan).
  Status forward(const Camera& cam, const float bg[3], const simd::KernelTable* kt, platform::ThreadPool* pool) {
    const GaussianParams gp = activate(*cloud, &opacity);
    RenderOptions ro;
    ro.validate_inputs = false;  // Adam keeps finite inputs finite; bake_model checks the result
    for (int c = 0; c < 3; ++c) ro.background[c] = bg[c];
    Status st = renderer.forward(cam, gp, ro, rgb.data());
    if (st.code() == StatusCode::kCapacityExceeded && renderer.stats().isects > cap.max_isects) {
      cap.max_isects = renderer.stats().isects + renderer.stats().isects / 2;
      GS_RETURN_IF_ERROR(renderer.init(cap, pool, kt));
      st = renderer.forward(cam, gp, ro, rgb.data());
    }
    return st;
  }

  // One step towards target for cam; returns the loss.
  Expected<double> step(const Camera& cam, const float bg[3], int64_t t, const simd::KernelTable* kt, platform::ThreadPool* pool) {
    GS_RETURN_IF_ERROR(forward(cam, bg, kt, pool));
    const int W = cam.intr.width, H = cam.intr.height;
    double l1 = 0, ssim = 0;
    kt->loss_bwd(&loss_params, W, H, rgb.data(), target.data(), 1.0, loss_scratch.data(), v_rgb.data(), &l1, &ssim);
    GaussianGrads g;
    g.v_means = groups[0].grad.data();
    g.v_log_scales = groups[1].grad.data();
    g.v_quats = groups[2].grad.data();
    g.v_opacities = v_opacity.data();
    g.v_sh = groups[4].grad.data();
    GS_RETURN_IF_ERROR(renderer.backward(v_rgb.data(), &g));
    const size_t N = cloud->size();
    for (size_t i = 0; i < N; ++i) groups[3].grad[i] = v_opacity[i] * opacity[i] * (1.0f - opacity[i]);  // d sigmoid
    for (size_t gi = 0; gi < 4; ++gi) {
      Group& gr = groups[gi];
      optim::adam_step(*kt, pool, optim::adam_params(gr.lr, t), gr.n, gr.param, gr.grad.data(), gr.m.data(), gr.v.data());
    }
    Group& sh = groups[4];
    const size_t K = size_t(sh_coeff_count(cloud->sh_degree));
    // SH: the DC coefficients (each Gaussian's first 3 floats) at the full rate, the rest at 1/20 of
    // it (3DGS's feature_lr / 20), so Adam runs on each Gaussian's two slices.
    for (size_t i = 0; i < N; ++i) {
      const size_t base = i * K * 3;
      optim::adam_step(*kt, nullptr, optim::adam_params(sh.lr, t), 3, sh.param + base, sh.grad.data() + base, sh.m.data() + base,
                       sh.v.data() + base);
      if (K > 1)
        optim::adam_step(*kt, nullptr, optim::adam_params(sh.lr / 20, t), 3 * (K - 1), sh.param + base + 3,
                         sh.grad.data() + base + 3, sh.m.data() + base + 3, sh.v.data() + base + 3);
    }
    return (1 - loss_params.lambda) * l1 + loss_params.lambda * (1 - ssim);
  }
};

}  // namespace

Expected<GaussianCloud> bake_model(const HybridModel& model, const std::vector<Camera>& cameras, const BakeOptions& o,
                                   platform::ThreadPool* pool, BakeStats* stats) {
  if (cameras.empty()) return invalid_argument("bake: no cameras to bake over");
  if (o.sh_degree < 0 || o.sh_degree > 3) return invalid_argument("bake: sh_degree must be 0-3");
  if (!(o.sh_ridge >= 0) || !(o.min_opacity >= 0 && o.min_opacity < 1) || o.distill_iterations < 0)
    return invalid_argument("bake: sh_ridge must be >= 0, min_opacity in [0, 1) and distill_iterations >= 0");
  GS_RETURN_IF_ERROR(model.config.validate());
  if (model.anchor_count == 0) return invalid_argument("bake: the model has no anchors");
  int max_w = 1, max_h = 1;
  for (const Camera& c : cameras) {
    GS_RETURN_IF_ERROR(validate_camera(c));
    max_w = std::max(max_w, c.intr.width);
    max_h = std::max(max_h, c.intr.height);
  }
  const simd::KernelTable* kt = &simd::best_kernel_table();
  BakeStats st;
  const double t0 = platform::now_seconds();

  // Stage 1: decode every camera's visible anchors once and accumulate.
  FitSums f;
  {
    Renderer renderer;
    detail::FloatBackend backend;
    StepWorkspace<float> ws;
    Expected<RenderCapacity> rc = detail::plan_model_pipeline(model, model.anchor_count, max_w, max_h, 1, 1, pool, kt, &renderer,
                                                              &backend, &ws, /*training=*/false);
    if (!rc.ok()) return rc.status();
    const size_t M = model.anchor_count, k = size_t(model.config.k), K = size_t(sh_coeff_count(o.sh_degree));
    f.K = K;
    f.k = k;
    f.views.assign(M, 0);
    f.AtA.assign(M * K * K, 0.0);
    f.Atb.assign(M * k * K * 3, 0.0);
    f.opacity.assign(M * k, 0.0);
    f.weight.assign(M * k, 0.0);
    f.log_scale.assign(M * k * 3, 0.0);
    f.quat.assign(M * k * 4, 0.0);
    const ModelParamsT<float> p = detail::model_params(model);
    for (const Camera& cam : cameras) {
      size_t V = 0;
      decode_view(backend, p, cam, ws, &V);
      accumulate_view(model, cam, V, ws, o.sh_degree, &f);
    }
    st.candidates = M * k;
  }
  GaussianCloud cloud = solve_fit(model, f, o, &st);
  f = FitSums{};
  st.fit_seconds = platform::now_seconds() - t0;
  if (cloud.size() == 0) return invalid_argument("bake: no Gaussian of the model is visible from the cameras");

  // Stage 2: distillation against the model's renders (and the PSNR before and after). The renders
  // are made once and kept in 16 bits per channel (a step of 1/65535, far below an 8-bit level):
  // each is used once per epoch, and rendering the model again every step cost as much as the step.
  Distiller d;
  GS_RETURN_IF_ERROR(d.init(&cloud, max_w, max_h, kt, pool, double(model.scene_extent)));
  std::vector<size_t> offset(cameras.size() + 1, 0);
  for (size_t i = 0; i < cameras.size(); ++i)
    offset[i + 1] = offset[i] + size_t(cameras[i].intr.width) * size_t(cameras[i].intr.height) * 3;
  std::vector<uint16_t> targets(offset.back());
  {
    ModelRenderer model_renderer;
    ModelRenderOptions mro;
    std::copy(o.background, o.background + 3, mro.background);
    GS_RETURN_IF_ERROR(model_renderer.set_options(mro));
    GS_RETURN_IF_ERROR(model_renderer.init(model, max_w, max_h, pool, kt));
    for (size_t i = 0; i < cameras.size(); ++i) {
      GS_RETURN_IF_ERROR(model_renderer.render(model, cameras[i], d.target.data()));
      for (size_t j = 0; j < offset[i + 1] - offset[i]; ++j)
        targets[offset[i] + j] = uint16_t(std::lround(std::clamp(d.target[j], 0.0f, 1.0f) * 65535.0f));
    }
  }
  auto load_target = [&](size_t i) {
    for (size_t j = 0; j < offset[i + 1] - offset[i]; ++j) d.target[j] = float(targets[offset[i] + j]) * (1.0f / 65535.0f);
  };
  auto mean_psnr = [&]() -> Expected<double> {
    double sum = 0;
    for (size_t i = 0; i < cameras.size(); ++i) {
      load_target(i);
      GS_RETURN_IF_ERROR(d.forward(cameras[i], o.background, kt, pool));
      sum += metrics::psnr_f32(d.rgb.data(), d.target.data(), offset[i + 1] - offset[i]);
    }
    return sum / double(cameras.size());
  };
  Expected<double> before = mean_psnr();
  if (!before.ok()) return before.status();
  st.psnr_fit = *before;
  if (o.distill_iterations > 0) {
    const double t1 = platform::now_seconds();
    SplitMix64 rng;
    rng.state = o.seed * 0x9E3779B97F4A7C15ull + 11;
    std::vector<size_t> order(cameras.size());
    size_t pos = order.size();
    for (int it = 1; it <= o.distill_iterations; ++it) {
      if (pos == order.size()) {  // a new epoch: shuffle the cameras
        std::iota(order.begin(), order.end(), size_t(0));
        for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng.next() % i]);
        pos = 0;
      }
      const size_t i = order[pos++];
      load_target(i);
      Expected<double> loss = d.step(cameras[i], o.background, it, kt, pool);
      if (!loss.ok()) return loss.status();
    }
    st.distill_seconds = platform::now_seconds() - t1;
    Expected<double> after = mean_psnr();
    if (!after.ok()) return after.status();
    st.psnr_distilled = *after;
  }
  std::vector<float> opacities;
  if (Status v = validate_gaussians(activate(cloud, &opacities)); !v.ok())
    return numerical_error("bake: the distillation diverged (" + v.message() + "); try fewer --distill steps");
  if (stats) *stats = st;
  return cloud;
}

}  // namespace gs::model
