// SPDX-License-Identifier: MIT
// The training loop (see gs/model/trainer.h): view sampling, learning-rate schedules, dense Adam
// per parameter group, densification statistics, anchor growing / pruning under the budgets,
// image-feature refresh, checkpoints; and ModelRenderer for evaluation.
#include "gs/model/trainer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "byte_codec.h"
#include "cloud_decode.h"
#include "float_backend.h"
#include "gs/io/composite.h"
#include "gs/model/image_features.h"
#include "gs/model/quant_decoder.h"
#include "gs/optim/adam.h"
#include "gs/optim/schedule.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/model/register.h"
#include "gs/render.h"

namespace gs::model {

namespace {

constexpr char kCheckpointMagic[8] = {'H', 'B', 'G', 'S', 'C', 'K', 'P', 'T'};
constexpr uint32_t kCheckpointVersion = 3;  // 2: training poses and their Adam state; 3: held-back views
// Tile pairs planned per Gaussian of capacity where the renderer is used through
// FloatBackend::render_params (it re-plans with 1.5x headroom when a view needs more): training
// snowmiku_plush at 393 px used at most 1.5 (130k pairs for 88k Gaussians of capacity); 8 cost
// 85 MB of arena per renderer for nothing.
constexpr size_t kReplannedIsectsPerGaussian = 3;

// One optimised tensor: parameters (owned by the model), gradient and Adam moments. Per-anchor
// groups hold row_floats values per anchor and are stepped over the live rows only.
struct ParamGroup {
  const char* name = "";
  float* param = nullptr;
  size_t row_floats = 0;  // per-anchor groups: floats per anchor; 0 = a fixed-size tensor
  size_t fixed_size = 0;  // fixed-size groups: element count
  std::vector<float> grad, m, v;
  double lr0 = 0, lr1 = 0;
  size_t live(size_t anchors) const { return row_floats ? row_floats * anchors : fixed_size; }
};

struct CellKey {
  int64_t x, y, z;
  bool operator<(const CellKey& o) const { return x != o.x ? x < o.x : (y != o.y ? y < o.y : z < o.z); }
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

}  // namespace

float cameras_extent(const std::vector<const Camera*>& cameras) {
  if (cameras.empty()) return 1.0f;
  std::vector<double> centres(cameras.size() * 3);
  double mean[3] = {0, 0, 0};
  for (size_t i = 0; i < cameras.size(); ++i) {
    camera_centre(cameras[i]->pose, &centres[3 * i]);
    for (int c = 0; c < 3; ++c) mean[c] += centres[3 * i + c] / double(cameras.size());
  }
  double radius = 0;
  for (size_t i = 0; i < cameras.size(); ++i) {
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += (centres[3 * i + c] - mean[c]) * (centres[3 * i + c] - mean[c]);
    radius = std::max(radius, std::sqrt(d2));
  }
  return float(1.1 * (radius > 0 ? radius : 1.0));
}

// ---- Trainer ----------------------------------------------------------------------------------

struct Trainer::Impl {
  HybridModel model;
  TrainOptions opt;
  std::vector<const io::DatasetView*> views;
  // [views] the photos of masked views composited on the evaluation background, for the image
  // features and the registration passes (empty for a view without a mask: its image is used).
  std::vector<io::Image8> composited;
  std::vector<Camera> view_cameras;     // [views] current training poses (optimised in place)
  std::vector<const Camera*> cameras;   // -> view_cameras (the image-feature bank reads these)
  std::vector<double> pose_m, pose_v;   // [views, 6] Adam moments of the pose twists
  std::vector<int32_t> pose_steps;      // [views] Adam steps taken per pose
  std::unique_ptr<pose::Registrar> registrar;  // registration passes (pose_register_every > 0)
  platform::ThreadPool* pool = nullptr;
  const simd::KernelTable* kernels = nullptr;
  ImageFeatureBank bank;
  Renderer renderer;
  detail::FloatBackend backend;
  StepWorkspace<float> ws;
  std::vector<float> target;  // [H, W, 3] of the current view
  std::vector<ParamGroup> groups;  // offsets, log_scales, features, then the MLPs
  int iteration = 0;
  detail::SplitMix64 rng;
  std::vector<int32_t> view_order;
  size_t view_pos = 0;
  std::vector<uint8_t> held;  // [views] 1: held back (not trained on) until registered
  // Densification statistics (capacity rows).
  std::vector<float> opacity_accum;   // [cap]
  std::vector<int32_t> anchor_seen;   // [cap]
  std::vector<float> grad_accum;      // [cap, k]
  std::vector<int32_t> grad_denom;    // [cap, k]
  // Growth scratch (capacity-sized; std::sort works in place).
  std::vector<CellKey> existing_cells;            // [cap]
  std::vector<std::pair<CellKey, uint32_t>> cand;  // [cap k] (cell, candidate index row * k + j)
  std::vector<uint8_t> pruned;                     // [cap]
  uint64_t planned_bytes = 0;
  int nonfinite_steps = 0, nonfinite_in_a_row = 0, first_nonfinite = 0;
  int plan_w = 1, plan_h = 1;  // largest training view: what the pipeline is planned for
  Status growth_status;        // a failed growth (allocation) reported by step()
  int growths = 0;             // times the rows grew (each one allocation, at a densification step)

  // True when every live gradient (and the pose twist) is finite. The exponent bits are tested
  // as integers so that the scan vectorises (a float reduction would not, without fast-math).
  bool gradients_finite(size_t M, const double v_pose[6]) const {
    for (const ParamGroup& g : groups) {
      const size_t n = g.live(M);
      const float* p = g.grad.data();
      uint32_t bad = 0;
      for (size_t i = 0; i < n; ++i) {
        uint32_t bits;
        std::memcpy(&bits, p + i, 4);
        bad |= uint32_t((bits & 0x7f800000u) == 0x7f800000u);
      }
      if (bad) return false;
    }
    for (int i = 0; i < 6; ++i)
      if (!std::isfinite(v_pose[i])) return false;
    return true;
  }

  size_t cap() const { return model.capacity(); }
  size_t budget() const { return model.config.anchor_capacity(); }

