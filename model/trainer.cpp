// SPDX-License-Identifier: MIT
// The training loop (see gs/model/trainer.h): view sampling, learning-rate schedules, dense Adam
// per parameter group, joint pose steps and registration passes, image-feature refresh, and
// Trainer::step; the state is Trainer::Impl (trainer_state.h), anchor growing and pruning are in
// trainer_anchors.cpp, the checkpoint file in checkpoint.cpp.
#include "gs/model/trainer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "gs/io/composite.h"
#include "gs/metrics/image_metrics.h"
#include "gs/optim/adam.h"
#include "gs/optim/schedule.h"
#include "gs/platform/clock.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "image_descriptor.h"
#include "register_sharing.h"
#include "trainer_state.h"

namespace gs::model {

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

namespace {

// f(group, begin, end) over slices of every group's live gradient: part i of the pool's parts
// takes the i-th slice of each group, so one parallel loop covers all groups.
template <class F>
void for_gradient_slices(platform::ThreadPool* pool, const std::vector<detail::ParamGroup>& groups, size_t M, F&& f) {
  size_t total = 0;
  for (const detail::ParamGroup& g : groups) total += g.live(M);
  const size_t parts = detail::part_count(pool, total, 1 << 15);
  detail::for_parts(pool, parts, parts, [&](size_t i, size_t, size_t) {
    for (size_t gi = 0; gi < groups.size(); ++gi) {
      const size_t n = groups[gi].live(M);
      f(gi, detail::part_begin(n, parts, i), detail::part_begin(n, parts, i + 1));
    }
  });
}

}  // namespace

bool Trainer::Impl::gradients_finite(size_t M, const double v_pose[6]) const {
  std::atomic<uint32_t> bad{0};
  for_gradient_slices(pool, groups, M, [&](size_t gi, size_t b, size_t e) {
    const float* p = groups[gi].grad.data();
    uint32_t any = 0;
    for (size_t i = b; i < e; ++i) {
      uint32_t bits;
      std::memcpy(&bits, p + i, 4);
      any |= uint32_t((bits & 0x7f800000u) == 0x7f800000u);
    }
    if (any) bad.store(1, std::memory_order_relaxed);
  });
  if (bad.load(std::memory_order_relaxed)) return false;
  for (int i = 0; i < 6; ++i)
    if (!std::isfinite(v_pose[i])) return false;
  return true;
}

size_t Trainer::Impl::most_visible_anchors() const {
  const AnchorParams<float> a = params().anchors;
  size_t most = 0;
  for (const Camera& cam : view_cameras) most = std::max(most, select_visible_anchors(cam, a, static_cast<uint32_t*>(nullptr)));
  return most;
}

Status Trainer::Impl::plan(const TrainOptions& options) {
  const size_t c = cap(), K = size_t(k());
  // The decoder workspace follows what the views decode: the most anchors a training view sees
  // now (a dry run of the visibility test) and a quarter more for the anchors grown into these
  // rows; the kept Gaussians half again the most a step has decoded (before the first step: k per
  // visible anchor). A step that needs more grows them (StepWorkspace::ensure_visible).
  const size_t visible = std::min(c, std::max<size_t>(1, most_visible_anchors() * 5 / 4));
  const size_t gaussians = most_gaussians > 0 ? std::min(visible * K, most_gaussians * 3 / 2) : visible * K;
  Expected<RenderCapacity> rc = detail::plan_model_pipeline(model, c, plan_w, plan_h, plan_w, plan_h, pool, kernels,
                                                            &renderer, &backend, &ws, /*training=*/true,
                                                            detail::kReplannedIsectsPerGaussian, visible, gaussians);
  if (!rc.ok()) return rc.status();
  opacity_accum.resize(c, 0.0f);
  anchor_seen.resize(c, 0);
  grad_accum.resize(c * K, 0.0f);
  grad_denom.resize(c * K, 0);
  existing_cells.resize(c, detail::CellKey{0, 0, 0});
  cand.resize(c * K, {detail::CellKey{0, 0, 0}, 0u});
  cell_scores.resize(c * K, {0.0f, 0u});
  pruned.resize(c, 0);
  uint64_t bytes = Renderer::plan_bytes(*rc);
  registrar.reset();
  GS_RETURN_IF_ERROR(plan_registrar(options));
  if (registrar) bytes += registrar->planned_bytes();
  bytes += uint64_t(model.positions.size() + model.offsets.size() + model.log_scales.size() + model.features.size() +
                    model.image_raw.size()) * 4;
  for (const detail::ParamGroup& g : groups) bytes += uint64_t(g.grad.size() * 3) * 4;
  bytes += uint64_t(ws.X.size() * 3 + ws.means.size() * 4 + ws.quats.size() * 2 + ws.rgb.size() * 2) * 4;
  bytes += uint64_t(c * K) * (4 + 4 + sizeof(cand[0]) + sizeof(cell_scores[0]));
  planned_bytes = bytes;
  return Status::Ok();
}

Status Trainer::Impl::plan_registrar(const TrainOptions& options) {
  // Registration passes plan it with everything else. Held-back views do not: their passes create
  // it for the rows of that moment and free it once no view is held or repaired (register_held).
  // Either way it borrows the trainer's renderer and workspaces, so it adds only its images.
  if (options.pose_register_every <= 0) return Status::Ok();
  return create_registrar();
}

Status Trainer::Impl::create_registrar() {
  pose::RegisterOptions ro;
  ro.max_iterations_per_level = 10;
  for (int ch = 0; ch < 3; ++ch) ro.background[ch] = opt.background.rgb[ch];
  // It borrows the trainer's renderer, backend and workspace: registration runs between steps.
  Expected<std::unique_ptr<pose::Registrar>> reg =
      pose::RegistrarSharing::create(model, plan_w, plan_h, ro, pool, kernels, cap(), &renderer, &backend, &ws);
  if (!reg.ok()) return reg.status();
  registrar = std::move(reg).value();
  return Status::Ok();
}

Status Trainer::Impl::ensure_capacity(size_t rows) {
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
    detail::ParamGroup& g = groups[gi];
    if (!g.row_floats) continue;
    g.param = anchor_params[gi];  // the anchor groups come first, in this order (build_groups)
    g.grad.resize(g.row_floats * c, 0.0f);
    g.m.resize(g.row_floats * c, 0.0f);
    g.v.resize(g.row_floats * c, 0.0f);
  }
  ++growths;
  return plan(opt);
}

