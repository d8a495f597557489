// SPDX-License-Identifier: MIT
// The whole training step graph (gs/model/step_graph.h) checked end to end:
//  * in double, with a backend made of the scalar references (mlp_*_ref, gs::ref renderer,
//    loss_bwd_ref), finite differences of StepResult::loss against the accumulated ModelGradsT
//    gradient of every parameter group: the four MLPs (including the image-feature MLP F), anchor
//    features, offsets and anchor log-scales, with image features on (G > 0) and off;
//  * in float, with the production kernels (best SIMD table MLPs and loss, gs::Renderer), against
//    the double gradients on the same parameters.
//
// Boundary band (STYLE.md 8): a probe is skipped when the discrete structure of the forward differs
// anywhere in x +- 2h: the reference renderer's signature, the visible anchor rows, the kept
// candidates (count and sources), the ReLU patterns of the MLPs and the signs of the L1 residuals.
// Skips are counted and bounded so the check cannot pass vacuously.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "gs/hash.h"
#include "gs/model/step_graph.h"
#include "gs/render.h"
#include "gs/render_ref.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/loss.h"
#include "gs/simd/mlp.h"
#include "support/random_scene.h"
#include "support/reduced.h"

namespace gs::model {
namespace {

using simd::MlpAct;
using simd::MlpShape;

// 4-point central difference with h = 1e-5 max(1, |x|). The loss is O(0.3) and computed in double
// (each evaluation carries ~1e-15 of rounding), so the difference has ~1e-15 / 1e-5 = 1e-10 of noise
// and negligible truncation (O(h^4)). Tolerance: relative 1e-5 plus absolute 2e-9; an analytic
// gradient is exact, so a real error (a wrong factor, a missing term) is orders of magnitude above.
constexpr double kStep = 1e-5;
constexpr double kRelTol = 1e-5;
constexpr double kAbsTol = 2e-9;
constexpr double kMaxSkipFraction = 0.2;

// gs::hash_combine then a multiply by the FNV prime (spreads each step's bits).
uint64_t mix(uint64_t h, uint64_t v) { return hash_combine(h, v) * 0x100000001b3ull; }

// Backend<double> of the scalar references; records a hash of every discrete decision.
struct RefBackend {
  simd::LossParams lp = simd::make_loss_params();
  std::vector<double> scratch;
  ref::Scene<double> scene;
  ref::View<double> view;
  ref::Forward<double> fwd;
  uint64_t signature = 0;
  double render_pose[6] = {0, 0, 0, 0, 0, 0};  // the rasteriser's share of the last pose gradient
  size_t N = 0;