  // Plans every capacity-sized array for cap() rows: the renderer, decoder workspace and
  // registrar, the densification statistics and growth scratch (resize: live rows keep their
  // values), and the byte count. Called at creation and after the rows grow.
  Status plan(const TrainOptions& options) {
    const size_t c = cap(), K = size_t(k());
    Expected<RenderCapacity> rc = detail::plan_model_pipeline(model, c, plan_w, plan_h, plan_w, plan_h, pool, kernels,
                                                              &renderer, &backend, &ws, /*training=*/true,
                                                              kReplannedIsectsPerGaussian);
    if (!rc.ok()) return rc.status();
    opacity_accum.resize(c, 0.0f);
    anchor_seen.resize(c, 0);
    grad_accum.resize(c * K, 0.0f);
    grad_denom.resize(c * K, 0);
    existing_cells.resize(c, CellKey{0, 0, 0});
    cand.resize(c * K, {CellKey{0, 0, 0}, 0u});
    pruned.resize(c, 0);
    uint64_t bytes = Renderer::plan_bytes(*rc);
    registrar.reset();
    // A run that may hold views back keeps its registrar even once none is held (a resumed run
    // learns which views are held from its checkpoint, after this plan).
    if (options.pose_register_every > 0 || options.held_back_register_every > 0) {
      pose::RegisterOptions ro;
      ro.max_iterations_per_level = 10;
      for (int ch = 0; ch < 3; ++ch) ro.background[ch] = opt.background.rgb[ch];
      Expected<std::unique_ptr<pose::Registrar>> reg = pose::Registrar::create(model, plan_w, plan_h, ro, pool, kernels, c);
      if (!reg.ok()) return reg.status();
      registrar = std::move(reg).value();
      bytes += registrar->planned_bytes();
    }
    bytes += uint64_t(model.positions.size() + model.offsets.size() + model.log_scales.size() + model.features.size() +
                      model.image_raw.size()) * 4;
    for (const ParamGroup& g : groups) bytes += uint64_t(g.grad.size() * 3) * 4;
    bytes += uint64_t(ws.X.size() * 3 + ws.means.size() * 4 + ws.quats.size() * 2 + ws.rgb.size() * 2) * 4;
    bytes += uint64_t(c * K) * (4 + 4 + sizeof(cand[0]));
    planned_bytes = bytes;
    return Status::Ok();
  }

  // Memory follows the scene: the rows (model, Adam moments, gradients, statistics, pipeline) grow
  // to hold `rows` anchors, by at least half again, never past the anchor budget. Values of the
  // live rows are kept; results do not depend on the capacity.
  Status ensure_capacity(size_t rows) {
    if (rows <= cap()) return Status::Ok();
    const size_t c = std::min(budget(), std::max(rows, cap() + cap() / 2));
    const ModelConfig& mc = model.config;
    model.positions.resize(c * 3, 0.0f);
    model.offsets.resize(c * size_t(mc.k) * 3, 0.0f);
    model.log_scales.resize(c * 6, 0.0f);
    model.features.resize(c * size_t(mc.feature_dim), 0.0f);
    if (paper()) model.image_raw.resize(c * size_t(kImageRawDim), 0.0f);
    float* const anchor_params[3] = {model.offsets.data(), model.log_scales.data(), model.features.data()};
    for (size_t gi = 0; gi < groups.size(); ++gi) {
      ParamGroup& g = groups[gi];
      if (!g.row_floats) continue;
      g.param = anchor_params[gi];  // the anchor groups come first, in this order (build_groups)
      g.grad.resize(g.row_floats * c, 0.0f);
      g.m.resize(g.row_floats * c, 0.0f);
      g.v.resize(g.row_floats * c, 0.0f);
    }
    ++growths;
    return plan(opt);
  }
  int k() const { return model.config.k; }
  bool paper() const { return uses_image_features(model.config.image_features); }
  // Every anchor's raw image feature from the current poses (visible mode: after the depth buffers
  // of the current anchors, discs of one voxel).
  void refresh_image_features() {
    bank.set_occluders(model.positions.data(), model.anchor_count, model.voxel_size, pool);
    bank.compute(model.positions.data(), model.anchor_count, model.image_raw.data(), pool);
  }

  ModelParamsT<float> params() const { return detail::model_params(model); }

  void build_groups() {
    const ModelConfig& c = model.config;
    const double E = model.scene_extent;
    groups.clear();
    auto anchor_group = [&](const char* name, std::vector<float>& v, size_t row, double lr0, double lr1) {
      ParamGroup g;
      g.name = name;
      g.param = v.data();
      g.row_floats = row;
      g.lr0 = lr0;
      g.lr1 = lr1;
      groups.push_back(std::move(g));
    };
    anchor_group("offsets", model.offsets, size_t(c.k) * 3, opt.lr_offset_init * E, opt.lr_offset_final * E);
    anchor_group("scaling", model.log_scales, 6, opt.lr_scaling, opt.lr_scaling);
    anchor_group("features", model.features, size_t(c.feature_dim), opt.lr_feature, opt.lr_feature);
    const double lrs[kMlpCount][2] = {{opt.lr_mlp_opacity_init, opt.lr_mlp_opacity_final},
                                      {opt.lr_mlp_cov_init, opt.lr_mlp_cov_final},
                                      {opt.lr_mlp_color_init, opt.lr_mlp_color_final},
                                      {opt.lr_mlp_image_init, opt.lr_mlp_image_final}};
    static const char* names[kMlpCount] = {"mlp_opacity", "mlp_cov", "mlp_color", "mlp_image"};
    for (int i = 0; i < kMlpCount; ++i) {
      if (model.mlps[i].params.empty()) continue;
      ParamGroup g;
      g.name = names[i];
      g.param = model.mlps[i].params.data();
      g.fixed_size = model.mlps[i].params.size();
      g.lr0 = lrs[i][0];
      g.lr1 = lrs[i][1];
      groups.push_back(std::move(g));
    }
    for (ParamGroup& g : groups) {
      const size_t n = g.row_floats ? g.row_floats * cap() : g.fixed_size;
      g.grad.assign(n, 0.0f);
      g.m.assign(n, 0.0f);
      g.v.assign(n, 0.0f);
    }
  }

  ModelGradsT<float> grads() {
    ModelGradsT<float> g;
    g.offsets = groups[0].grad.data();
    g.log_scales = groups[1].grad.data();
    g.features = groups[2].grad.data();
    size_t gi = 3;
    for (int i = 0; i < kMlpCount; ++i) g.mlp[i] = model.mlps[i].params.empty() ? nullptr : groups[gi++].grad.data();
    return g;
  }