void Trainer::Impl::refresh_image_features() {
  bank.set_occluders(model.positions.data(), model.anchor_count, model.voxel_size, pool);
  bank.compute(model.positions.data(), model.anchor_count, model.image_raw.data(), pool);
}

void Trainer::Impl::build_groups() {
  const ModelConfig& c = model.config;
  const double E = model.scene_extent;
  groups.clear();
  auto anchor_group = [&](const char* name, std::vector<float>& v, size_t row, double lr0, double lr1) {
    detail::ParamGroup g;
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
    detail::ParamGroup g;
    g.name = names[i];
    g.param = model.mlps[i].params.data();
    g.fixed_size = model.mlps[i].params.size();
    g.lr0 = lrs[i][0];
    g.lr1 = lrs[i][1];
    groups.push_back(std::move(g));
  }
  for (detail::ParamGroup& g : groups) {
    const size_t n = g.row_floats ? g.row_floats * cap() : g.fixed_size;
    g.grad.assign(n, 0.0f);
    g.m.assign(n, 0.0f);
    g.v.assign(n, 0.0f);
  }
}

ModelGradsT<float> Trainer::Impl::grads() {
  ModelGradsT<float> g;
  g.offsets = groups[0].grad.data();
  g.log_scales = groups[1].grad.data();
  g.features = groups[2].grad.data();
  size_t gi = 3;
  for (int i = 0; i < kMlpCount; ++i) g.mlp[i] = model.mlps[i].params.empty() ? nullptr : groups[gi++].grad.data();
  return g;
}