  void mlp_fwd(const MlpShape& s, int32_t B, const double* x, const double* p, double* hidden, double* y) {
    simd::mlp_fwd_ref<double>(&s, B, x, p, p + Mlp::off_b1(s), p + Mlp::off_W2(s), p + Mlp::off_b2(s), hidden, y);
    for (size_t i = 0; i < size_t(B) * size_t(s.hidden); ++i) signature = mix(signature, hidden[i] > 0 ? 1 : 2);
  }
  void mlp_bwd(const MlpShape& s, int32_t B, const double* x, const double* p, const double* hidden, const double* y,
               const double* v_y, double* v_x, double* v_p) {
    simd::mlp_bwd_ref<double>(&s, B, x, p, p + Mlp::off_b1(s), p + Mlp::off_W2(s), p + Mlp::off_b2(s), hidden, y, v_y, v_x, v_p,
                              v_p + Mlp::off_b1(s), v_p + Mlp::off_W2(s), v_p + Mlp::off_b2(s));
  }
  Status render_fwd(const Camera& cam, const NeuralGaussians<double>& ng, double* rgb) {
    N = ng.count;
    scene.n = N;
    scene.sh_degree = -1;
    scene.means.assign(ng.means, ng.means + 3 * N);
    scene.log_scales.assign(ng.log_scales, ng.log_scales + 3 * N);
    scene.quats.assign(ng.quats, ng.quats + 4 * N);
    scene.opacities.assign(ng.opacities, ng.opacities + N);
    scene.colors.assign(ng.colors, ng.colors + 3 * N);
    for (int i = 0; i < 9; ++i) view.R[i] = cam.pose.R[i];
    for (int i = 0; i < 3; ++i) view.t[i] = cam.pose.t[i];
    view.fx = cam.intr.fx, view.fy = cam.intr.fy, view.cx = cam.intr.cx, view.cy = cam.intr.cy;
    view.width = cam.intr.width, view.height = cam.intr.height;
    fwd = ref::render_fwd(scene, view);
    signature = mix(signature, fwd.signature);
    std::copy(fwd.rgb.begin(), fwd.rgb.end(), rgb);
    return Status::Ok();
  }
  Status render_bwd(const double* v_rgb, double* v_means, double* v_log_scales, double* v_quats, double* v_opacities,
                    double* v_colors, double* v_means2d, double* v_pose) {
    const ref::Grads<double> g = ref::render_bwd(scene, view, fwd, v_rgb);
    for (int i = 0; i < 6; ++i) v_pose[i] += render_pose[i] = g.v_pose[i];
    std::copy(g.v_means.begin(), g.v_means.begin() + long(3 * N), v_means);
    std::copy(g.v_log_scales.begin(), g.v_log_scales.begin() + long(3 * N), v_log_scales);
    std::copy(g.v_quats.begin(), g.v_quats.begin() + long(4 * N), v_quats);
    std::copy(g.v_opacities.begin(), g.v_opacities.begin() + long(N), v_opacities);
    std::copy(g.v_colors.begin(), g.v_colors.begin() + long(3 * N), v_colors);
    std::copy(g.v_means2d.begin(), g.v_means2d.begin() + long(2 * N), v_means2d);
    return Status::Ok();
  }
  void loss_bwd(int W, int H, const double* image, const double* target, double* v_image, double* l1, double* ssim) {
    scratch.resize(simd::loss_scratch_floats(W, H));
    simd::loss_bwd_ref<double>(&lp, W, H, image, target, 1.0, scratch.data(), v_image, l1, ssim);
    for (size_t i = 0; i < size_t(W) * size_t(H) * 3; ++i) signature = mix(signature, image[i] > target[i] ? 1 : 2);
  }
};

// Backend<float> of the production kernels: best SIMD table MLPs and loss, gs::Renderer.
struct FloatBackend {
  const simd::KernelTable* kt = &simd::best_kernel_table();
  simd::LossParams lp = simd::make_loss_params();
  std::vector<float> scratch;
  Renderer renderer;
  size_t N = 0;

  Status init(size_t max_gaussians, int W, int H) {
    scratch.assign(simd::loss_scratch_floats(W, H), 0.0f);
    RenderCapacity cap;
    cap.max_gaussians = max_gaussians;
    cap.max_width = W;
    cap.max_height = H;
    cap.max_sh_degree = 0;
    return renderer.init(cap, nullptr, kt);
  }
  void mlp_fwd(const MlpShape& s, int32_t B, const float* x, const float* p, float* hidden, float* y) {
    kt->mlp_fwd(&s, B, x, p, p + Mlp::off_b1(s), p + Mlp::off_W2(s), p + Mlp::off_b2(s), hidden, y);
  }
  void mlp_bwd(const MlpShape& s, int32_t B, const float* x, const float* p, const float* hidden, const float* y,
               const float* v_y, float* v_x, float* v_p) {
    kt->mlp_bwd(&s, B, x, p, p + Mlp::off_b1(s), p + Mlp::off_W2(s), p + Mlp::off_b2(s), hidden, y, v_y, v_x, v_p,
                v_p + Mlp::off_b1(s), v_p + Mlp::off_W2(s), v_p + Mlp::off_b2(s));
  }
  Status render_fwd(const Camera& cam, const NeuralGaussians<float>& ng, float* rgb) {
    N = ng.count;
    return renderer.forward(cam, gaussian_params(ng), RenderOptions{}, rgb);
  }
  Status render_bwd(const float* v_rgb, float* v_means, float* v_log_scales, float* v_quats, float* v_opacities,
                    float* v_colors, float* v_means2d, double* v_pose) {
    GaussianGrads g = colored_gaussian_grads(v_means, v_log_scales, v_quats, v_opacities, v_colors, v_means2d);
    GS_RETURN_IF_ERROR(renderer.backward(v_rgb, &g));
    for (int i = 0; i < 6; ++i) v_pose[i] += g.v_pose[i];
    return Status::Ok();
  }
  void loss_bwd(int W, int H, const float* image, const float* target, float* v_image, double* l1, double* ssim) {
    kt->loss_bwd(&lp, W, H, image, target, 1.0, scratch.data(), v_image, l1, ssim);
  }
};

// A small model in double: M anchors (one behind the camera), k offsets, random features,
// offsets, log-scales, image features and MLP weights, a 24 x 18 view and a random target.
struct Problem {
  int W = 24, H = 18;
  size_t M = 10;
  int k = 4, F = 6, hidden = 8, G = 0, Hi = 6;
  Camera cam;
  MlpShape shapes[kMlpCount];
  std::vector<double> positions, offsets, log_scales, features, image_raw, target;
  std::vector<double> mlp[kMlpCount];