  // The next training view, skipping held-back ones (create() refuses a run with every view held).
  int next_view() {
    for (;;) {
      if (view_pos >= view_order.size()) {  // new epoch: Fisher-Yates with the run's generator
        for (size_t i = 0; i < view_order.size(); ++i) view_order[i] = int32_t(i);
        for (size_t i = view_order.size(); i > 1; --i) std::swap(view_order[i - 1], view_order[rng.next() % i]);
        view_pos = 0;
      }
      const int v = view_order[view_pos++];
      if (!held[size_t(v)]) return v;
    }
  }

  // View v takes a pose found by registration: its Adam state starts again.
  void adopt_pose(size_t v, const Pose& pose) {
    view_cameras[v].pose = pose;
    std::fill(pose_m.begin() + std::ptrdiff_t(6 * v), pose_m.begin() + std::ptrdiff_t(6 * v + 6), 0.0);
    std::fill(pose_v.begin() + std::ptrdiff_t(6 * v), pose_v.begin() + std::ptrdiff_t(6 * v + 6), 0.0);
    pose_steps[v] = 0;
  }

  // Registers every held-back view against the current model; a converged one gets that pose
  // (Adam state reset) and joins training. Returns how many joined.
  Status register_held(int it, int* released) {
    *released = 0;
    registrar->mutable_options().finest_downscale = std::max(2, downscale_at(it));
    for (size_t v = 0; v < views.size(); ++v) {
      if (!held[v]) continue;
      pose::RegisterResult r;
      GS_RETURN_IF_ERROR(registrar->register_view(photo(v).pixels.data(), view_cameras[v].intr, view_cameras[v].pose, &r));
      if (!r.converged()) continue;
      adopt_pose(v, r.pose);
      held[v] = 0;
      ++*released;
    }
    return Status::Ok();
  }
  int held_count() const { return int(std::count(held.begin(), held.end(), uint8_t(1))); }

  // The photo of view v as the model should render it (composited when the view has a mask).
  const io::Image8& photo(size_t v) const { return composited[v].empty() ? views[v]->image : composited[v]; }

  // Target at resolution divisor s (s x s block means, matching scaled_camera), composited on bg.
  void load_target(const io::DatasetView& v, int s, const float bg[3]) {
    io::composite_target(v.image, v.mask, s, bg, target.data());
  }

  int downscale_at(int it) const {
    if (opt.coarse_levels <= 0) return 1;
    const double coarse_end = opt.coarse_fraction * double(opt.iterations);
    if (double(it) > coarse_end) return 1;
    const int level = std::min(opt.coarse_levels - 1, int(double(it - 1) * opt.coarse_levels / std::max(coarse_end, 1.0)));
    return 1 << (opt.coarse_levels - level);
  }

  // Registers every training pose against the current model (see TrainOptions); returns how many
  // poses moved.
  Status register_all(int it, int* moved) {
    *moved = 0;
    // Registration at no finer than half resolution: a pass is for large errors (the joint Adam
    // steps refine at full resolution), and its cost grows with the pixel count.
    registrar->mutable_options().finest_downscale = std::max(2, downscale_at(it));
    for (size_t v = 0; v < views.size(); ++v) {
      pose::RegisterResult r;
      GS_RETURN_IF_ERROR(registrar->register_view(photo(v).pixels.data(), view_cameras[v].intr, view_cameras[v].pose, &r));
      if (!(r.final_rmse < r.initial_rmse) || r.verdict == pose::RegisterVerdict::kDiverged || r.verdict == pose::RegisterVerdict::kNothingVisible)
        continue;
      adopt_pose(v, r.pose);
      ++*moved;
    }
    return Status::Ok();
  }

  // One Adam step on the pose of view vi from its twist gradient g (rho, phi), retracted on SE(3).
  void pose_adam(size_t vi, const double g[6], int it) {
    const double warm = optim::warmup(opt.pose_warmup, it);
    const double lr_rot = warm * optim::expon_lr(opt.lr_pose_rotation_init, opt.lr_pose_rotation_final, opt.schedule_iterations, it);
    const double lr_tr = warm * model.scene_extent *
                         optim::expon_lr(opt.lr_pose_translation_init, opt.lr_pose_translation_final, opt.schedule_iterations, it);
    const int step = ++pose_steps[vi];
    double xi[6];
    optim::twist_adam_step(g, lr_tr, lr_rot, step, opt.adam_eps, &pose_m[6 * vi], &pose_v[6 * vi], xi);
    pose::apply_left_twist(xi, &view_cameras[vi].pose);
  }

  void adam_all(int it) {
    const size_t M = model.anchor_count;
    for (ParamGroup& g : groups) {
      const simd::AdamParams ap = optim::adam_params(optim::expon_lr(g.lr0, g.lr1, opt.schedule_iterations, it), it, opt.adam_eps);
      optim::adam_step(*kernels, pool, ap, g.live(M), g.param, g.grad.data(), g.m.data(), g.v.data());
    }
  }

  void accumulate_stats(const Camera& cam) {
    const size_t V = last_visible;
    const int K = k();
    const float* alpha = ws.y[kMlpOpacity].data();
    for (size_t v = 0; v < V; ++v) {
      const uint32_t row = ws.rows[v];
      float sum = 0;
      for (int j = 0; j < K; ++j) sum += std::max(alpha[v * size_t(K) + size_t(j)], 0.0f);
      opacity_accum[row] += sum;
      anchor_seen[row] += 1;
    }
    const int32_t* radii = renderer.radii();
    const float hw = 0.5f * float(cam.intr.width), hh = 0.5f * float(cam.intr.height);
    for (size_t n = 0; n < ws.ng.count; ++n) {
      if (radii[n] <= 0) continue;
      const uint32_t s = ws.source[n];
      const size_t idx = size_t(ws.rows[s / uint32_t(K)]) * size_t(K) + s % uint32_t(K);
      const float gx = ws.v_means2d[2 * n] * hw, gy = ws.v_means2d[2 * n + 1] * hh;  // NDC-space gradient
      grad_accum[idx] += std::sqrt(gx * gx + gy * gy);
      grad_denom[idx] += 1;
    }
  }

  // Moves anchor row src to dst in every per-anchor array (model, optimiser, statistics).
  void move_row(size_t src, size_t dst) {
    const ModelConfig& c = model.config;
    auto mv = [&](float* base, size_t w) { std::memmove(base + dst * w, base + src * w, w * sizeof(float)); };
    mv(model.positions.data(), 3);
    mv(model.offsets.data(), size_t(c.k) * 3);
    mv(model.log_scales.data(), 6);
    mv(model.features.data(), size_t(c.feature_dim));
    if (paper()) mv(model.image_raw.data(), kImageRawDim);
    for (size_t gi = 0; gi < 3; ++gi) {
      mv(groups[gi].m.data(), groups[gi].row_floats);
      mv(groups[gi].v.data(), groups[gi].row_floats);
    }
    opacity_accum[dst] = opacity_accum[src];
    anchor_seen[dst] = anchor_seen[src];
    mv(grad_accum.data(), size_t(c.k));
    std::memmove(grad_denom.data() + dst * size_t(c.k), grad_denom.data() + src * size_t(c.k), size_t(c.k) * sizeof(int32_t));
  }

