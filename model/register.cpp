// SPDX-License-Identifier: MIT
// Registration of a view against a frozen model (see gs/model/register.h): pyramid, per-level
// decoding, Levenberg-Marquardt or Adam on the pose twist, best-pose bookkeeping and the verdict.
#include "gs/model/register.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "pose_solve.h"
#include "cloud_decode.h"
#include "float_backend.h"
#include "image_descriptor.h"
#include "register_sharing.h"
#include "gs/constants.h"
#include "gs/io/image.h"
#include "gs/model/step_graph.h"
#include "gs/optim/adam.h"
#include "gs/optim/schedule.h"
#include "gs/platform/clock.h"
#include "gs/pose/pose.h"
#include "gs/render.h"

namespace gs::pose {

const char* verdict_name(RegisterVerdict v) {
  switch (v) {
    case RegisterVerdict::kConverged: return "converged";
    case RegisterVerdict::kNothingVisible: return "nothing_visible";
    case RegisterVerdict::kPoorFit: return "poor_fit";
    case RegisterVerdict::kDiverged: return "diverged";
    case RegisterVerdict::kTimeBudget: return "time_budget";
  }
  return "unknown";
}

namespace {

// The camera used to choose and decode anchors: the same pose with the image widened by a quarter
// of its size on every side, so anchors just outside the view (which a moving pose brings in) are
// decoded (a wider margin costs projection work on Gaussians that mostly stay outside).
Camera decode_camera(const Camera& cam) {
  Camera c = cam;
  c.intr.width = cam.intr.width + cam.intr.width / 2;
  c.intr.height = cam.intr.height + cam.intr.height / 2;
  c.intr.cx = cam.intr.cx + 0.25f * float(cam.intr.width);
  c.intr.cy = cam.intr.cy + 0.25f * float(cam.intr.height);
  return c;
}

Status check_plan(int max_width, int max_height, const RegisterOptions& options) {
  if (max_width < 1 || max_height < 1 || max_width > 16384 || max_height > 16384)
    return invalid_argument("registration: image size " + std::to_string(max_width) + "x" + std::to_string(max_height) +
                            " out of range");
  if (options.finest_downscale < 1 || options.max_levels < 1 || options.max_iterations_per_level < 1 ||
      options.adam_iterations_per_level < 1 || options.min_coarse_width < 1)
    return invalid_argument("registration: downscale, levels and iteration caps must be positive");
  return Status::Ok();
}

}  // namespace

struct Registrar::Impl {
  const model::HybridModel* model = nullptr;  // the anchor model, or
  const GaussianCloud* cloud = nullptr;       // plain Gaussians (decoded by cloud_decoder)
  model::detail::CloudDecoder cloud_decoder;
  RegisterOptions opt;
  platform::ThreadPool* pool = nullptr;
  const simd::KernelTable* kernels = nullptr;
  simd::KernelTable portable_kernels{};  // fixed_point: the table with the exact decode and the reference projection
  // The renderer, decode backend and workspace: the registrar's own, or lent by a trainer
  // (RegistrarSharing: registration runs between its steps, so one set serves both).
  Renderer own_renderer;
  model::detail::FloatBackend own_backend;
  model::StepWorkspace<float> own_ws;
  Renderer* renderer = &own_renderer;
  model::detail::FloatBackend* backend = &own_backend;
  model::StepWorkspace<float>* ws = &own_ws;
  std::vector<float> target, rgb, v_rgb;  // [H, W, 3] of the current level
  // kKeyframe: the keyframe at the finest level (colour, alpha-weighted depth, alpha) and its
  // box-filtered level copies, and the target at the level.
  std::vector<float> key_rgb, key_depth, key_alpha, lvl_rgb, lvl_depth, lvl_alpha, fin_alpha;
  bool polish_render_valid = false;  // rgb / fin_alpha hold the polish's render at the pose it returned
  // Relocalisation candidates (set_candidates): poses, their renders' grey descriptors [count,
  // desc_dim] at 1/desc_factor of cand_intr, the image's descriptor and the ranking (reserved).
  std::vector<Pose> cand;
  std::vector<float> cand_desc, image_desc;
  std::vector<std::pair<float, int>> ranked;
  PinholeIntrinsics cand_intr{};
  int desc_factor = 1;
  size_t desc_dim = 0;
  uint64_t cand_bytes = 0;  // of the above, in planned_bytes()
  int max_w = 0, max_h = 0;
  size_t planned_rows = 0;

  Status register_once(const uint8_t* rgb, const PinholeIntrinsics& intr, const Pose& init, double deadline,
                       RegisterResult* out);
  uint64_t bytes = 0;
  double extent = 1;


  // The start of both creations for an anchor model (its own set or a lent one): checks, options,
  // the planned rows.
  static Expected<std::unique_ptr<Registrar>> for_model(const model::HybridModel& model, int max_width, int max_height,
                                                        const RegisterOptions& options, platform::ThreadPool* pool,
                                                        const simd::KernelTable* kernels, size_t plan_anchor_rows) {
    GS_RETURN_IF_ERROR(model.config.validate());
    if (model.anchor_count == 0) return invalid_argument("registration: the model has no anchors");
    GS_RETURN_IF_ERROR(check_plan(max_width, max_height, options));
    std::unique_ptr<Registrar> r(new Registrar());
    Impl& d = *r->impl_;
    d.model = &model;
    d.setup(options, pool, kernels, max_width, max_height, model.scene_extent);
    d.planned_rows = std::max(model.anchor_count, plan_anchor_rows);
    return r;
  }

  // What both kinds of scene share at creation.
  void setup(const RegisterOptions& options, platform::ThreadPool* p, const simd::KernelTable* k, int w, int h, float e) {
    opt = options;
    pool = p;
    kernels = k ? k : &simd::best_kernel_table();
    if (options.fixed_point) {
      // The same poses on every CPU: the fixed-point blending is bit-identical across tables, and
      // the float kernels before it run bit-identical to their scalar references (the decoder MLPs'
      // exact variant; the projection's reference itself), where the fast SIMD variants round
      // differently (0.0014-0.0017 degrees apart after a tracked path).
      portable_kernels = *kernels;
      portable_kernels.mlp_fwd = kernels->mlp_fwd_exact;
      portable_kernels.project_fwd = simd::ref_kernel_table().project_fwd;
      kernels = &portable_kernels;
    }
    max_w = w;
    max_h = h;
    extent = e;
  }