  Problem(uint64_t seed, bool image_features) {
    G = image_features ? 3 : 0;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::normal_distribution<double> nrm(0, 1);
    ref::View<double> v = test::random_view(rng, W, H);
    v.fx = v.fy = 22;
    cam = test::to_camera(test::to_float(v));
    // Positions: camera-space points in the frustum at depth 2.5-4, mapped to world; the last
    // anchor sits behind the camera (never visible: its gradients must stay zero).
    for (size_t i = 0; i < M; ++i) {
      const double z = i + 1 == M ? -3.0 : 2.5 + 0.75 * (1 + u(rng));
      const double px = W * (0.5 + 0.4 * u(rng)), py = H * (0.5 + 0.4 * u(rng));
      const double c[3] = {(px - cam.intr.cx) / cam.intr.fx * z - cam.pose.t[0], (py - cam.intr.cy) / cam.intr.fy * z - cam.pose.t[1],
                           z - cam.pose.t[2]};
      for (int a = 0; a < 3; ++a)
        positions.push_back(cam.pose.R[a] * c[0] + cam.pose.R[3 + a] * c[1] + cam.pose.R[6 + a] * c[2]);
    }
    offsets.resize(M * size_t(k) * 3);
    for (double& x : offsets) x = nrm(rng);
    for (size_t i = 0; i < M; ++i) {
      for (int a = 0; a < 3; ++a) log_scales.push_back(std::log(0.3) + 0.3 * u(rng));
      for (int a = 0; a < 3; ++a) log_scales.push_back(std::log(0.35) + 0.3 * u(rng));
    }
    features.resize(M * size_t(F));
    for (double& x : features) x = nrm(rng);
    if (G > 0) {
      image_raw.resize(M * size_t(kImageRawDim));
      for (size_t i = 0; i < M; ++i) {
        double* r = &image_raw[i * kImageRawDim];
        for (int c = 0; c < 9; ++c) r[c] = 0.5 + 0.5 * u(rng);
        for (int c = 9; c < 12; ++c) r[c] = 0.2 * u(rng);
        r[12] = 1;
      }
    }
    const int D = F + G + 4;
    shapes[kMlpOpacity] = {D, hidden, k, MlpAct::kTanh};
    shapes[kMlpCov] = {D, hidden, 7 * k, MlpAct::kNone};
    shapes[kMlpColor] = {D, hidden, 3 * k, MlpAct::kSigmoid};
    shapes[kMlpImage] = {kImageRawDim, Hi, G > 0 ? G : 1, MlpAct::kNone};  // as create_model
    for (int m = 0; m < kMlpCount; ++m) {
      const MlpShape& s = shapes[m];
      mlp[m].resize(Mlp::param_count(s));
      // PyTorch default init: U(-1/sqrt(fan_in), 1/sqrt(fan_in)) per layer.
      const double a1 = 1 / std::sqrt(double(s.in)), a2 = 1 / std::sqrt(double(s.hidden));
      for (size_t i = 0; i < mlp[m].size(); ++i) mlp[m][i] = (i < Mlp::off_W2(s) ? a1 : a2) * u(rng);
    }
    // Bias the opacity MLP so that most (not all) candidates are kept (tanh > 0).
    for (int j = 0; j < k; ++j) mlp[kMlpOpacity][Mlp::off_b2(shapes[kMlpOpacity]) + size_t(j)] += 0.15;
    target.resize(size_t(W) * size_t(H) * 3);
    for (double& x : target) x = 0.5 + 0.45 * u(rng);
  }
};

template <class T>
std::vector<T> cast(const std::vector<double>& v) {
  return std::vector<T>(v.begin(), v.end());
}

template <class T>
struct Bound {
  std::vector<T> positions, offsets, log_scales, features, image_raw, target;
  std::vector<T> mlp[kMlpCount];
  std::vector<T> g_offsets, g_log_scales, g_features, g_mlp[kMlpCount];
  ModelParamsT<T> params;
  ModelGradsT<T> grads;