  // Clears a newly added anchor row's optimiser state and statistics.
  void clear_row(size_t row) {
    for (size_t gi = 0; gi < 3; ++gi) {
      const size_t w = groups[gi].row_floats;
      std::fill(groups[gi].m.begin() + std::ptrdiff_t(row * w), groups[gi].m.begin() + std::ptrdiff_t((row + 1) * w), 0.0f);
      std::fill(groups[gi].v.begin() + std::ptrdiff_t(row * w), groups[gi].v.begin() + std::ptrdiff_t((row + 1) * w), 0.0f);
    }
    opacity_accum[row] = 0;
    anchor_seen[row] = 0;
    for (int j = 0; j < k(); ++j) {
      grad_accum[row * size_t(k()) + size_t(j)] = 0;
      grad_denom[row * size_t(k()) + size_t(j)] = 0;
    }
  }

  static CellKey cell_of(const float* p, double size) {
    return {int64_t(std::llround(double(p[0]) / size)), int64_t(std::llround(double(p[1]) / size)),
            int64_t(std::llround(double(p[2]) / size))};
  }

  // One growth level (Part B section 7 step 2); returns the number of anchors added.
  size_t grow_level(int level, double min_denom) {
    const ModelConfig& c = model.config;
    const size_t M = model.anchor_count, K = size_t(c.k);
    const double threshold = opt.densify_grad_threshold * std::pow(double(opt.update_hierarchy_factor / 2), level);
    int factor = opt.update_init_factor;
    for (int l = 0; l < level; ++l) factor /= opt.update_hierarchy_factor;
    const double size = double(model.voxel_size) * double(std::max(factor, 1));
    const double keep = std::pow(0.5, level + 1);
    size_t nc = 0;
    for (size_t idx = 0; idx < M * K; ++idx) {
      const bool random_keep = rng.uniform() > keep;  // drawn for every candidate: a fixed stream
      if (!(grad_denom[idx] > min_denom) || !random_keep) continue;
      if (grad_accum[idx] / float(grad_denom[idx]) < threshold) continue;
      const size_t row = idx / K, j = idx % K;
      const float* a = &model.positions[3 * row];
      const float* o = &model.offsets[(row * K + j) * 3];
      const float* ls = &model.log_scales[6 * row];
      const float mu[3] = {a[0] + o[0] * std::exp(ls[0]), a[1] + o[1] * std::exp(ls[1]), a[2] + o[2] * std::exp(ls[2])};
      cand[nc++] = {cell_of(mu, size), uint32_t(idx)};
    }
    if (nc == 0) return 0;
    // Room for every candidate cell (at most nc new anchors), within the budget.
    if (Status st = ensure_capacity(std::min(budget(), M + nc)); !st.ok()) {
      growth_status = st;
      return 0;
    }
    std::sort(cand.begin(), cand.begin() + std::ptrdiff_t(nc));
    for (size_t i = 0; i < M; ++i) existing_cells[i] = cell_of(&model.positions[3 * i], size);
    std::sort(existing_cells.begin(), existing_cells.begin() + std::ptrdiff_t(M));
    size_t added = 0;
    for (size_t b = 0; b < nc;) {
      size_t e = b + 1;
      while (e < nc && cand[e].first == cand[b].first) ++e;
      const CellKey cell = cand[b].first;
      const bool taken = std::binary_search(existing_cells.begin(), existing_cells.begin() + std::ptrdiff_t(M), cell);
      if (!taken && model.anchor_count < cap()) {
        const size_t row = model.anchor_count++;
        const float pos[3] = {float(double(cell.x) * size), float(double(cell.y) * size), float(double(cell.z) * size)};
        std::copy(pos, pos + 3, &model.positions[3 * row]);
        std::fill(&model.offsets[row * K * 3], &model.offsets[(row + 1) * K * 3], 0.0f);
        std::fill(&model.log_scales[6 * row], &model.log_scales[6 * row + 6], float(std::log(size)));
        // Feature = element-wise max over the parents in this cell (Scaffold-GS; order-consistent).
        float* f = &model.features[row * size_t(c.feature_dim)];
        for (int d = 0; d < c.feature_dim; ++d) {
          float best = -INFINITY;
          for (size_t q = b; q < e; ++q) best = std::max(best, model.features[(cand[q].second / K) * size_t(c.feature_dim) + size_t(d)]);
          f[d] = best;
        }
        if (paper()) bank.compute(pos, 1, &model.image_raw[row * size_t(kImageRawDim)], nullptr);
        clear_row(row);
        ++added;
      }
      b = e;
    }
    return added;
  }

  void adjust_anchors() {
    const size_t K = size_t(k());
    const double min_denom = opt.update_interval * opt.success_threshold * 0.5;
    const size_t M0 = model.anchor_count;
    size_t added = 0;
    for (int level = 0; level < opt.update_depth; ++level) {
      if (level > 0 && added == 0) break;  // deeper levels run only after a level added something
      added += grow_level(level, min_denom);
    }
    for (size_t idx = 0; idx < M0 * K; ++idx)
      if (grad_denom[idx] > min_denom) {
        grad_denom[idx] = 0;
        grad_accum[idx] = 0;
      }
    // Prune anchors that stayed nearly transparent over enough views; never the last anchor.
    const double min_seen = opt.update_interval * opt.success_threshold;
    size_t keep_count = 0;
    const size_t M = model.anchor_count;
    for (size_t i = 0; i < M; ++i) {
      pruned[i] = anchor_seen[i] > min_seen && opacity_accum[i] < opt.min_opacity * anchor_seen[i];
      keep_count += !pruned[i];
    }
    if (keep_count > 0) {
      size_t dst = 0;
      for (size_t i = 0; i < M; ++i) {
        if (pruned[i]) continue;
        if (dst != i) move_row(i, dst);
        ++dst;
      }
      model.anchor_count = dst;
    }
    for (size_t i = 0; i < model.anchor_count; ++i) {
      if (anchor_seen[i] > min_seen) {
        opacity_accum[i] = 0;
        anchor_seen[i] = 0;
      }
      for (int l = 3; l < 6; ++l) model.log_scales[6 * i + size_t(l)] = std::min(model.log_scales[6 * i + size_t(l)], 0.05f);
    }
  }