  void allocate_images() {
    const size_t px = size_t(max_w) * size_t(max_h) * 3, npx = size_t(max_w) * size_t(max_h);
    for (auto* v : {&target, &rgb, &v_rgb, &key_rgb, &lvl_rgb}) v->assign(px, 0.0f);
    for (auto* v : {&key_depth, &key_alpha, &lvl_depth, &lvl_alpha, &fin_alpha}) v->assign(npx, 0.0f);
  }
  uint64_t image_bytes() const { return uint64_t(max_w) * uint64_t(max_h) * (5 * 3 + 5) * 4; }

  // The options of the forward-only renders (keyframes, the render polish, the verdict's render):
  // these may use the fixed-point rasteriser (RegisterOptions::fixed_point). The lm and adam
  // solvers' renders (render()) stay float: they need the renderer's backward / forward-mode pose
  // Jacobian, which the fixed-point path does not have.
  RenderOptions render_options(bool depth) const {
    RenderOptions ro;
    ro.validate_inputs = false;  // decoded values are finite by construction
    ro.depth = depth;
    ro.fixed_point = opt.fixed_point;
    for (int c = 0; c < 3; ++c) ro.background[c] = float(opt.background[c]);
    return ro;
  }

  // Every render of the registrar. A lent renderer is planned for fewer tile pairs per Gaussian
  // (kReplannedIsectsPerGaussian) and re-plans when a view needs more (forward_replanning, as the
  // trainer's renders do); its own renderer is planned for 8 and is never re-planned by a
  // register_view, which allocates nothing.
  Status forward(const Camera& cam, const GaussianParams& gp, const RenderOptions& ro, float* out_rgb,
                 float* out_depth = nullptr) {
    if (renderer == &own_renderer) return renderer->forward(cam, gp, ro, out_rgb, out_depth);
    return model::detail::forward_replanning(renderer, pool, kernels, cam, gp, ro, out_rgb, out_depth, nullptr);
  }

  // The last render's opacity, 1 - final transmittance, [H, W] of cam.
  void opacity(const Camera& cam, float* out) const {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height);
    const float* T = renderer->final_transmittance();
    for (size_t i = 0; i < n; ++i) out[i] = 1.0f - T[i];
  }

  // Decodes the model's Gaussians for a pose (colours for its view direction).
  // The camera of the last decode and its count (a decode costs as much as a render here: the
  // decoders run for every anchor in view), so a repeated decode at the same pose is skipped.
  Camera decoded_cam{};
  size_t decoded_n = 0;
  bool decoded_valid = false;
  // The pose and divisor of the render held in key_rgb / key_depth / key_alpha (with depth).
  Camera key_cam{};
  bool key_valid = false;

  static bool same_camera(const Camera& a, const Camera& b) {
    return std::memcmp(&a.pose, &b.pose, sizeof(Pose)) == 0 && a.intr.fx == b.intr.fx && a.intr.fy == b.intr.fy &&
           a.intr.cx == b.intr.cx && a.intr.cy == b.intr.cy && a.intr.width == b.intr.width && a.intr.height == b.intr.height;
  }

  size_t decode(const Camera& cam) {
    if (decoded_valid && same_camera(cam, decoded_cam)) return decoded_n;
    decoded_cam = cam;
    decoded_valid = true;
    decoded_n = decode_uncached(cam);
    return decoded_n;
  }

  size_t decode_uncached(const Camera& cam) {
    if (cloud) return cloud_decoder.decode(*cloud, decode_camera(cam));
    size_t V = 0;
    return model::decode_view(*backend, model::detail::model_params(*model), decode_camera(cam), *ws, &V);
  }

  // The Gaussians of the last decode, as the renderer takes them.
  GaussianParams gaussians() const { return cloud ? cloud_decoder.params() : model::gaussian_params(ws->ng); }

  Status render(const Camera& cam) {
    const GaussianParams gp = gaussians();
    RenderOptions ro = render_options(false);
    ro.fixed_point = false;  // followed by backward / pose_normal_equations (float only)
    return forward(cam, gp, ro, rgb.data());
  }