int Trainer::Impl::next_view() {
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

void Trainer::Impl::adopt_pose(size_t v, const Pose& pose) {
  view_cameras[v].pose = pose;
  std::fill(pose_m.begin() + std::ptrdiff_t(6 * v), pose_m.begin() + std::ptrdiff_t(6 * v + 6), 0.0);
  std::fill(pose_v.begin() + std::ptrdiff_t(6 * v), pose_v.begin() + std::ptrdiff_t(6 * v + 6), 0.0);
  pose_steps[v] = 0;
}

void Trainer::Impl::describe_photos() {
  const int dw = pose::detail::kDescriptorWidth, dh = pose::detail::kDescriptorHeight;
  const size_t dim = size_t(dw) * size_t(dh);
  descriptors.assign(views.size() * dim, 0.0f);
  std::vector<float> small(dim * 3);
  for (size_t i = 0; i < views.size(); ++i) {
    const io::Image8 s = io::resize_area(photo(i), dw, dh);
    for (size_t j = 0; j < small.size(); ++j) small[j] = float(s.pixels[j]);
    pose::detail::grey_descriptor(small.data(), dim, &descriptors[i * dim]);
  }
}

int Trainer::Impl::held_starts(size_t v, Pose* starts) const {
  int n = 0;
  starts[n++] = view_cameras[v].pose;
  auto add = [&](size_t u) {
    for (int i = 1; i < n; ++i)
      if (std::memcmp(&starts[i], &view_cameras[u].pose, sizeof(Pose)) == 0) return;
    if (n < kHeldStarts) starts[n++] = view_cameras[u].pose;
  };
  // Capture order: the nearest trained view before and after (views are sorted by name, which for
  // frames of a video or a photo series is the order they were taken in).
  for (size_t u = v; u-- > 0;)
    if (!held[u]) { add(u); break; }
  for (size_t u = v + 1; u < views.size(); ++u)
    if (!held[u]) { add(u); break; }
  if (descriptors.empty()) return n;
  // Image similarity: the two trained views whose photos correlate best with this one.
  const size_t dim = size_t(pose::detail::kDescriptorWidth) * pose::detail::kDescriptorHeight;
  const float* dv = &descriptors[v * dim];
  size_t best[2] = {v, v};
  float score[2] = {-2.0f, -2.0f};
  for (size_t u = 0; u < views.size(); ++u) {
    if (held[u] || u == v) continue;
    const float* du = &descriptors[u * dim];
    float dot = 0;
    for (size_t i = 0; i < dim; ++i) dot += dv[i] * du[i];
    if (dot > score[0]) best[1] = best[0], score[1] = score[0], best[0] = u, score[0] = dot;
    else if (dot > score[1]) best[1] = u, score[1] = dot;
  }
  for (size_t b : best)
    if (b != v) add(b);
  return n;
}

Status Trainer::Impl::register_held(int it, int* released) {
  *released = 0;
  if (!registrar) GS_RETURN_IF_ERROR(create_registrar());
  // A pose a view is moved to comes from full resolution, whatever this iteration trains at (a
  // registration pass stops at half of it): the pose a held view rejoins at is the one it keeps,
  // since joint optimisation moves a view only a few hundredths of a degree once the rates have
  // decayed and fixed poses never move.
  pose::RegisterOptions& ro = registrar->mutable_options();
  const int finest_default = ro.finest_downscale, polish_default = ro.polish_downscale;
  if (descriptors.empty()) describe_photos();  // a resumed run that holds views (once)
  for (size_t v = 0; v < views.size(); ++v) {
    // Registers view v from start with its last level at 1/finest and its polish at 1/polish; the
    // registrar's options are as before afterwards, on an error too.
    auto register_at = [&](int finest, int polish, const Pose& start, pose::RegisterResult* r) {
      ro.finest_downscale = finest;
      ro.polish_downscale = polish;
      const Status st = registrar->register_view(photo(v).pixels.data(), view_cameras[v].intr, start, r);
      ro.finest_downscale = finest_default;
      ro.polish_downscale = polish_default;
      return st;
    };
    if (repaired[v]) {
      pose::RegisterResult r;
      GS_RETURN_IF_ERROR(register_at(1, polish_default, view_cameras[v].pose, &r));
      if (r.converged() && r.final_rmse < r.initial_rmse) adopt_pose(v, r.pose);
      continue;
    }
    if (!held[v]) continue;
    Pose starts[kHeldStarts];
    const int n = held_starts(v, starts);
    auto near_start = [&](const Pose& p) {
      return pose::rotation_error_deg(p, starts[0]) <= kConfirmDeg &&
             pose::centre_distance(p, starts[0]) <= kConfirmExtent * model.scene_extent;
    };
    // Every start first searches where the view may be at kHeldSearchDownscale (a tenth of the
    // cost of full resolution); when none converges there, the view stays held until the next pass
    // (on a young model that is most passes: at full resolution these failures took 2/3 of a
    // snowmiku_plush run, 6 held views, 1,000 iterations). Else its own pose is registered at
    // kHeldDecideDownscale (confirmed when it stays there), and the search that converged with the
    // lowest residual is registered again there from where it ended. The decision needs only to
    // tell poses a degree apart; only a pose the view moves to is registered at full resolution
    // (deciding at full resolution made these passes 14 % of a default 3,000-iteration
    // snowmiku_plush run, which confirms all 6 of its held views).
    // The search's verdict only picks where the decision starts, so its polish renders at half
    // resolution (a render at 1/2 leaves 0.1-0.5 degree biases at 1/4; the decision removes them).
    pose::RegisterResult lead;
    int lead_start = -1;
    for (int i = 0; i < n; ++i) {
      pose::RegisterResult r;
      GS_RETURN_IF_ERROR(register_at(kHeldSearchDownscale, kHeldSearchDownscale / 2, starts[i], &r));
      if (r.converged() && (lead_start < 0 || r.final_rmse < lead.final_rmse)) lead = r, lead_start = i;
    }
    if (lead_start < 0) continue;
    pose::RegisterResult own, best;
    bool found = false;
    auto consider = [&](const pose::RegisterResult& r) {
      if (r.converged() && (!found || r.final_rmse < best.final_rmse)) best = r, found = true;
    };
    GS_RETURN_IF_ERROR(register_at(kHeldDecideDownscale, polish_default, starts[0], &own));
    consider(own);
    if (!(found && near_start(own.pose)) && lead_start > 0) {
      pose::RegisterResult r;
      GS_RETURN_IF_ERROR(register_at(kHeldDecideDownscale, polish_default, lead.pose, &r));
      consider(r);
    }
    // A new pose only on clear evidence: it converged away from the given pose AND fits the photo
    // much better than the given pose does (a turned view: 0.20-0.27 -> 0.08-0.09 RMSE on the
    // built-in scene), unless the points contradict it there. A correct view the points doubted
    // (snowmiku_plush's close-ups behind the wardrobe door) registers against a model that has not
    // seen what it shows: there, moves of 3-12 degrees improved the RMSE by 1-15 % and adopting them
    // cost 0.5 dB. Or when the points clearly prefer the new pose and it fits better at all: a view
    // SfM placed 8 degrees off registered to its true pose at a ratio of only 0.77 in a
    // 200-iteration run.
    // The given pose is confirmed when the registration from it converged and stayed there, or
    // when the alternative the model found is one the points contradict (snowmiku_plush's door
    // views). An alternative the points accept but that does not fit clearly better leaves the view
    // held until a later pass decides: confirmed so, a view COLMAP placed about 5 degrees off
    // trained at that pose in one e2e run (0.191 degrees mean at the end, the limit is 0.2).
    using Evidence = TrainOptions::PoseEvidence;
    bool repair = false, alternative_refuted = false;
    if (found && !near_start(best.pose)) {
      Camera moved = view_cameras[v];
      moved.pose = best.pose;
      const Evidence evidence = opt.judge_new_pose ? opt.judge_new_pose(v, view_cameras[v], moved) : Evidence::kAccepts;
      repair = (evidence == Evidence::kAccepts && best.final_rmse < kRepairRmseRatio * own.initial_rmse) ||
               (evidence == Evidence::kPrefers && best.final_rmse < own.initial_rmse);
      alternative_refuted = evidence == Evidence::kContradicts;
    }
    const bool confirm = own.converged() && (near_start(own.pose) || near_start(best.pose) || alternative_refuted);
    if (!repair && !confirm) continue;
    held[v] = 0;
    ++*released;
    if (!repair) continue;
    pose::RegisterResult fine;
    GS_RETURN_IF_ERROR(register_at(1, polish_default, best.pose, &fine));
    adopt_pose(v, fine.converged() ? fine.pose : best.pose);
    repaired[v] = 1;
  }
  if (opt.pose_register_every <= 0 && held_count() == 0 && repaired_count() == 0) registrar.reset();
  return Status::Ok();
}

// The step's train PSNR (progress output), over the pixels that have a source when `valid` is
// given (io::DatasetView::valid): squared errors summed in double over a fixed number of pixel
// ranges on the pool, joined in order, so the value does not depend on the thread count (run
// serially it was 0.5 % of a 1-thread snowmiku_plush iteration's perf samples).
namespace {
double step_psnr(const float* rgb, const float* target, const uint8_t* valid, size_t pixels, platform::ThreadPool* pool) {
  constexpr size_t kParts = 16;
  const size_t parts = std::max<size_t>(1, std::min(kParts, pixels / 4096));
  double sse[kParts] = {}, count[kParts] = {};
  detail::for_parts(pool, pixels, parts, [&](size_t part, size_t b, size_t e) {
    double s = 0, n = 0;
    for (size_t p = b; p < e; ++p) {
      if (valid && !valid[p]) continue;
      for (size_t c = 0; c < 3; ++c) {
        const double d = double(rgb[3 * p + c]) - double(target[3 * p + c]);
        s += d * d;
      }
      n += 3;
    }
    sse[part] = s;
    count[part] = n;
  });
  double total = 0, n = 0;
  for (size_t i = 0; i < parts; ++i) {
    total += sse[i];
    n += count[i];
  }
  return metrics::psnr_from_sse(total, n);
}
}  // namespace

void Trainer::Impl::load_target(const io::DatasetView& v, int s, const float bg[3]) {
  io::composite_target(v.image, v.mask, s, bg, target.data(), pool);
  ws.valid_pixels = nullptr;
  if (v.valid.empty()) return;
  io::valid_target(v.valid, s, valid_target.data());
  ws.valid_pixels = valid_target.data();
}

int Trainer::Impl::coarse_level(int it, double end) const {
  const int L = opt.coarse_levels;
  return std::max(0, std::min(L - 1, int(double(it - 1) * L / std::max(end, 1.0))));
}

int Trainer::Impl::downscale_at(int it) const {
  if (opt.coarse_levels <= 0) return 1;
  if (double(it) > coarse_end) return 1;
  return 1 << (opt.coarse_levels - coarse_level(it, coarse_end));
}

Status Trainer::Impl::register_all(int it, int* moved) {
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

void Trainer::Impl::pose_adam(size_t vi, const double g[6], int it) {
  const double warm = optim::warmup(opt.pose_warmup, it);
  const double lr_rot = warm * optim::expon_lr_at(opt.lr_pose_rotation_init, opt.lr_pose_rotation_final, lr_progress);
  const double lr_tr = warm * model.scene_extent *
                       optim::expon_lr_at(opt.lr_pose_translation_init, opt.lr_pose_translation_final, lr_progress);
  const int step = ++pose_steps[vi];
  double xi[6];
  optim::twist_adam_step(g, lr_tr, lr_rot, step, opt.adam_eps, &pose_m[6 * vi], &pose_v[6 * vi], xi);
  pose::apply_left_twist(xi, &view_cameras[vi].pose);
}

void Trainer::Impl::adam_all(int it) {
  const size_t M = model.anchor_count;
  // Every group in one pass over the pool (the same per-element updates as one adam_step per group).
  constexpr size_t kMaxGroups = 16;
  optim::AdamArray arrays[kMaxGroups];
  size_t count = 0;
  for (detail::ParamGroup& g : groups) {
    const simd::AdamParams ap = optim::adam_params(optim::expon_lr_at(g.lr0, g.lr1, lr_progress), it, opt.adam_eps);
    if (count == kMaxGroups) {  // (not with today's 7 groups)
      optim::adam_step(*kernels, pool, ap, g.live(M), g.param, g.grad.data(), g.m.data(), g.v.data());
      continue;
    }
    arrays[count++] = optim::AdamArray{ap, g.live(M), g.param, g.grad.data(), g.m.data(), g.v.data()};
  }
  optim::adam_step_arrays(*kernels, pool, arrays, count);
}


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
    if (!v.valid.empty() && (v.valid.channels != 1 || v.valid.width != v.image.width || v.valid.height != v.image.height))
      return invalid_argument("trainer: view '" + v.name + "' has a valid-pixel map that is not one channel of its image's size");
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
  d.valid_target.assign(size_t(max_w) * size_t(max_h), 0);
  d.build_groups();
  d.rng.state = options.seed * 0x9E3779B97F4A7C15ull + 7;
  d.view_order.assign(train_views.size(), 0);
  d.view_pos = d.view_order.size();  // first call shuffles
  d.held = options.held_back_views.empty() ? std::vector<uint8_t>(train_views.size(), 0) : options.held_back_views;
  d.coarse_end = options.coarse_fraction * double(options.iterations);
  for (uint8_t& h : d.held) h = h ? 1 : 0;
  d.repaired.assign(train_views.size(), 0);
  if (d.held_count() > 0) d.describe_photos();
  GS_RETURN_IF_ERROR(d.plan(options));
  if (d.paper()) d.refresh_image_features();
  return t;
}

Status Trainer::step(IterationStats* stats) {
  Impl& d = *impl_;
  if (d.step_memory_released) {
    GS_RETURN_IF_ERROR(d.plan(d.opt));
    d.step_memory_released = false;
  }
  const double t0 = platform::now_seconds();
  // The stage timers are lent to the renderer and the workspace for this step only (render() and
  // the evaluations between steps stay out of the profile).
  StageTimes* const times = d.stage_times;
  const uint64_t t0_ns = times ? platform::now_ns() : 0;
  struct LendTimers {
    Impl& d;
    LendTimers(Impl& impl, StageTimes* t) : d(impl) {
      d.renderer.set_stage_times(t);
      d.ws.stage_times = t;
    }
    ~LendTimers() {
      d.renderer.set_stage_times(nullptr);
      d.ws.stage_times = nullptr;
    }
  } lend(d, times);
  const int it = d.iteration + 1;
  // it / schedule_iterations (at most 1), as expon_lr computes it; after a retarget never below the
  // last step's.
  d.lr_progress = std::max(d.lr_progress, std::min(1.0, double(it) / double(std::max(d.opt.schedule_iterations, 1))));
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
  for_gradient_slices(d.pool, d.groups, M, [&](size_t gi, size_t b, size_t e) {
    float* grad = d.groups[gi].grad.data();
    std::fill(grad + b, grad + e, 0.0f);
  });
  ModelParamsT<float> p = d.params();
  ModelGradsT<float> grads = d.grads();
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
  if (d.opt.optimize_poses) grads.pose = v_pose;
  StepResult res;
  GS_RETURN_IF_ERROR(step_forward_backward(d.backend, p, cam, d.target.data(), d.opt.step, d.ws, &grads, &res));
  d.last_visible = res.visible_anchors;
  d.last_gaussians = res.gaussians;
  d.most_gaussians = std::max(d.most_gaussians, res.gaussians);
  StageClock clock(times);
  if (!d.opt.test_nonfinite_iterations.empty() &&
      std::find(d.opt.test_nonfinite_iterations.begin(), d.opt.test_nonfinite_iterations.end(), it) != d.opt.test_nonfinite_iterations.end())
    d.groups.front().grad[0] = std::numeric_limits<float>::quiet_NaN();
  // The numerical guard: one bad step must not write NaN into every parameter through Adam.
  const bool finite = std::isfinite(res.loss) && d.gradients_finite(M, v_pose);
  if (finite) {
    d.nonfinite_in_a_row = 0;
    if (it > d.opt.stat_start && it < d.opt.update_until) {
      clock.restart();
      d.accumulate_stats(cam);
      clock.lap(kStageStats);
      if (times) ++times->stats_steps;
    }
    clock.restart();
    d.adam_all(it);
    if (d.opt.optimize_poses) d.pose_adam(size_t(vi), v_pose, it);
    clock.lap(kStageAdam);
    if (times)
      for (const detail::ParamGroup& g : d.groups) times->adam_floats += g.live(M);
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
    clock.restart();
    d.adjust_anchors();
    clock.lap(kStageAdjust);
    if (!d.growth_status.ok()) return d.growth_status;
    adjusted = true;
    if (times) ++times->adjust_steps;
  }
  bool refresh = d.paper() && d.opt.image_feature_refresh > 0 && it % d.opt.image_feature_refresh == 0;
  // Registration renders and decodes with the step's renderer and workspace (RegistrarSharing):
  // not a stage of the step, so their timers are taken back here.
  d.renderer.set_stage_times(nullptr);
  d.ws.stage_times = nullptr;
  int moved = -1;
  if (d.registrar && d.opt.pose_register_every > 0 && it % d.opt.pose_register_every == 0 && it <= d.opt.pose_register_until) {
    GS_RETURN_IF_ERROR(d.register_all(it, &moved));
    refresh = refresh || (d.paper() && moved > 0);
  }
  int released = -1;
  if (d.opt.held_back_register_every > 0 && it % d.opt.held_back_register_every == 0 &&
      it >= d.opt.held_back_register_from && it <= d.opt.held_back_register_until &&
      (d.held_count() > 0 || d.repaired_count() > 0)) {
    GS_RETURN_IF_ERROR(d.register_held(it, &released));
    refresh = refresh || (d.paper() && released > 0);
  }
  if (refresh) {
    clock.restart();
    d.refresh_image_features();
    clock.lap(kStageImageFeatures);
    if (times) ++times->refresh_steps;
  }
  d.iteration = it;
  if (stats) {
    stats->iteration = it;
    stats->view = vi;
    stats->step = res;
    stats->downscale = scale;
    stats->poses_registered = moved;
    stats->views_released = released;
    stats->views_held_back = d.held_count();
    stats->psnr = step_psnr(d.ws.rgb.data(), d.target.data(), d.ws.valid_pixels,
                            size_t(cam.intr.width) * size_t(cam.intr.height), d.pool);
    stats->anchors = d.model.anchor_count;
    stats->isects = d.renderer.stats().isects;
    stats->adjusted = adjusted;
    stats->seconds = platform::now_seconds() - t0;
    stats->skipped_nonfinite = !finite;
    stats->nonfinite_steps = d.nonfinite_steps;
  }
  if (times) {
    times->anchors += M;
    times->visible_anchors += res.visible_anchors;
    times->gaussians += res.gaussians;
    times->finish_iteration(platform::now_ns() - t0_ns);
  }
  return Status::Ok();
}

namespace {

// A window [*from, *until] of the schedule moved to [from, until] at completed iteration it: one
// that has closed (it >= *until) stays closed, one that has started (it > *from) keeps its start.
void move_window(int it, int from, int until, int* cur_from, int* cur_until) {
  if (it >= *cur_until) return;
  if (it <= *cur_from) *cur_from = from;
  *cur_until = until;
}

}  // namespace

Status Trainer::retarget(const TrainOptions& s) {
  Impl& d = *impl_;
  if (s.iterations < 0 || s.schedule_iterations < 1 || s.update_interval < 1 || s.pose_warmup < 0 || s.pose_register_every < 0 ||
      s.held_back_register_every < 0)
    return invalid_argument("trainer: retarget: iteration counts and intervals must be positive");
  TrainOptions& o = d.opt;
  const int it = d.iteration;
  o.iterations = s.iterations;
  o.schedule_iterations = s.schedule_iterations;
  // Statistics and growth share update_until: both windows close together.
  int stat_until = o.update_until;
  move_window(it, s.stat_start, s.update_until, &o.stat_start, &stat_until);
  move_window(it, s.update_from, s.update_until, &o.update_from, &o.update_until);
  if (it < o.update_until) o.update_interval = s.update_interval;
  // The warm-up factor min(1, it / pose_warmup) must not fall: once begun, the ramp only steepens.
  o.pose_warmup = it > 0 ? std::min(o.pose_warmup, s.pose_warmup) : s.pose_warmup;
  if (o.pose_register_every > 0 && s.pose_register_every > 0) {
    int from = 0;
    move_window(it, 0, s.pose_register_until, &from, &o.pose_register_until);
    if (it < o.pose_register_until) o.pose_register_every = s.pose_register_every;
  }
  if (o.held_back_register_every > 0 && s.held_back_register_every > 0) {
    move_window(it, s.held_back_register_from, s.held_back_register_until, &o.held_back_register_from, &o.held_back_register_until);
    if (it < o.held_back_register_until) o.held_back_register_every = s.held_back_register_every;
  }
  // Coarse to fine: a finished coarse phase stays finished, and the level reached at `it` is kept
  // (a later end would make the current level coarser again).
  if (o.coarse_levels > 0 && double(it) <= d.coarse_end) {
    double end = o.coarse_fraction * double(s.iterations);
    const int L = o.coarse_levels;
    const int level = it > 0 ? d.coarse_level(it, d.coarse_end) : 0;
    if (level > 0) {
      end = std::min(end, double(it - 1) * L / level);
      while (end > 0 && d.coarse_level(it, end) < level) end = std::nextafter(end, 0.0);  // rounding
    }
    d.coarse_end = end;
  }
  d.retargeted = true;
  return Status::Ok();
}

double Trainer::schedule_progress() const { return impl_->lr_progress; }
void Trainer::set_stage_times(StageTimes* times) { impl_->stage_times = times; }

int Trainer::iteration() const { return impl_->iteration; }
const std::vector<Camera>& Trainer::cameras() const { return impl_->view_cameras; }
const std::vector<uint8_t>& Trainer::held_back() const { return impl_->held; }
const std::vector<uint8_t>& Trainer::repaired() const { return impl_->repaired; }
int Trainer::downscale_at(int iteration) const { return impl_->downscale_at(iteration); }
const HybridModel& Trainer::model() const { return impl_->model; }
const TrainOptions& Trainer::options() const { return impl_->opt; }
uint64_t Trainer::planned_bytes() const { return impl_->planned_bytes; }
int Trainer::workspace_replans() const { return impl_->ws.replans; }

void Trainer::release_step_memory() {
  Impl& d = *impl_;
  d.ws.release_gradients();
  std::vector<detail::CellKey>().swap(d.existing_cells);
  std::vector<std::pair<detail::CellKey, uint32_t>>().swap(d.cand);
  std::vector<std::pair<float, uint32_t>>().swap(d.cell_scores);
  d.step_memory_released = true;
}

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

}  // namespace gs::model