  explicit Bound(const Problem& p) {
    positions = cast<T>(p.positions);
    offsets = cast<T>(p.offsets);
    log_scales = cast<T>(p.log_scales);
    features = cast<T>(p.features);
    image_raw = cast<T>(p.image_raw);
    target = cast<T>(p.target);
    for (int m = 0; m < kMlpCount; ++m) mlp[m] = cast<T>(p.mlp[m]);
    g_offsets.assign(offsets.size(), T(0));
    g_log_scales.assign(log_scales.size(), T(0));
    g_features.assign(features.size(), T(0));
    for (int m = 0; m < kMlpCount; ++m) g_mlp[m].assign(mlp[m].size(), T(0));
    AnchorParams<T>& a = params.anchors;
    a.count = p.M;
    a.k = p.k;
    a.feature_dim = p.F;
    a.positions = positions.data();
    a.offsets = offsets.data();
    a.log_scales = log_scales.data();
    a.features = features.data();
    params.image_raw = p.G > 0 ? image_raw.data() : nullptr;
    params.image_feature_dim = p.G;
    for (int m = 0; m < kMlpCount; ++m) {
      params.shapes[m] = p.shapes[m];
      params.mlp[m] = mlp[m].data();
    }
    grads.offsets = g_offsets.data();
    grads.log_scales = g_log_scales.data();
    grads.features = g_features.data();
    for (int m = 0; m < kMlpCount; ++m) grads.mlp[m] = g_mlp[m].data();
  }
};

struct Tally {
  int probes = 0, skipped = 0, failures = 0, nontrivial = 0;
  double worst = 0;  // relative, over probes with |gradient| > 1e-6
};

void check_step_fd(uint64_t seed, bool image_features) {
  CAPTURE(seed);
  CAPTURE(image_features);
  const Problem prob(seed, image_features);
  Bound<double> b(prob);
  RefBackend be;
  StepWorkspace<double> ws;
  ws.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  StepConfig cfg;
  cfg.opacity_weight = 0.05;  // the opacity term's gradient is checked with the rest
  StepResult r0;
  REQUIRE(step_forward_backward(be, b.params, prob.cam, b.target.data(), cfg, ws, &b.grads, &r0).ok());
  MESSAGE("seed " << seed << std::string(image_features ? " (paper)" : " (none)") << ": loss " << r0.loss << ", " << r0.visible_anchors
                  << " visible anchors, " << r0.gaussians << " Gaussians");
  REQUIRE(r0.visible_anchors == prob.M - 1);  // all but the one behind the camera
  REQUIRE(r0.gaussians >= size_t(prob.M));    // a good share of candidates kept
  CHECK(r0.loss ==
        doctest::Approx((1 - cfg.ssim_lambda) * r0.l1 + cfg.ssim_lambda * (1 - r0.ssim) + r0.volume + r0.opacity));
  CHECK(r0.volume > 0);
  CHECK(r0.opacity > 0);

  // Structure of a forward: backend signature, visible rows, kept sources.
  auto forward = [&](uint64_t* sig) {
    be.signature = 0;
    StepResult r;
    const Status st = step_forward_backward(be, b.params, prob.cam, b.target.data(), cfg, ws, static_cast<ModelGradsT<double>*>(nullptr), &r);
    REQUIRE(st.ok());
    uint64_t h = mix(be.signature, r.gaussians);
    h = mix(h, r.visible_anchors);
    for (size_t v = 0; v < r.visible_anchors; ++v) h = mix(h, ws.rows[v]);
    for (size_t n = 0; n < r.gaussians; ++n) h = mix(h, ws.source[n]);
    *sig = h;
    return r.loss;
  };
  uint64_t sig0 = 0;
  const double l0 = forward(&sig0);
  CHECK(l0 == r0.loss);  // the gradient pass does not change the forward

  Tally total;
  std::mt19937_64 pick(seed * 7 + 1);
  auto probe = [&](const std::string& group, std::vector<double>& arr, size_t i, double analytic, Tally* t) {
    double* slot = &arr[i];
    const double x0 = *slot, h = kStep * std::max(1.0, std::fabs(x0));
    const double off[4] = {-2 * h, -h, h, 2 * h};
    double l[4];
    bool flip = false;
    for (int q = 0; q < 4; ++q) {
      *slot = x0 + off[q];
      uint64_t sig = 0;
      l[q] = forward(&sig);
      flip = flip || sig != sig0;
    }
    *slot = x0;
    ++t->probes;
    if (flip) {
      ++t->skipped;
      return;
    }
    const double fd = (8 * (l[2] - l[1]) - (l[3] - l[0])) / (12 * h);
    const double diff = std::fabs(fd - analytic);
    if (std::fabs(analytic) > 1e-6) {
      ++t->nontrivial;
      t->worst = std::max(t->worst, diff / std::fabs(analytic));
    }
    if (diff > kRelTol * std::max(std::fabs(fd), std::fabs(analytic)) + kAbsTol) {
      ++t->failures;
      MESSAGE(group << "[" << i << "]: finite difference " << fd << " vs analytic " << analytic);
    }
  };
  auto sample = [&](size_t lo, size_t hi, int count) {
    std::vector<size_t> idx;
    std::uniform_int_distribution<size_t> d(lo, hi - 1);
    for (int c = 0; c < count; ++c) idx.push_back(d(pick));
    return idx;
  };
  auto run_group = [&](const std::string& group, std::vector<double>& arr, const std::vector<double>& grad,
                       const std::vector<size_t>& idx, int min_nontrivial) {
    Tally t;
    for (size_t i : idx) probe(group, arr, i, grad[i], &t);
    MESSAGE("  " << group << ": " << t.probes << " probes, " << t.skipped << " in the boundary band, " << t.nontrivial
                 << " with |g| > 1e-6, worst relative error " << t.worst);
    CHECK_MESSAGE(t.nontrivial >= min_nontrivial, group << ": too few non-zero gradients probed");
    total.probes += t.probes, total.skipped += t.skipped, total.failures += t.failures, total.nontrivial += t.nontrivial;
    total.worst = std::max(total.worst, t.worst);
  };

  const char* names[kMlpCount] = {"mlp opacity", "mlp cov", "mlp colour", "mlp image F"};
  for (int m = 0; m < kMlpCount; ++m) {
    if (m == kMlpImage && prob.G == 0) continue;
    const MlpShape& s = prob.shapes[m];
    std::vector<size_t> idx;
    for (size_t i : sample(0, Mlp::off_b1(s), 10)) idx.push_back(i);
    for (size_t i : sample(Mlp::off_b1(s), Mlp::off_W2(s), 4)) idx.push_back(i);
    for (size_t i : sample(Mlp::off_W2(s), Mlp::off_b2(s), 10)) idx.push_back(i);
    for (size_t i : sample(Mlp::off_b2(s), Mlp::param_count(s), 4)) idx.push_back(i);
    run_group(names[m], b.mlp[m], b.g_mlp[m], idx, 10);
  }
  // Anchor parameters of the visible anchors (rows 0..M-2), and every parameter of the invisible one.
  const size_t Mv = prob.M - 1, k = size_t(prob.k), F = size_t(prob.F);
  run_group("anchor features", b.features, b.g_features, sample(0, Mv * F, 24), 12);
  run_group("offsets", b.offsets, b.g_offsets, sample(0, Mv * k * 3, 24), 12);
  std::vector<size_t> all_ls;
  for (size_t i = 0; i < 6 * Mv; ++i) all_ls.push_back(i);
  run_group("anchor log-scales", b.log_scales, b.g_log_scales, all_ls, int(3 * Mv));

  MESSAGE("  total: " << total.probes << " probes, " << total.skipped << " skipped, worst relative error " << total.worst);
  CHECK(total.failures == 0);
  CHECK(total.skipped <= int(kMaxSkipFraction * total.probes));

  // The anchor behind the camera: exactly zero gradients.
  const size_t last = prob.M - 1;
  for (size_t i = 0; i < F; ++i) CHECK(b.g_features[last * F + i] == 0);
  for (size_t i = 0; i < 3 * k; ++i) CHECK(b.g_offsets[last * 3 * k + i] == 0);
  for (size_t i = 0; i < 6; ++i) CHECK(b.g_log_scales[6 * last + i] == 0);
  // Mode none: the image MLP is untouched.
  if (prob.G == 0)
    for (double g : b.g_mlp[kMlpImage]) CHECK(g == 0);
}

TEST_CASE("step graph: finite differences of the loss with image features (paper mode)") {
  for (uint64_t seed : gs::test::full_or_first<uint64_t>({1, 2}, 1)) check_step_fd(seed, true);
}

TEST_CASE("step graph: finite differences of the loss without image features (none mode)") {
  for (uint64_t seed : gs::test::full_or_first<uint64_t>({3, 4}, 1)) check_step_fd(seed, false);
}

TEST_CASE("step graph: gradients accumulate across calls and the gradient pass repeats exactly") {
  const Problem prob(5, true);
  Bound<double> b(prob);
  RefBackend be;
  StepWorkspace<double> ws;
  ws.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  StepResult r;
  REQUIRE(step_forward_backward(be, b.params, prob.cam, b.target.data(), StepConfig{}, ws, &b.grads, &r).ok());
  const std::vector<double> once_f = b.g_features, once_o = b.g_offsets, once_m = b.g_mlp[kMlpImage];
  REQUIRE(step_forward_backward(be, b.params, prob.cam, b.target.data(), StepConfig{}, ws, &b.grads, &r).ok());
  double norm = 0;
  for (size_t i = 0; i < once_f.size(); ++i) {
    CHECK(b.g_features[i] == 2 * once_f[i]);
    norm += std::fabs(once_f[i]);
  }
  for (size_t i = 0; i < once_o.size(); ++i) CHECK(b.g_offsets[i] == 2 * once_o[i]);
  // (MLP weight gradients sum over rows, so the second pass rounds differently: approximate.)
  for (size_t i = 0; i < once_m.size(); ++i) CHECK(b.g_mlp[kMlpImage][i] == doctest::Approx(2 * once_m[i]).epsilon(1e-12));
  CHECK(norm > 0);
  // A workspace planned for fewer anchors is refused, not overrun.
  StepWorkspace<double> small;
  small.reserve(prob.M - 1, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  CHECK(step_forward_backward(be, b.params, prob.cam, b.target.data(), StepConfig{}, small, &b.grads, &r).code() ==
        StatusCode::kCapacityExceeded);
}

// Pixels a view has no source for (io::DatasetView::valid, set per step as ws.valid_pixels) are
// dropped from the loss: an all-valid map changes nothing, the target's values there do not matter,
// and l1 is the mean absolute error over the valid pixels.
TEST_CASE("step graph: pixels marked missing are dropped from the loss") {
  const Problem prob(6, false);
  RefBackend be;
  StepWorkspace<double> ws;
  ws.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  const size_t pixels = size_t(prob.W) * size_t(prob.H);
  auto run = [&](const std::vector<uint8_t>* valid, const std::vector<double>& target, Bound<double>* b, StepResult* r) {
    b->target = target;
    ws.valid_pixels = valid ? valid->data() : nullptr;
    StepConfig cfg;
    cfg.volume_weight = 0;  // the photometric loss only (the volume term has gradients of its own)
    REQUIRE(step_forward_backward(be, b->params, prob.cam, b->target.data(), cfg, ws, &b->grads, r).ok());
    ws.valid_pixels = nullptr;
  };
  Bound<double> plain(prob), all(prob);
  StepResult r_plain, r_all;
  const std::vector<uint8_t> every(pixels, 255);
  run(nullptr, prob.target, &plain, &r_plain);
  run(&every, prob.target, &all, &r_all);
  CHECK(r_all.loss == r_plain.loss);
  CHECK(all.g_features == plain.g_features);
  CHECK(all.g_offsets == plain.g_offsets);

  // The left third of the image has no source; its target is changed wildly in the second run.
  std::vector<uint8_t> valid(pixels, 255);
  for (int y = 0; y < prob.H; ++y)
    for (int x = 0; x < prob.W / 3; ++x) valid[size_t(y) * size_t(prob.W) + size_t(x)] = 0;
  std::vector<double> other = prob.target;
  for (size_t p = 0; p < pixels; ++p)
    if (!valid[p])
      for (size_t c = 0; c < 3; ++c) other[3 * p + c] = 1 - other[3 * p + c];
  Bound<double> a(prob), b(prob);
  StepResult ra, rb;
  run(&valid, prob.target, &a, &ra);
  const std::vector<double> rendered = ws.rgb;
  run(&valid, other, &b, &rb);
  CHECK(ra.loss == rb.loss);
  CHECK(ra.l1 == rb.l1);
  CHECK(a.g_features == b.g_features);
  CHECK(a.g_offsets == b.g_offsets);
  CHECK(ra.loss != r_plain.loss);
  double sum = 0;
  size_t count = 0;
  for (size_t p = 0; p < pixels; ++p) {
    if (!valid[p]) continue;
    for (size_t c = 0; c < 3; ++c) sum += std::fabs(rendered[3 * p + c] - prob.target[3 * p + c]);
    ++count;
  }
  CHECK(ra.l1 == doctest::Approx(sum / double(3 * count)).epsilon(1e-12));
  // Nothing valid: no gradient at all.
  const std::vector<uint8_t> none(pixels, 0);
  Bound<double> z(prob);
  StepResult rz;
  run(&none, prob.target, &z, &rz);
  CHECK(rz.l1 == 0);
  CHECK(rz.ssim == 1);
  for (double g : z.g_features) CHECK(g == 0);
}

// The pose gradient (rasteriser twist + view direction and distance through the camera centre).
// A translation twist rho moves every camera-space point by rho, exactly as shifting all world
// content by R^T rho does; anchor positions are double here, so the translation components are
// checked by the same double finite differences as every other parameter (h = 1e-5), covering
// both paths (the decoder inputs see the anchors move relative to the camera centre). The rotation
// components do not reach the decoder (the camera centre does not move under phi), so they must
// equal the rasteriser's, whose finite-difference check is tests/core/test_grad_fd.cpp.
void check_pose_fd(uint64_t seed, bool image_features) {
  CAPTURE(seed);
  const Problem prob(seed, image_features);
  Bound<double> b(prob);
  RefBackend be;
  StepWorkspace<double> ws;
  ws.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
  b.grads.pose = v_pose;
  StepResult r0;
  REQUIRE(step_forward_backward(be, b.params, prob.cam, b.target.data(), StepConfig{}, ws, &b.grads, &r0).ok());
  double view_path = 0, total = 0;
  for (int i = 0; i < 3; ++i) {
    view_path += std::fabs(v_pose[i] - be.render_pose[i]);
    total += std::fabs(v_pose[i]);
  }
  MESSAGE("seed " << seed << ": |translation gradient| " << total << ", view-direction share " << view_path / total);
  CHECK(view_path > 0.01 * total);  // the decoder path is large enough for the check below to see it
  for (int i = 3; i < 6; ++i) CHECK(v_pose[i] == be.render_pose[i]);

  auto loss_at = [&](uint64_t* sig) {
    be.signature = 0;
    StepResult r;
    REQUIRE(step_forward_backward(be, b.params, prob.cam, b.target.data(), StepConfig{}, ws,
                                  static_cast<ModelGradsT<double>*>(nullptr), &r).ok());
    uint64_t h = mix(be.signature, r.gaussians);
    for (size_t v = 0; v < r.visible_anchors; ++v) h = mix(h, ws.rows[v]);
    *sig = h;
    return r.loss;
  };
  uint64_t sig0 = 0;
  loss_at(&sig0);
  const std::vector<double> positions0 = b.positions;
  int compared = 0;
  for (int c = 0; c < 3; ++c) {
    const double dir[3] = {prob.cam.pose.R[3 * c], prob.cam.pose.R[3 * c + 1], prob.cam.pose.R[3 * c + 2]};  // R^T e_c
    const double off[4] = {-2 * kStep, -kStep, kStep, 2 * kStep};
    double l[4];
    bool flip = false;
    for (int q = 0; q < 4; ++q) {
      for (size_t i = 0; i < prob.M; ++i)
        for (int a = 0; a < 3; ++a) b.positions[3 * i + size_t(a)] = positions0[3 * i + size_t(a)] + off[q] * dir[a];
      uint64_t sig = 0;
      l[q] = loss_at(&sig);
      flip = flip || sig != sig0;
    }
    b.positions = positions0;
    if (flip) continue;
    ++compared;
    const double fd = (8 * (l[2] - l[1]) - (l[3] - l[0])) / (12 * kStep);
    CAPTURE(c);
    CHECK(std::fabs(fd - v_pose[c]) <= kRelTol * std::max(std::fabs(fd), std::fabs(v_pose[c])) + kAbsTol);
  }
  CHECK(compared >= 2);
}

TEST_CASE("step graph: finite differences of the pose gradient through the rasteriser and the view direction") {
  check_pose_fd(21, true);
  check_pose_fd(22, false);
}

// Relative error of a float gradient group against the double one.
double rel_err(const std::vector<float>& f, const std::vector<double>& d) {
  double num = 0, den = 0;
  for (size_t i = 0; i < d.size(); ++i) num += (double(f[i]) - d[i]) * (double(f[i]) - d[i]), den += d[i] * d[i];
  return den > 0 ? std::sqrt(num / den) : (num > 0 ? INFINITY : 0);
}

// float production step vs the double reference step on identical (float-representable) parameters.
// Tolerance 1e-3: float rendering and loss carry ~1e-6 relative rounding per operation; summed over
// a few hundred pixels and Gaussians the gradients agree to ~1e-5 (measured below); a real
// disagreement (a kernel computing something else) is O(1).
void check_float_vs_double(uint64_t seed, bool image_features) {
  CAPTURE(seed);
  CAPTURE(image_features);
  Problem prob(seed, image_features);
  // Round the parameters to float first so both runs see the same values.
  for (auto* v : {&prob.positions, &prob.offsets, &prob.log_scales, &prob.features, &prob.image_raw, &prob.target})
    for (double& x : *v) x = double(float(x));
  for (auto& m : prob.mlp)
    for (double& x : m) x = double(float(x));
  Bound<double> bd(prob);
  Bound<float> bf(prob);
  RefBackend rbe;
  FloatBackend fbe;
  REQUIRE(fbe.init(prob.M * size_t(prob.k), prob.W, prob.H).ok());
  StepWorkspace<double> wsd;
  StepWorkspace<float> wsf;
  wsd.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  wsf.reserve(prob.M, prob.k, prob.shapes, prob.G, prob.W, prob.H);
  StepResult rd, rf;
  REQUIRE(step_forward_backward(rbe, bd.params, prob.cam, bd.target.data(), StepConfig{}, wsd, &bd.grads, &rd).ok());
  const Status st = step_forward_backward(fbe, bf.params, prob.cam, bf.target.data(), StepConfig{}, wsf, &bf.grads, &rf);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  CHECK(rf.gaussians == rd.gaussians);
  CHECK(rf.visible_anchors == rd.visible_anchors);
  CHECK(rf.loss == doctest::Approx(rd.loss).epsilon(1e-5));
  struct G {
    const char* name;
    const std::vector<float>* f;
    const std::vector<double>* d;
  };
  std::vector<G> groups = {{"offsets", &bf.g_offsets, &bd.g_offsets},
                           {"anchor log-scales", &bf.g_log_scales, &bd.g_log_scales},
                           {"anchor features", &bf.g_features, &bd.g_features},
                           {"mlp opacity", &bf.g_mlp[kMlpOpacity], &bd.g_mlp[kMlpOpacity]},
                           {"mlp cov", &bf.g_mlp[kMlpCov], &bd.g_mlp[kMlpCov]},
                           {"mlp colour", &bf.g_mlp[kMlpColor], &bd.g_mlp[kMlpColor]}};
  if (image_features) groups.push_back({"mlp image F", &bf.g_mlp[kMlpImage], &bd.g_mlp[kMlpImage]});
  double worst = 0;
  for (const G& g : groups) {
    double norm = 0;
    for (double x : *g.d) norm += x * x;
    CHECK_MESSAGE(norm > 0, std::string(g.name));
    const double e = rel_err(*g.f, *g.d);
    worst = std::max(worst, e);
    CHECK_MESSAGE(e < 1e-3, std::string(g.name) << ": relative error " << e);
  }
  MESSAGE("seed " << seed << std::string(image_features ? " (paper)" : " (none)") << ", isa " << std::string(fbe.kt->isa) << ": float vs double loss "
                  << rf.loss << " / " << rd.loss << ", worst gradient-group relative error " << worst);
}

TEST_CASE("step graph: float production kernels match the double reference") {
  check_float_vs_double(11, true);
  check_float_vs_double(12, true);
  check_float_vs_double(13, false);
}

}  // namespace
}  // namespace gs::model