  double rmse(const Camera& cam) const {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height) * 3;
    double se = 0;
    for (size_t i = 0; i < n; ++i) {
      const double e = double(rgb[i]) - double(target[i]);
      se += e * e;
    }
    return std::sqrt(se / double(n));
  }

  // Variance of the target's colour values (finest level), for the explained fraction.
  double target_variance(const Camera& cam) const {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height) * 3;
    double sum = 0, sq = 0;
    for (size_t i = 0; i < n; ++i) sum += target[i], sq += double(target[i]) * target[i];
    const double mean = sum / double(n);
    return std::max(sq / double(n) - mean * mean, 0.0);
  }

  double coverage(const Camera& cam) const {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height);
    const float* T = renderer->final_transmittance();
    double c = 0;
    for (size_t i = 0; i < n; ++i) c += 1.0 - double(T[i]);
    return c / double(n);
  }

  // The divisor keyframes are rendered at before being box-filtered down to the levels (no level
  // sees the aliasing of sub-pixel Gaussians); the polish's remaining bias is what the keyframes'
  // would be, so they can be coarser.
  int keyframe_scale(int finest) const {
    const int k = opt.keyframe_downscale > 0 ? opt.keyframe_downscale : std::max(1, finest / 2);
    return finest % k == 0 ? k : 1;
  }
  // The divisor of the render polish and of the verdict's render: at 1/4 a render at 1/2 (box-
  // filtered) still left 0.1-0.5 degree biases on the test scenes, at full 0.01-0.1.
  int polish_scale(int finest) const {
    const int k = opt.polish_downscale > 0 ? opt.polish_downscale : std::max(1, finest / 4);
    return finest % k == 0 ? k : 1;
  }

  // Anti-aliased render at the finest level: rendered at keyframe_scale(finest) and box-filtered
  // into rgb (and the opacity into lvl_alpha), so the verdict's residual measures the pose, not the
  // aliasing of a direct low-resolution render. Decodes the model for the pose; the count of
  // decoded Gaussians is returned in *decoded.
  Status render_antialiased(const Camera& full, int finest, size_t* decoded) {
    const int ks = polish_scale(finest);
    const Camera kc = scaled_camera(full, ks);
    *decoded = decode(full);
    if (*decoded == 0) return Status::Ok();
    if (!(key_valid && same_camera(kc, key_cam))) {
      const GaussianParams gp = gaussians();
      GS_RETURN_IF_ERROR(forward(kc, gp, render_options(true), key_rgb.data(), key_depth.data()));
      opacity(kc, key_alpha.data());
      key_cam = kc;
      key_valid = true;
    }
    const int f = finest / ks;
    io::box_downsample_float(key_rgb.data(), kc.intr.width, kc.intr.height, 3, f, rgb.data());
    io::box_downsample_float(key_alpha.data(), kc.intr.width, kc.intr.height, 1, f, lvl_alpha.data());
    return Status::Ok();
  }

  double level_coverage(const Camera& cam) const {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height);
    double c = 0;
    for (size_t i = 0; i < n; ++i) c += double(lvl_alpha[i]);
    return c / double(n);
  }

  bool step_small(const double xi[6]) const {
    const double r = std::sqrt(xi[3] * xi[3] + xi[4] * xi[4] + xi[5] * xi[5]);
    const double t = std::sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
    return r < opt.min_step_rotation && t < opt.min_step_translation * extent;
  }

  // Levenberg-Marquardt at one level from cam.pose; returns the best pose in cam.pose.
  Status level_gauss_newton(Camera& cam, int* iterations, double deadline) {
    PoseNormalEquations ne;
    GS_RETURN_IF_ERROR(render(cam));
    GS_RETURN_IF_ERROR(renderer->pose_normal_equations(target.data(), nullptr, opt.huber_delta, &ne));
    double lambda = 1e-3;
    for (int it = 0; it < opt.max_iterations_per_level; ++it) {
      if (deadline > 0 && platform::now_seconds() > deadline) break;
      detail::Mat6 A;
      detail::Vec6 b;
      for (int r = 0; r < 6; ++r) {
        b(r) = ne.Jtr[r];
        for (int c = 0; c < 6; ++c) A(r, c) = ne.JtJ[6 * r + c];
      }
      bool accepted = false;
      for (int attempt = 0; attempt < 8 && !accepted; ++attempt) {
        // Trust region: at most 0.05 rad (3 deg) and 0.05 x extent per step, so a step cannot jump
        // over the basin into a look-alike view.
        double xi[6];
        detail::damped_step(A, b, lambda, 0.05, 0.05 * extent, xi);
        Camera trial = cam;
        pose::apply_left_twist(xi, &trial.pose);
        GS_RETURN_IF_ERROR(render(trial));
        PoseNormalEquations tne;
        GS_RETURN_IF_ERROR(renderer->pose_normal_equations(target.data(), nullptr, opt.huber_delta, &tne));
        ++*iterations;
        if (tne.cost < ne.cost) {
          const double decrease = (ne.cost - tne.cost) / std::max(ne.cost, 1e-30);
          cam = trial;
          ne = tne;
          lambda = std::max(lambda / 3, 1e-7);
          accepted = true;
          if (step_small(xi) || decrease < opt.min_relative_decrease) return Status::Ok();
        } else {
          lambda *= 4;
        }
      }
      if (!accepted) break;  // no descent direction left at this level
    }
    return Status::Ok();
  }

  // Renders the keyframe (colour, depth, alpha) at the finest level for the pose of cam.
  Status render_keyframe(const Camera& full, int finest) {
    const Camera cam = scaled_camera(full, finest);
    decode(full);
    if (key_valid && same_camera(cam, key_cam)) return Status::Ok();
    key_cam = cam;
    key_valid = true;
    const GaussianParams gp = gaussians();
    GS_RETURN_IF_ERROR(forward(cam, gp, render_options(true), key_rgb.data(), key_depth.data()));
    opacity(cam, key_alpha.data());
    return Status::Ok();
  }

  // Mean Huber cost of warping the level keyframe by rel (keyframe camera -> target camera) into
  // the level target, and optionally the normal equations. Keyframe pixels with alpha < 0.5 are
  // skipped; one that warps outside the target costs a full-delta residual.
  double warp_cost(const PinholeIntrinsics& in, const Pose& rel, detail::Mat6* A,
                   detail::Vec6* b) const {
    const double delta = opt.huber_delta;
    const detail::RgbView tgt{target.data(), in.width, in.height};
    double R[9], t[3];
    for (int i = 0; i < 9; ++i) R[i] = rel.R[i];
    for (int i = 0; i < 3; ++i) t[i] = rel.t[i];
    if (A) A->setZero(), b->setZero();
    double total = 0;
    size_t used = 0;
    for (int y = 0; y < in.height; ++y)
      for (int x = 0; x < in.width; ++x) {
        const size_t pix = size_t(y) * size_t(in.width) + size_t(x);
        const double alpha = lvl_alpha[pix];
        if (!(alpha > 0.5)) continue;
        const double z = lvl_depth[pix] / alpha;
        if (!(z > 1e-3)) continue;
        ++used;
        const double Xk[3] = {z * ((x + 0.5) - in.cx) / in.fx, z * ((y + 0.5) - in.cy) / in.fy, z};
        double m[3];
        for (int r = 0; r < 3; ++r) m[r] = R[3 * r] * Xk[0] + R[3 * r + 1] * Xk[1] + R[3 * r + 2] * Xk[2] + t[r];
        double c[3], cu[3], cv[3];
        if (!(m[2] > 1e-3) || !detail::sample_bilinear(tgt, in.fx * m[0] / m[2] + in.cx, in.fy * m[1] / m[2] + in.cy, c, cu, cv)) {
          total += detail::huber_cost(2 * delta, delta);
          continue;
        }
        double r[3];
        for (int k = 0; k < 3; ++k) r[k] = c[k] - lvl_rgb[3 * pix + size_t(k)];
        const double rn = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        total += detail::huber_cost(rn, delta);
        if (!A) continue;
        double du[6], dv[6];
        detail::projection_twist_jacobian(m, in.fx, in.fy, du, dv);
        const double w = detail::huber_weight(rn, delta);
        for (int k = 0; k < 3; ++k) {
          double J[6];
          for (int j = 0; j < 6; ++j) J[j] = cu[k] * du[j] + cv[k] * dv[j];
          for (int i = 0; i < 6; ++i) {
            (*b)(i) += w * J[i] * r[k];
            for (int j = i; j < 6; ++j) (*A)(i, j) += w * J[i] * J[j];
          }
        }
      }
    if (A)
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < i; ++j) (*A)(i, j) = (*A)(j, i);
    return used ? total / double(used) : INFINITY;
  }

  // Direct alignment of the target to the keyframe at one level; rel is updated in place.
  void align_level(const PinholeIntrinsics& in, Pose* rel, int* iterations, double deadline) {
    detail::Mat6 A;
    detail::Vec6 b;
    double c = warp_cost(in, *rel, &A, &b);
    if (!std::isfinite(c)) return;
    double lambda = 1e-3;
    for (int it = 0; it < opt.keyframe_iterations; ++it) {
      if (deadline > 0 && platform::now_seconds() > deadline) return;
      bool accepted = false;
      for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
        double xi[6];
        detail::damped_step(A, b, lambda, 0.05, 0.05 * extent, xi);
        Pose trial = *rel;
        pose::apply_left_twist(xi, &trial);
        const double ct = warp_cost(in, trial, nullptr, nullptr);
        ++*iterations;
        if (ct < c) {
          const double decrease = (c - ct) / std::max(c, 1e-30);
          *rel = trial;
          c = warp_cost(in, *rel, &A, &b);
          lambda = std::max(lambda / 3, 1e-7);
          accepted = true;
          if (step_small(xi) || decrease < opt.min_relative_decrease) return;
        } else {
          lambda *= 4;
        }
      }
      if (!accepted) return;
    }
  }

  // The coarsest alignment from several rotations about the camera centre (see
  // RegisterOptions::coarse_candidates); rel ends as the candidate with the lowest final cost.
  void align_from_candidates(const PinholeIntrinsics& in, Pose* rel, int* iterations, double deadline) {
    const int n = std::max(1, std::min(opt.coarse_candidates, 9));
    const double a = opt.candidate_angle_deg * kPi / 180.0;
    // Candidate order: the start first, then the four pan/tilt neighbours, then the diagonals.
    static const int kOffsets[9][2] = {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};
    Pose best = *rel;
    double best_cost = INFINITY;
    for (int c = 0; c < n; ++c) {
      if (c > 0 && deadline > 0 && platform::now_seconds() > deadline) break;
      Pose cand = *rel;
      const double xi[6] = {0, 0, 0, kOffsets[c][1] * a, kOffsets[c][0] * a, 0};  // tilt about x, pan about y
      pose::apply_left_twist(xi, &cand);
      align_level(in, &cand, iterations, deadline);
      const double cost = warp_cost(in, cand, nullptr, nullptr);
      if (cost < best_cost) best_cost = cost, best = cand;
    }
    *rel = best;
  }

  // Renders the pose at the keyframe divisor with depth and box-filters colour, depth and opacity
  // to the finest level (lvl_*); the Gaussians of the last decode are used.
  Status render_level_from_key(const Camera& full, int finest) {
    const int ks = polish_scale(finest);
    const Camera kc = scaled_camera(full, ks);
    const GaussianParams gp = gaussians();
    key_valid = false;  // rendered with the Gaussians of the polish's decode, not full's own
    GS_RETURN_IF_ERROR(forward(kc, gp, render_options(true), key_rgb.data(), key_depth.data()));
    opacity(kc, key_alpha.data());
    const int f = finest / ks;
    io::box_downsample_float(key_rgb.data(), kc.intr.width, kc.intr.height, 3, f, lvl_rgb.data());
    io::box_downsample_float(key_depth.data(), kc.intr.width, kc.intr.height, 1, f, lvl_depth.data());
    io::box_downsample_float(key_alpha.data(), kc.intr.width, kc.intr.height, 1, f, lvl_alpha.data());
    return Status::Ok();
  }

  // Mean Huber cost of the anti-aliased render (lvl_rgb) against the level target over the pixels
  // the model covers (opacity > 0.5), and the Gauss-Newton normal equations with the Jacobian of
  // the render taken from its own image gradient (central differences) and depth:
  // render_new(p) ~ render(p - dp), dp = d(u, v)/dxi xi, so dr/dxi = -grad(render) . dp/dxi.
  double render_cost(const PinholeIntrinsics& in, detail::Mat6* A, detail::Vec6* b) const {
    const double delta = opt.huber_delta;
    if (A) A->setZero(), b->setZero();
    double total = 0;
    size_t used = 0;
    const int w = in.width, h = in.height;
    for (int y = 1; y + 1 < h; ++y)
      for (int x = 1; x + 1 < w; ++x) {
        const size_t pix = size_t(y) * size_t(w) + size_t(x);
        const double alpha = lvl_alpha[pix];
        if (!(alpha > 0.5)) continue;
        const double z = lvl_depth[pix] / alpha;
        if (!(z > 1e-3)) continue;
        ++used;
        double r[3];
        for (int k = 0; k < 3; ++k) r[k] = double(lvl_rgb[3 * pix + size_t(k)]) - double(target[3 * pix + size_t(k)]);
        const double rn = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        total += detail::huber_cost(rn, delta);
        if (!A) continue;
        const double m[3] = {z * ((x + 0.5) - in.cx) / in.fx, z * ((y + 0.5) - in.cy) / in.fy, z};
        double du[6], dv[6];
        detail::projection_twist_jacobian(m, in.fx, in.fy, du, dv);
        const double wgt = detail::huber_weight(rn, delta);
        for (int k = 0; k < 3; ++k) {
          const double gx = 0.5 * (double(lvl_rgb[3 * (pix + 1) + size_t(k)]) - double(lvl_rgb[3 * (pix - 1) + size_t(k)]));
          const double gy = 0.5 * (double(lvl_rgb[3 * (pix + size_t(w)) + size_t(k)]) - double(lvl_rgb[3 * (pix - size_t(w)) + size_t(k)]));
          double J[6];
          for (int j = 0; j < 6; ++j) J[j] = -(gx * du[j] + gy * dv[j]);
          for (int i = 0; i < 6; ++i) {
            (*b)(i) += wgt * J[i] * r[k];
            for (int j = i; j < 6; ++j) (*A)(i, j) += wgt * J[i] * J[j];
          }
        }
      }
    if (A)
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < i; ++j) (*A)(i, j) = (*A)(j, i);
    return used ? total / double(used) : INFINITY;
  }

  // Keeps the polish's render at the accepted pose (rgb, fin_alpha): the verdict's render then costs
  // nothing (its Gaussians were decoded at the polish's start pose, at most 0.6 degrees away).
  void keep_polish_render(const PinholeIntrinsics& in) {
    const size_t n = size_t(in.width) * size_t(in.height);
    std::copy(lvl_rgb.begin(), lvl_rgb.begin() + std::ptrdiff_t(3 * n), rgb.begin());
    std::copy(lvl_alpha.begin(), lvl_alpha.begin() + std::ptrdiff_t(n), fin_alpha.begin());
    polish_render_valid = true;
  }

  // The end of kKeyframe below full resolution: Levenberg-Marquardt against the anti-aliased render
  // itself at the finest level (each trial re-renders at the keyframe divisor). Its fixed point is
  // where the render's residual has no component along the Jacobian, which the keyframe warp's is
  // not (depth blended across edges at the level, pixels warping out of the image): on the test
  // scenes the warp's minimum sat 0.1-1 degree from the true pose at 1/4.
  Status render_polish(Camera* full, const uint8_t* image, int finest, int* iterations, double deadline) {
    const PinholeIntrinsics in = scaled_camera(*full, finest).intr;
    io::box_downsample_rgb(image, full->intr.width, full->intr.height, finest, target.data());
    if (decode(*full) == 0) return Status::Ok();
    GS_RETURN_IF_ERROR(render_level_from_key(*full, finest));
    detail::Mat6 A;
    detail::Vec6 b;
    double c = render_cost(in, &A, &b);
    if (!std::isfinite(c)) return Status::Ok();
    keep_polish_render(in);
    double lambda = 1e-3;
    for (int it = 0; it < opt.render_polish_iterations; ++it) {
      if (deadline > 0 && platform::now_seconds() > deadline) break;
      bool accepted = false;
      for (int attempt = 0; attempt < 4 && !accepted; ++attempt) {
        double xi[6];
        detail::damped_step(A, b, lambda, 0.01, 0.01 * extent, xi);
        Camera trial = *full;
        pose::apply_left_twist(xi, &trial.pose);
        GS_RETURN_IF_ERROR(render_level_from_key(trial, finest));
        detail::Mat6 At;
        detail::Vec6 bt;
        const double ct = render_cost(in, &At, &bt);
        ++*iterations;
        if (ct < c) {
          const double decrease = (c - ct) / std::max(c, 1e-30);
          full->pose = trial.pose;
          c = ct, A = At, b = bt;
          keep_polish_render(in);
          lambda = std::max(lambda / 3, 1e-7);
          accepted = true;
          if (step_small(xi) || decrease < opt.min_relative_decrease) return Status::Ok();
        } else {
          lambda *= 4;
        }
      }
      if (!accepted) break;
    }
    return Status::Ok();
  }

  // kKeyframe: keyframes at the current pose, each aligned coarse to fine; returns the new pose.
  Status keyframe_alignment(Camera* full, const uint8_t* image, int coarsest, int finest, int* iterations, int* levels,
                            double deadline) {
    // The keyframe is rendered at twice the finest level's resolution (when the image has it) and
    // box-filtered down, so that no level sees the aliasing of sub-pixel Gaussians.
    const int key_scale = keyframe_scale(finest);
    const Camera kcam = scaled_camera(*full, key_scale);
    const int kw = kcam.intr.width, kh = kcam.intr.height;
    for (int k = 0; k < opt.keyframes; ++k) {
      if (deadline > 0 && platform::now_seconds() > deadline) break;
      GS_RETURN_IF_ERROR(render_keyframe(*full, key_scale));
      Pose rel;  // identity: keyframe camera -> target camera
      for (int s = coarsest; s >= finest; s /= 2) {
        const int f = s / key_scale;
        const PinholeIntrinsics in = scaled_camera(kcam, f).intr;
        io::box_downsample_float(key_rgb.data(), kw, kh, 3, f, lvl_rgb.data());
        io::box_downsample_float(key_depth.data(), kw, kh, 1, f, lvl_depth.data());
        io::box_downsample_float(key_alpha.data(), kw, kh, 1, f, lvl_alpha.data());
        io::box_downsample_rgb(image, full->intr.width, full->intr.height, s, target.data());
        if (k == 0 && s == coarsest)
          align_from_candidates(in, &rel, iterations, deadline);
        else
          align_level(in, &rel, iterations, deadline);
        if (k == 0) ++*levels;
      }
      // The target pose: rel o keyframe pose (R = R_rel R_k, t = R_rel t_k + t_rel).
      Pose next;
      for (int r = 0; r < 3; ++r) {
        double tr = rel.t[r];
        for (int c = 0; c < 3; ++c) {
          double v = 0;
          for (int j = 0; j < 3; ++j) v += double(rel.R[3 * r + j]) * full->pose.R[3 * j + c];
          next.R[3 * r + c] = float(v);
          tr += double(rel.R[3 * r + c]) * full->pose.t[c];
        }
        next.t[r] = float(tr);
      }
      const double zero[6] = {0, 0, 0, 0, 0, 0};
      pose::apply_left_twist(zero, &next);  // re-orthonormalise
      double moved[6];
      pose::left_difference(full->pose, next, moved);
      full->pose = next;
      if (step_small(moved)) break;  // the keyframe already sits at the answer
    }
    return Status::Ok();
  }

  // Adam on the L1 loss at one level; keeps the pose with the lowest loss seen (the loss is
  // measured before the step, so the stored pose is the one that achieved it).
  Status level_adam(Camera& cam, int* iterations, double deadline) {
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height) * 3;
    double m[6] = {0, 0, 0, 0, 0, 0}, v[6] = {0, 0, 0, 0, 0, 0};
    double best = INFINITY;
    Pose best_pose = cam.pose;
    const int steps = opt.adam_iterations_per_level;
    for (int it = 1; it <= steps; ++it) {
      if (deadline > 0 && platform::now_seconds() > deadline) break;
      GS_RETURN_IF_ERROR(render(cam));
      double l1 = 0;
      const float inv = 1.0f / float(n);
      for (size_t i = 0; i < n; ++i) {
        const float e = rgb[i] - target[i];
        l1 += std::fabs(double(e));
        v_rgb[i] = e > 0 ? inv : (e < 0 ? -inv : 0.0f);
      }
      l1 /= double(n);
      if (l1 < best) {
        best = l1;
        best_pose = cam.pose;
      }
      GaussianGrads g;
      GS_RETURN_IF_ERROR(renderer->backward(v_rgb.data(), &g));
      ++*iterations;
      // Cosine decay of the rate over the level (large early steps, fine at the end).
      const double decay = optim::cosine_decay(steps, it, 0.05);
      double xi[6];
      optim::twist_adam_step(g.v_pose, decay * opt.adam_lr_translation * extent, decay * opt.adam_lr_rotation, it,
                             optim::kAdamEps, m, v, xi);
      pose::apply_left_twist(xi, &cam.pose);
    }
    cam.pose = best_pose;
    return Status::Ok();
  }
};