  size_t last_visible = 0;
};

Trainer::Trainer() : impl_(new Impl) {}
Trainer::~Trainer() = default;

Expected<std::unique_ptr<Trainer>> Trainer::create(HybridModel model, const std::vector<const io::DatasetView*>& train_views,
                                                   const TrainOptions& options, platform::ThreadPool* pool,
                                                   const simd::KernelTable* kernels) {
  if (train_views.empty()) return invalid_argument("trainer: no training views");
  GS_RETURN_IF_ERROR(model.config.validate());
  if (model.anchor_count == 0) return invalid_argument("trainer: the model has no anchors");
  if (model.anchor_count > model.capacity()) return invalid_argument("trainer: the model holds more anchors than its capacity");
  if (options.iterations < 0 || options.schedule_iterations < 1 || options.update_interval < 1 || options.update_depth < 0 ||
      options.update_hierarchy_factor < 1 || options.update_init_factor < 1)
    return invalid_argument("trainer: iteration counts and densification intervals must be positive");
  if (options.max_nonfinite_in_a_row < 1) return invalid_argument("trainer: max_nonfinite_in_a_row must be at least 1");
  if (!options.held_back_views.empty()) {
    if (options.held_back_views.size() != train_views.size())
      return invalid_argument("trainer: held_back_views has " + std::to_string(options.held_back_views.size()) + " entries for " +
                              std::to_string(train_views.size()) + " training views");
    if (std::find(options.held_back_views.begin(), options.held_back_views.end(), uint8_t(0)) == options.held_back_views.end())
      return invalid_argument("trainer: every training view is held back; nothing would train");
    if (options.held_back_register_every < 0) return invalid_argument("trainer: held_back_register_every must not be negative");
  }
  if (options.coarse_levels < 0 || options.coarse_levels > 4 || !(options.coarse_fraction >= 0 && options.coarse_fraction <= 1))
    return invalid_argument("trainer: coarse_levels must be 0-4 and coarse_fraction in [0, 1]");
  if (!(options.lr_pose_rotation_init >= 0) || !(options.lr_pose_rotation_final > 0) || !(options.lr_pose_translation_init >= 0) ||
      !(options.lr_pose_translation_final > 0) || options.pose_warmup < 0)
    return invalid_argument("trainer: pose learning rates must be positive and the warm-up non-negative");
  std::unique_ptr<Trainer> t(new Trainer());
  Impl& d = *t->impl_;
  d.model = std::move(model);
  d.opt = options;
  d.views = train_views;
  d.pool = pool;
  d.kernels = kernels ? kernels : &simd::best_kernel_table();
  int max_w = 1, max_h = 1;
  std::vector<const io::Image8*> images;
  for (size_t i = 0; i < train_views.size(); ++i) {
    const io::DatasetView& v = *train_views[i];
    GS_RETURN_IF_ERROR(validate_camera(v.camera));
    if (v.image.channels != 3 || v.image.width != v.camera.intr.width || v.image.height != v.camera.intr.height)
      return invalid_argument("trainer: view '" + v.name + "' has a " + std::to_string(v.image.width) + "x" +
                              std::to_string(v.image.height) + " image with " + std::to_string(v.image.channels) +
                              " channels, but its camera is " + std::to_string(v.camera.intr.width) + "x" +
                              std::to_string(v.camera.intr.height) + " RGB");
    if (!v.mask.empty() && (v.mask.channels != 1 || v.mask.width != v.image.width || v.mask.height != v.image.height))
      return invalid_argument("trainer: view '" + v.name + "' has a mask that is not one channel of its image's size");
    d.view_cameras.push_back(v.camera);
    d.composited.push_back(v.mask.empty() ? io::Image8{} : io::composite_rgb8(v.image, v.mask, options.background.rgb));
    max_w = std::max(max_w, v.camera.intr.width);
    max_h = std::max(max_h, v.camera.intr.height);
  }
  for (const Camera& c : d.view_cameras) d.cameras.push_back(&c);
  for (size_t i = 0; i < train_views.size(); ++i) images.push_back(&d.photo(i));
  d.pose_m.assign(6 * train_views.size(), 0.0);
  d.pose_v.assign(6 * train_views.size(), 0.0);
  d.pose_steps.assign(train_views.size(), 0);
  if (d.paper()) GS_RETURN_IF_ERROR(d.bank.init(d.cameras, images, d.model.config.image_features));
  d.plan_w = max_w;
  d.plan_h = max_h;
  d.target.assign(size_t(max_w) * size_t(max_h) * 3, 0.0f);
  d.build_groups();
  d.rng.state = options.seed * 0x9E3779B97F4A7C15ull + 7;
  d.view_order.assign(train_views.size(), 0);
  d.view_pos = d.view_order.size();  // first call shuffles
  d.held = options.held_back_views.empty() ? std::vector<uint8_t>(train_views.size(), 0) : options.held_back_views;
  for (uint8_t& h : d.held) h = h ? 1 : 0;
  GS_RETURN_IF_ERROR(d.plan(options));
  if (d.paper()) d.refresh_image_features();
  return t;
}

Status Trainer::step(IterationStats* stats) {
  Impl& d = *impl_;
  const double t0 = platform::now_seconds();
  const int it = d.iteration + 1;
  const int vi = d.next_view();
  const io::DatasetView& view = *d.views[size_t(vi)];
  const int scale = d.downscale_at(it);
  const Camera cam = scaled_camera(d.view_cameras[size_t(vi)], scale);
  float bg[3] = {d.opt.background.rgb[0], d.opt.background.rgb[1], d.opt.background.rgb[2]};
  if (d.opt.background.random)
    for (float& c : bg) c = float(d.rng.next() >> 40) * (1.0f / 16777216.0f);  // 24 bits, [0, 1)
  for (int c = 0; c < 3; ++c) d.backend.background[c] = bg[c];
  d.load_target(view, scale, bg);
  const size_t M = d.model.anchor_count;
  for (ParamGroup& g : d.groups) std::fill(g.grad.begin(), g.grad.begin() + std::ptrdiff_t(g.live(M)), 0.0f);
  ModelParamsT<float> p = d.params();
  ModelGradsT<float> grads = d.grads();
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
  if (d.opt.optimize_poses) grads.pose = v_pose;
  StepResult res;
  GS_RETURN_IF_ERROR(step_forward_backward(d.backend, p, cam, d.target.data(), d.opt.step, d.ws, &grads, &res));
  d.last_visible = res.visible_anchors;
  if (!d.opt.test_nonfinite_iterations.empty() &&
      std::find(d.opt.test_nonfinite_iterations.begin(), d.opt.test_nonfinite_iterations.end(), it) != d.opt.test_nonfinite_iterations.end())
    d.groups.front().grad[0] = std::numeric_limits<float>::quiet_NaN();
  // The numerical guard: one bad step must not write NaN into every parameter through Adam.
  const bool finite = std::isfinite(res.loss) && d.gradients_finite(M, v_pose);
  if (finite) {
    d.nonfinite_in_a_row = 0;
    if (it > d.opt.stat_start && it < d.opt.update_until) d.accumulate_stats(cam);
    d.adam_all(it);
    if (d.opt.optimize_poses) d.pose_adam(size_t(vi), v_pose, it);
  } else {
    if (d.nonfinite_in_a_row == 0) d.first_nonfinite = it;
    ++d.nonfinite_steps;
    if (++d.nonfinite_in_a_row >= d.opt.max_nonfinite_in_a_row)
      return numerical_error("training diverged: the loss or gradients were NaN or infinite in " +
                             std::to_string(d.nonfinite_in_a_row) + " steps in a row (iterations " +
                             std::to_string(d.first_nonfinite) + "-" + std::to_string(it) + ", " +
                             std::to_string(d.nonfinite_steps) + " such steps in all); those steps were skipped, so the "
                             "last checkpoint holds no NaN. Lower the learning rates or check the input poses and images");
  }
  bool adjusted = false;
  if (it > d.opt.update_from && it % d.opt.update_interval == 0 && it < d.opt.update_until) {
    d.adjust_anchors();
    if (!d.growth_status.ok()) return d.growth_status;
    adjusted = true;
  }
  bool refresh = d.paper() && d.opt.image_feature_refresh > 0 && it % d.opt.image_feature_refresh == 0;
  int moved = -1;
  if (d.registrar && d.opt.pose_register_every > 0 && it % d.opt.pose_register_every == 0 && it <= d.opt.pose_register_until) {
    GS_RETURN_IF_ERROR(d.register_all(it, &moved));
    refresh = refresh || (d.paper() && moved > 0);
  }
  int released = -1;
  if (d.registrar && d.opt.held_back_register_every > 0 && it % d.opt.held_back_register_every == 0 &&
      it >= d.opt.held_back_register_from && it <= d.opt.held_back_register_until && d.held_count() > 0) {
    GS_RETURN_IF_ERROR(d.register_held(it, &released));
    refresh = refresh || (d.paper() && released > 0);
  }
  if (refresh) d.refresh_image_features();
  d.iteration = it;
  if (stats) {
    stats->iteration = it;
    stats->view = vi;
    stats->step = res;
    stats->downscale = scale;
    stats->poses_registered = moved;
    stats->views_released = released;
    stats->views_held_back = d.held_count();
    const size_t n = size_t(cam.intr.width) * size_t(cam.intr.height) * 3;
    double se = 0;
    for (size_t i = 0; i < n; ++i) {
      const double e = double(d.ws.rgb[i]) - double(d.target[i]);
      se += e * e;
    }
    stats->psnr = se > 0 ? -10.0 * std::log10(se / double(n)) : 99.0;
    stats->anchors = d.model.anchor_count;
    stats->isects = d.renderer.stats().isects;
    stats->adjusted = adjusted;
    stats->seconds = platform::now_seconds() - t0;
    stats->skipped_nonfinite = !finite;
    stats->nonfinite_steps = d.nonfinite_steps;
  }
  return Status::Ok();
}

int Trainer::iteration() const { return impl_->iteration; }
const std::vector<Camera>& Trainer::cameras() const { return impl_->view_cameras; }
const std::vector<uint8_t>& Trainer::held_back() const { return impl_->held; }
int Trainer::downscale_at(int iteration) const { return impl_->downscale_at(iteration); }
const HybridModel& Trainer::model() const { return impl_->model; }
const TrainOptions& Trainer::options() const { return impl_->opt; }
uint64_t Trainer::planned_bytes() const { return impl_->planned_bytes; }

bool Trainer::can_render(int width, int height) const {
  return width >= 1 && height >= 1 && size_t(width) * size_t(height) * 3 <= impl_->ws.rgb.size() &&
         width <= impl_->renderer.capacity().max_width && height <= impl_->renderer.capacity().max_height;
}

Status Trainer::render(const Camera& camera, const float background[3], float* rgb, size_t* gaussians, float* alpha) {
  Impl& d = *impl_;
  GS_RETURN_IF_ERROR(validate_camera(camera));
  if (!can_render(camera.intr.width, camera.intr.height))
    return capacity_exceeded("trainer: a " + std::to_string(camera.intr.width) + "x" + std::to_string(camera.intr.height) +
                             " render is larger than the training views");
  for (int c = 0; c < 3; ++c) d.backend.background[c] = background[c];  // step() sets its own again
  size_t V = 0;
  const size_t n = decode_view(d.backend, d.params(), camera, d.ws, &V);
  if (gaussians) *gaussians = n;
  GS_RETURN_IF_ERROR(d.backend.render_fwd(camera, d.ws.ng, rgb));
  if (alpha) {
    const size_t px = size_t(camera.intr.width) * size_t(camera.intr.height);
    const float* T = d.renderer.final_transmittance();
    for (size_t i = 0; i < px; ++i) alpha[i] = 1.0f - T[i];
  }
  return Status::Ok();
}

Status Trainer::save_checkpoint(const std::string& path) const {
  const Impl& d = *impl_;
  if (Status st = check_model_finite(d.model, path); !st.ok()) return Status(st.code(), "refusing to write " + st.message());
  detail::ByteWriter w;
  w.raw(kCheckpointMagic, 8);
  w.u32(kCheckpointVersion);
  const std::vector<uint8_t> model = serialize_model(d.model);
  w.u64(model.size());
  w.raw(model.data(), model.size());
  w.u64(d.views.size());
  w.i32(d.iteration);
  w.u64(d.rng.state);
  w.u64(d.view_pos);
  for (int32_t v : d.view_order) w.i32(v);
  const size_t M = d.model.anchor_count, K = size_t(d.model.config.k);
  w.u64(d.groups.size());
  for (const ParamGroup& g : d.groups) {
    w.floats(g.m.data(), g.live(M));
    w.floats(g.v.data(), g.live(M));
  }
  w.floats(d.opacity_accum.data(), M);
  for (size_t i = 0; i < M; ++i) w.i32(d.anchor_seen[i]);
  w.floats(d.grad_accum.data(), M * K);
  for (size_t i = 0; i < M * K; ++i) w.i32(d.grad_denom[i]);
  for (size_t v = 0; v < d.views.size(); ++v) {
    w.floats(d.view_cameras[v].pose.R, 9);
    w.floats(d.view_cameras[v].pose.t, 3);
    w.i32(d.pose_steps[v]);
    for (int i = 0; i < 6; ++i) {
      w.f64(d.pose_m[6 * v + size_t(i)]);
      w.f64(d.pose_v[6 * v + size_t(i)]);
    }
  }
  for (uint8_t h : d.held) w.u8(h);
  w.u64(detail::fnv1a64(w.bytes.data(), w.bytes.size()));
  return platform::write_file_atomic(path, w.bytes.data(), w.bytes.size());
}

Status Trainer::load_checkpoint(const std::string& path) {
  Impl& d = *impl_;
  Expected<std::vector<uint8_t>> file = platform::read_file(path);
  if (!file.ok()) return file.status();
  const std::vector<uint8_t>& bytes = *file;
  detail::ByteReader r(bytes.data(), bytes.size(), path);
  char magic[8] = {};
  if (!r.bytes(magic, 8, "the file signature")) return r.status();
  if (std::memcmp(magic, kCheckpointMagic, 8) != 0) return parse_error(path + ": not an hbgs checkpoint");
  const uint32_t version = r.u32("the format version");
  if (!r.status().ok()) return r.status();
  if (version != kCheckpointVersion && version != 2)
    return unsupported(path + ": checkpoint format version " + std::to_string(version) + ", this hbgs reads versions 2 and " +
                       std::to_string(kCheckpointVersion) + (version == 1 ? " (version 1 predates pose optimisation; restart the run)" : ""));
  if (bytes.size() < 8 || detail::fnv1a64(bytes.data(), bytes.size() - 8) != bytes::load_u64(bytes.data() + bytes.size() - 8))
    return parse_error(path + ": checksum mismatch (the checkpoint is truncated or corrupt)");
  const uint64_t model_size = r.u64("the model size");
  if (!r.status().ok()) return r.status();
  if (model_size > bytes.size() - r.offset()) return parse_error(path + ": the embedded model is larger than the file");
  Expected<HybridModel> model = deserialize_model(bytes.data() + r.offset(), size_t(model_size), path + " (model)");
  if (!model.ok()) return model.status();
  r.skip(size_t(model_size));
  const ModelConfig& a = model->config;
  const ModelConfig& b = d.model.config;
  if (a.k != b.k || a.feature_dim != b.feature_dim || a.hidden != b.hidden || a.image_features != b.image_features ||
      a.image_feature_dim != b.image_feature_dim || a.image_feature_hidden != b.image_feature_hidden ||
      a.max_anchors != b.max_anchors || a.max_gaussians != b.max_gaussians)
    return invalid_argument(path + ": the checkpoint's model configuration differs from this run's");
  const uint64_t nviews = r.u64("the view count");
  if (r.status().ok() && nviews != d.views.size())
    return invalid_argument(path + ": the checkpoint was trained on " + std::to_string(nviews) +
                            " views, this dataset has " + std::to_string(d.views.size()) + " training views");
  const int iteration = r.i32("the iteration");
  const uint64_t rng_state = r.u64("the generator state");
  const uint64_t view_pos = r.u64("the view position");
  std::vector<int32_t> order(d.views.size());
  for (int32_t& v : order) {
    v = r.i32("the view order");
    if (r.status().ok() && (v < 0 || size_t(v) >= d.views.size())) return parse_error(path + ": bad view index");
  }
  const uint64_t ngroups = r.u64("the group count");
  if (!r.status().ok()) return r.status();
  if (ngroups != d.groups.size() || view_pos > order.size() || iteration < 0)
    return parse_error(path + ": inconsistent optimiser state");
  // Everything is checked: adopt the model into the planned arrays (grown first if the checkpoint
  // holds more anchors than this trainer has rows).
  HybridModel& m = d.model;
  const size_t M = model->anchor_count, K = size_t(a.k);
  if (M > d.budget()) return parse_error(path + ": the checkpoint holds more anchors than the budget");
  GS_RETURN_IF_ERROR(d.ensure_capacity(M));
  auto adopt = [](std::vector<float>& dst, const std::vector<float>& src, size_t n) { std::copy(src.begin(), src.begin() + std::ptrdiff_t(n), dst.begin()); };
  adopt(m.positions, model->positions, M * 3);
  adopt(m.offsets, model->offsets, M * K * 3);
  adopt(m.log_scales, model->log_scales, M * 6);
  adopt(m.features, model->features, M * size_t(a.feature_dim));
  if (d.paper()) adopt(m.image_raw, model->image_raw, M * size_t(kImageRawDim));
  for (int i = 0; i < kMlpCount; ++i) adopt(m.mlps[i].params, model->mlps[i].params, model->mlps[i].params.size());
  m.anchor_count = M;
  m.voxel_size = model->voxel_size;
  m.scene_extent = model->scene_extent;
  for (ParamGroup& g : d.groups) {
    r.floats(g.m.data(), g.live(M), "Adam moments");
    r.floats(g.v.data(), g.live(M), "Adam moments");
  }
  r.floats(d.opacity_accum.data(), M, "statistics");
  for (size_t i = 0; i < M; ++i) d.anchor_seen[i] = r.i32("statistics");
  r.floats(d.grad_accum.data(), M * K, "statistics");
  for (size_t i = 0; i < M * K; ++i) d.grad_denom[i] = r.i32("statistics");
  for (size_t v = 0; v < d.views.size(); ++v) {
    r.floats(d.view_cameras[v].pose.R, 9, "training poses");
    r.floats(d.view_cameras[v].pose.t, 3, "training poses");
    d.pose_steps[v] = r.i32("training poses");
    for (int i = 0; i < 6; ++i) {
      d.pose_m[6 * v + size_t(i)] = r.f64("pose moments");
      d.pose_v[6 * v + size_t(i)] = r.f64("pose moments");
    }
  }
  std::vector<uint8_t> held(d.views.size(), 0);  // version 2 predates held-back views: none
  if (version >= 3)
    for (uint8_t& h : held) {
      h = r.u8("held-back views");
      if (r.status().ok() && h > 1) return parse_error(path + ": bad held-back flag");
    }
  if (!r.status().ok()) return r.status();
  if (std::find(held.begin(), held.end(), uint8_t(0)) == held.end()) return parse_error(path + ": every view is held back");
  d.held = held;
  d.iteration = iteration;
  d.rng.state = rng_state;
  d.view_pos = size_t(view_pos);
  d.view_order = order;
  return Status::Ok();
}

// ---- ModelRenderer ----------------------------------------------------------------------------

struct ModelRenderer::Impl {
  Renderer renderer;
  detail::FloatBackend backend;
  StepWorkspace<float> ws;
  size_t capacity = 0;
  ModelRenderOptions options;
  double decode_ms = 0, forward_ms = 0;
  QuantDecoder int8;
  const CompactModel* int8_source = nullptr;  // what int8 was prepared from
  detail::CloudDecoder cloud;  // plain Gaussians (init with a GaussianCloud)