Registrar::Registrar() : impl_(new Impl) {}
Registrar::~Registrar() = default;

Expected<std::unique_ptr<Registrar>> Registrar::create(const model::HybridModel& model, int max_width, int max_height,
                                                       const RegisterOptions& options, platform::ThreadPool* pool,
                                                       const simd::KernelTable* kernels, size_t plan_anchor_rows) {
  Expected<std::unique_ptr<Registrar>> r = Impl::for_model(model, max_width, max_height, options, pool, kernels, plan_anchor_rows);
  if (!r.ok()) return r;
  Impl& d = *(*r)->impl_;
  // The kept Gaussians are planned by the first decode (half again of what it keeps; a pose that
  // keeps more grows the plan), not k per anchor row: a view keeps far fewer.
  Expected<RenderCapacity> rc = model::detail::plan_model_pipeline(model, d.planned_rows, max_width, max_height, 1, 1, pool, d.kernels,
                                                            d.renderer, d.backend, d.ws, /*training=*/false,
                                                            /*isects_per_gaussian=*/8, /*visible_rows=*/0, /*gaussians=*/1);
  if (!rc.ok()) return rc.status();
  d.allocate_images();
  d.bytes = Renderer::plan_bytes(*rc) + d.image_bytes() +
            uint64_t(d.ws->X.size() * 3 + d.ws->means.size() * 4 + d.ws->quats.size() * 2) * 4;
  return r;
}

Expected<std::unique_ptr<Registrar>> RegistrarSharing::create(const model::HybridModel& model, int max_width, int max_height,
                                                              const RegisterOptions& options, platform::ThreadPool* pool,
                                                              const simd::KernelTable* kernels, size_t plan_anchor_rows,
                                                              Renderer* renderer, model::detail::FloatBackend* backend,
                                                              model::StepWorkspace<float>* ws) {
  if (!renderer || !backend || !ws) return invalid_argument("registration: a lent renderer, backend and workspace are all needed");
  Expected<std::unique_ptr<Registrar>> r =
      Registrar::Impl::for_model(model, max_width, max_height, options, pool, kernels, plan_anchor_rows);
  if (!r.ok()) return r;
  Registrar::Impl& d = *(*r)->impl_;
  if (ws->capacity < d.planned_rows)
    return invalid_argument("registration: the lent workspace holds fewer anchor rows than planned");
  if (renderer->capacity().max_width < max_width || renderer->capacity().max_height < max_height)
    return invalid_argument("registration: the lent renderer is planned for smaller images");
  d.renderer = renderer;
  d.backend = backend;
  d.ws = ws;
  d.allocate_images();
  d.bytes = d.image_bytes();  // the rest is the lender's
  return r;
}

Expected<std::unique_ptr<Registrar>> Registrar::create(const GaussianCloud& cloud, float scene_extent, int max_width,
                                                       int max_height, const RegisterOptions& options,
                                                       platform::ThreadPool* pool, const simd::KernelTable* kernels) {
  if (cloud.size() == 0) return invalid_argument("registration: the cloud has no Gaussians");
  if (!(scene_extent > 0) || !std::isfinite(scene_extent)) return invalid_argument("registration: the scene extent must be positive");
  GS_RETURN_IF_ERROR(check_plan(max_width, max_height, options));
  std::unique_ptr<Registrar> r(new Registrar());
  Impl& d = *r->impl_;
  d.cloud = &cloud;
  d.setup(options, pool, kernels, max_width, max_height, scene_extent);
  const RenderCapacity rc = model::detail::cloud_render_capacity(cloud.size(), max_width, max_height);
  GS_RETURN_IF_ERROR(d.renderer->init(rc, pool, d.kernels));
  d.cloud_decoder.reserve(cloud.size(), cloud.sh_degree);
  d.allocate_images();
  d.bytes = Renderer::plan_bytes(rc) + d.image_bytes() + d.cloud_decoder.bytes();
  return r;
}