  void finish(Status st, const Camera& camera, float* alpha) const {
    if (!st.ok() || !alpha) return;
    const size_t n = size_t(camera.intr.width) * size_t(camera.intr.height);
    const float* T = renderer.final_transmittance();
    for (size_t i = 0; i < n; ++i) alpha[i] = 1.0f - T[i];
  }

  // Prepares (once per compact model) and attaches the int8 decoder, or detaches it.
  Status plan_int8() {
    if (!options.int8_mlp) {
      backend.set_int8_decoder(nullptr, nullptr, 0);
      return Status::Ok();
    }
    if (int8_source != options.int8_mlp) {
      Expected<QuantDecoder> q = prepare_quant_decoder(*options.int8_mlp);
      if (!q.ok()) return q.status();
      int8 = std::move(q).value();
      int8_source = options.int8_mlp;
    }
    if (capacity > 0) backend.set_int8_decoder(&int8, nullptr, capacity);
    return Status::Ok();
  }
};

ModelRenderer::ModelRenderer() : impl_(new Impl) {}
ModelRenderer::~ModelRenderer() = default;

Status ModelRenderer::set_options(const ModelRenderOptions& options) {
  Impl& d = *impl_;
  d.options = options;
  d.backend.fixed_point_raster = options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) d.backend.background[c] = options.background[c];
  return d.plan_int8();
}

Status ModelRenderer::init(const HybridModel& model, int max_width, int max_height, platform::ThreadPool* pool,
                           const simd::KernelTable* kernels) {
  GS_RETURN_IF_ERROR(model.config.validate());
  const simd::KernelTable* kt = kernels ? kernels : &simd::best_kernel_table();
  const size_t cap = std::max<size_t>(model.anchor_count, 1);
  Expected<RenderCapacity> rc = detail::plan_model_pipeline(model, cap, max_width, max_height, max_width, max_height, pool,
                                                            kt, &impl_->renderer, &impl_->backend, &impl_->ws,
                                                            /*training=*/false, kReplannedIsectsPerGaussian);
  if (!rc.ok()) return rc.status();
  impl_->capacity = cap;
  impl_->backend.fixed_point_raster = impl_->options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) impl_->backend.background[c] = impl_->options.background[c];
  return impl_->plan_int8();
}