Status Registrar::render(const Camera& cam, float* rgb, float* depth, float* alpha) {
  Impl& d = *impl_;
  if (!rgb) return invalid_argument("registration render: no colour buffer");
  if (cam.intr.width > d.max_w || cam.intr.height > d.max_h)
    return invalid_argument("registration render: " + std::to_string(cam.intr.width) + "x" + std::to_string(cam.intr.height) +
                            " exceeds the planned " + std::to_string(d.max_w) + "x" + std::to_string(d.max_h));
  GS_RETURN_IF_ERROR(validate_camera(cam));
  d.decoded_valid = false;  // the model may have changed since the last call
  if (d.decode(cam) == 0) {  // nothing in view: the background everywhere
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height);
    for (size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = d.opt.background[c];
    if (depth) std::fill(depth, depth + n, 0.0f);
    if (alpha) std::fill(alpha, alpha + n, 0.0f);
    return Status::Ok();
  }
  GS_RETURN_IF_ERROR(d.forward(cam, d.gaussians(), d.render_options(depth != nullptr), rgb, depth));
  if (alpha) d.opacity(cam, alpha);
  d.polish_render_valid = false;
  return Status::Ok();
}

const RegisterOptions& Registrar::options() const { return impl_->opt; }
RegisterOptions& Registrar::mutable_options() { return impl_->opt; }
uint64_t Registrar::planned_bytes() const { return impl_->bytes + impl_->cand_bytes; }

Status Registrar::register_view(const uint8_t* rgb, const PinholeIntrinsics& intr, const Pose& init, RegisterResult* out) {
  Impl& d = *impl_;
  if (!rgb || !out) return invalid_argument("registration: null image or result");
  if (intr.width > d.max_w || intr.height > d.max_h)
    return capacity_exceeded("registration: a " + std::to_string(intr.width) + "x" + std::to_string(intr.height) +
                             " image is larger than the planned " + std::to_string(d.max_w) + "x" + std::to_string(d.max_h));
  if (d.model && d.model->anchor_count > d.planned_rows)
    return capacity_exceeded("registration: the model has more anchors than planned");
  if (d.cloud && d.cloud->size() > d.cloud_decoder.capacity())
    return capacity_exceeded("registration: the cloud has more Gaussians than planned");
  if (Status st = validate_camera(Camera{intr, init}); !st.ok())
    return invalid_argument("registration: start pose or camera: " + st.message());
  const double t0 = platform::now_seconds();
  const double deadline = d.opt.time_budget_ms > 0 ? t0 + 1e-3 * d.opt.time_budget_ms : 0.0;
  GS_RETURN_IF_ERROR(d.register_once(rgb, intr, init, deadline, out));
  const bool relocalize = !out->converged() && out->verdict != RegisterVerdict::kTimeBudget && d.opt.relocalize_candidates > 0 &&
                          !d.cand.empty() && intr.width == d.cand_intr.width && intr.height == d.cand_intr.height;
  if (relocalize) {
    // The relocalize_candidates candidates most like the image; if none converges, the start's
    // result stands.
    io::box_downsample_rgb(rgb, intr.width, intr.height, d.desc_factor, d.lvl_rgb.data());
    detail::grey_descriptor(d.lvl_rgb.data(), d.desc_dim, d.image_desc.data());
    d.ranked.clear();
    for (size_t i = 0; i < d.cand.size(); ++i)
      d.ranked.emplace_back(detail::descriptor_distance(d.cand_desc.data() + i * d.desc_dim, d.image_desc.data(), d.desc_dim),
                            int(i));
    const size_t tries = std::min(d.ranked.size(), size_t(d.opt.relocalize_candidates));
    std::partial_sort(d.ranked.begin(), d.ranked.begin() + std::ptrdiff_t(tries), d.ranked.end());
    // Every ranked candidate is tried and the converged result that fits best wins: a look-alike pose
    // (the far side of a symmetric object) can converge too, with a worse fit than the true one.
    int iterations = out->iterations, attempts = 0;
    RegisterResult best;
    for (size_t k = 0; k < tries && !(deadline > 0 && platform::now_seconds() > deadline); ++k) {
      const int id = d.ranked[k].second;
      RegisterResult r;
      GS_RETURN_IF_ERROR(d.register_once(rgb, intr, d.cand[size_t(id)], deadline, &r));
      iterations += r.iterations;
      ++attempts;
      if (r.converged() && (best.relocalized_from < 0 || r.final_rmse < best.final_rmse)) {
        best = r;
        best.relocalized_from = id;
      }
    }
    if (best.relocalized_from >= 0) {
      best.initial_rmse = out->initial_rmse;
      *out = best;
    }
    out->iterations = iterations;
    out->relocalize_attempts = attempts;
  }
  out->milliseconds = 1e3 * (platform::now_seconds() - t0);
  return Status::Ok();
}

Status Registrar::set_candidates(const std::vector<Pose>& poses, const PinholeIntrinsics& intr) {
  Impl& d = *impl_;
  if (!poses.empty() && (intr.width > d.max_w || intr.height > d.max_h || intr.width < 1 || intr.height < 1))
    return invalid_argument("registration candidates: " + std::to_string(intr.width) + "x" + std::to_string(intr.height) +
                            " is not within the planned " + std::to_string(d.max_w) + "x" + std::to_string(d.max_h));
  d.cand.clear();  // on an error below, no candidates are left
  d.cand_desc.clear();
  d.cand_bytes = 0;
  if (poses.empty()) return Status::Ok();
  // The descriptor's grid: the largest whole divisor that keeps at least kDescriptorWidth x
  // kDescriptorHeight cells (an image smaller than that is described at its own size).
  d.desc_factor = std::max(1, std::min(intr.width / detail::kDescriptorWidth, intr.height / detail::kDescriptorHeight));
  const int dw = intr.width / d.desc_factor, dh = intr.height / d.desc_factor;
  d.desc_dim = size_t(dw) * size_t(dh);
  d.cand_desc.assign(poses.size() * d.desc_dim, 0.0f);
  d.image_desc.assign(d.desc_dim, 0.0f);
  d.ranked.clear();
  d.ranked.reserve(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    const Camera cam{intr, poses[i]};
    if (Status st = validate_camera(cam); !st.ok())
      return invalid_argument("registration candidate " + std::to_string(i) + ": " + st.message());
    GS_RETURN_IF_ERROR(render(cam, d.key_rgb.data()));
    io::box_downsample_float(d.key_rgb.data(), intr.width, intr.height, 3, d.desc_factor, d.lvl_rgb.data());
    detail::grey_descriptor(d.lvl_rgb.data(), d.desc_dim, d.cand_desc.data() + i * d.desc_dim);
  }
  d.key_valid = false;  // key_rgb held the candidates' renders
  d.cand = poses;
  d.cand_intr = intr;
  d.cand_bytes = uint64_t(d.cand_desc.size() + d.image_desc.size()) * sizeof(float) +
                 uint64_t(poses.size()) * (sizeof(Pose) + sizeof(std::pair<float, int>));
  return Status::Ok();
}