Status ModelRenderer::render(const HybridModel& model, const Camera& camera, float* rgb, size_t* gaussians, float* alpha) {
  Impl& d = *impl_;
  if (model.anchor_count > d.capacity) return capacity_exceeded("model renderer: the model has more anchors than planned");
  GS_RETURN_IF_ERROR(validate_camera(camera));
  ModelParamsT<float> p = detail::model_params(model);
  if (d.options.int8_mlp) {
    const float* keys[kMlpCount];
    for (int id = 0; id < kMlpCount; ++id) keys[id] = model.mlps[id].params.empty() ? nullptr : model.mlps[id].params.data();
    d.backend.set_int8_keys(keys);
  }
  size_t V = 0;
  const uint64_t t0 = platform::now_ns();
  const size_t N = decode_view(d.backend, p, camera, d.ws, &V);
  const uint64_t t1 = platform::now_ns();
  if (gaussians) *gaussians = N;
  const Status st = d.backend.render_fwd(camera, d.ws.ng, rgb);
  d.decode_ms = double(t1 - t0) * 1e-6;
  d.forward_ms = double(platform::now_ns() - t1) * 1e-6;
  d.finish(st, camera, alpha);
  return st;
}

Status ModelRenderer::init(const GaussianCloud& cloud, int max_width, int max_height, platform::ThreadPool* pool,
                           const simd::KernelTable* kernels) {
  Impl& d = *impl_;
  if (cloud.size() == 0) return invalid_argument("model renderer: the cloud has no Gaussians");
  const simd::KernelTable* kt = kernels ? kernels : &simd::best_kernel_table();
  GS_RETURN_IF_ERROR(d.renderer.init(detail::cloud_render_capacity(cloud.size(), max_width, max_height), pool, kt));
  d.backend.init(&d.renderer, kt, pool, 1, max_width);
  d.backend.fixed_point_raster = d.options.fixed_point_raster;
  for (int c = 0; c < 3; ++c) d.backend.background[c] = d.options.background[c];
  d.cloud.reserve(cloud.size(), cloud.sh_degree);
  d.capacity = 0;  // no anchor model planned
  return Status::Ok();
}

Status ModelRenderer::render(const GaussianCloud& cloud, const Camera& camera, float* rgb, size_t* gaussians, float* alpha) {
  Impl& d = *impl_;
  if (cloud.size() > d.cloud.capacity()) return capacity_exceeded("model renderer: the cloud has more Gaussians than planned");
  GS_RETURN_IF_ERROR(validate_camera(camera));
  const uint64_t t0 = platform::now_ns();
  const size_t n = d.cloud.decode(cloud, camera);
  const uint64_t t1 = platform::now_ns();
  if (gaussians) *gaussians = n;
  const Status st = d.backend.render_params(camera, d.cloud.params(), rgb);
  d.decode_ms = double(t1 - t0) * 1e-6;
  d.forward_ms = double(platform::now_ns() - t1) * 1e-6;
  d.finish(st, camera, alpha);
  return st;
}

double ModelRenderer::last_decode_ms() const { return impl_->decode_ms; }
double ModelRenderer::last_forward_ms() const { return impl_->forward_ms; }

}  // namespace gs::model