// One registration from init (the caller checked the sizes and the start): the pyramid, the solver,
// the polish and the verdict. deadline: 0 or the platform::now_seconds() to stop at.
Status Registrar::Impl::register_once(const uint8_t* rgb, const PinholeIntrinsics& intr, const Pose& init, double deadline,
                                      RegisterResult* out) {
  Impl& d = *this;
  const Camera full{intr, init};
  const RegisterOptions& o = d.opt;
  const double t0 = platform::now_seconds();
  d.decoded_valid = d.key_valid = d.polish_render_valid = false;  // the model may have changed since the last call
  *out = RegisterResult();
  out->pose = init;

  // Pyramid: from the largest divisor (a power of two times the finest) still min_coarse_width wide.
  const int finest = std::min(o.finest_downscale, std::max(1, std::min(intr.width, intr.height)));
  int coarsest = finest, levels = 1;
  while (levels < o.max_levels && intr.width / (coarsest * 2) >= o.min_coarse_width && intr.height / (coarsest * 2) >= 8) {
    coarsest *= 2;
    ++levels;
  }

  // The start: the finest level's residual, and whether the model is visible at all.
  Camera cam = scaled_camera(full, finest);
  io::box_downsample_rgb(rgb, intr.width, intr.height, finest, d.target.data());
  size_t decoded = 0;
  GS_RETURN_IF_ERROR(d.render_antialiased(full, finest, &decoded));
  if (decoded == 0) {
    out->verdict = RegisterVerdict::kNothingVisible;
    out->milliseconds = 1e3 * (platform::now_seconds() - t0);
    return Status::Ok();
  }
  out->initial_rmse = d.rmse(cam);

  Camera current = full;
  bool timed_out = false;
  if (o.solver == RegisterOptions::kKeyframe) {
    GS_RETURN_IF_ERROR(d.keyframe_alignment(&current, rgb, coarsest, finest, &out->iterations, &out->levels, deadline));
    // Polish against the renderer itself (occlusion and view-dependent colour): below full
    // resolution against the anti-aliased render (render_polish), at full resolution with the
    // renderer's forward-mode Jacobian (a direct render below full resolution aliases sub-pixel
    // Gaussians, which would bias it).
    Camera level = scaled_camera(current, finest);
    io::box_downsample_rgb(rgb, intr.width, intr.height, finest, d.target.data());
    if (finest > 1 && o.render_polish_iterations > 0 && !(deadline > 0 && platform::now_seconds() > deadline)) {
      const int pl = o.polish_level_downscale > 0 && finest % o.polish_level_downscale == 0 ? o.polish_level_downscale : finest;
      GS_RETURN_IF_ERROR(d.render_polish(&current, rgb, pl, &out->iterations, deadline));
      if (pl != finest) d.polish_render_valid = false;  // the verdict renders at the finest level itself
    }
    if (finest == 1 && d.decode(current) > 0 && o.polish_iterations > 0 && !(deadline > 0 && platform::now_seconds() > deadline)) {
      RegisterOptions saved = d.opt;
      d.opt.max_iterations_per_level = o.polish_iterations;
      const Status st = d.level_gauss_newton(level, &out->iterations, deadline);
      d.opt = saved;
      GS_RETURN_IF_ERROR(st);
      current.pose = level.pose;
    }
  }
  for (int s = coarsest; o.solver != RegisterOptions::kKeyframe && s >= finest; s /= 2) {
    if (deadline > 0 && platform::now_seconds() > deadline) {
      timed_out = true;
      break;
    }
    Camera level = scaled_camera(current, s);
    io::box_downsample_rgb(rgb, intr.width, intr.height, s, d.target.data());
    if (d.decode(current) == 0) break;  // the pose left the model: keep what we have
    Status st = o.solver == RegisterOptions::kAdam ? d.level_adam(level, &out->iterations, deadline)
                                                   : d.level_gauss_newton(level, &out->iterations, deadline);
    GS_RETURN_IF_ERROR(st);
    current.pose = level.pose;
    ++out->levels;
    if (s == finest) break;
  }
  if (deadline > 0 && platform::now_seconds() > deadline) timed_out = true;

  // The final residual and coverage at the pose found (finest level, decoded for that pose); the
  // start pose is kept if it fits better.
  cam = scaled_camera(current, finest);
  io::box_downsample_rgb(rgb, intr.width, intr.height, finest, d.target.data());
  size_t n_final = 0;
  double final_rmse = INFINITY, cover = 0;
  if (d.polish_render_valid) {
    final_rmse = d.rmse(cam);
    std::copy(d.fin_alpha.begin(), d.fin_alpha.end(), d.lvl_alpha.begin());
    cover = d.level_coverage(cam);
  } else {
    GS_RETURN_IF_ERROR(d.render_antialiased(current, finest, &n_final));
    if (n_final > 0) {
      final_rmse = d.rmse(cam);
      cover = d.level_coverage(cam);
    }
  }
  if (!(final_rmse <= out->initial_rmse)) {
    current.pose = init;
    cam = scaled_camera(current, finest);
    GS_RETURN_IF_ERROR(d.render_antialiased(current, finest, &n_final));
    final_rmse = d.rmse(cam);
    cover = d.level_coverage(cam);
  }
  out->pose = current.pose;
  out->final_rmse = final_rmse;
  out->coverage = cover;
  const double var = d.target_variance(cam);
  out->explained = var > 1e-8 ? std::max(0.0, 1.0 - final_rmse * final_rmse / var) : 0.0;
  const double moved_rot = pose::rotation_error_deg(init, current.pose);
  double c0[3], c1[3];
  pose::centre(init, c0);
  pose::centre(current.pose, c1);
  const double moved_t = std::sqrt((c0[0] - c1[0]) * (c0[0] - c1[0]) + (c0[1] - c1[1]) * (c0[1] - c1[1]) +
                                   (c0[2] - c1[2]) * (c0[2] - c1[2]));
  if (moved_rot > o.max_rotation_deg || moved_t > o.max_translation * d.extent) out->verdict = RegisterVerdict::kDiverged;
  else if (timed_out) out->verdict = RegisterVerdict::kTimeBudget;
  else if (!(final_rmse <= o.max_rmse) || out->explained < o.min_explained || cover < o.min_coverage)
    out->verdict = RegisterVerdict::kPoorFit;
  else out->verdict = RegisterVerdict::kConverged;
  out->milliseconds = 1e3 * (platform::now_seconds() - t0);
  return Status::Ok();
}

}  // namespace gs::pose
