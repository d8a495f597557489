// SPDX-License-Identifier: MIT
// The trainer's anchor growing and pruning (ALGORITHM.md Part B section 7, Scaffold-GS): the
// densification statistics gathered per step, new anchors at the voxels of neural Gaussians with
// large view-space gradients (level by level), pruning of anchors that stay transparent, under the
// anchor budget (the rows grow through Trainer::Impl::ensure_capacity).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "trainer_state.h"

namespace gs::model {

namespace {

detail::CellKey cell_of(const float* p, double size) {
  return {int64_t(std::llround(double(p[0]) / size)), int64_t(std::llround(double(p[1]) / size)),
          int64_t(std::llround(double(p[2]) / size))};
}

}  // namespace

void Trainer::Impl::accumulate_stats(const Camera& cam) {
  // Both loops run over the pool: visible rows are distinct, and so are the (row, j) slots of the
  // kept Gaussians, so every statistic gets exactly the serial pass's addition.
  const size_t V = last_visible;
  const int K = k();
  const float* alpha = ws.y[kMlpOpacity].data();
  detail::parallel_ranges(pool, V, 1024, [&](size_t b, size_t e) {
    for (size_t v = b; v < e; ++v) {
      const uint32_t row = ws.rows[v];
      float sum = 0;
      for (int j = 0; j < K; ++j) sum += std::max(alpha[v * size_t(K) + size_t(j)], 0.0f);
      opacity_accum[row] += sum;
      anchor_seen[row] += 1;
    }
  });
  const int32_t* radii = renderer.radii();
  const float hw = 0.5f * float(cam.intr.width), hh = 0.5f * float(cam.intr.height);
  detail::parallel_ranges(pool, ws.ng.count, 4096, [&](size_t b, size_t e) {
    for (size_t n = b; n < e; ++n) {
      if (radii[n] <= 0) continue;
      const uint32_t s = ws.source[n];
      const size_t idx = size_t(ws.rows[s / uint32_t(K)]) * size_t(K) + s % uint32_t(K);
      const float gx = ws.v_means2d[2 * n] * hw, gy = ws.v_means2d[2 * n + 1] * hh;  // NDC-space gradient
      grad_accum[idx] += std::sqrt(gx * gx + gy * gy);
      grad_denom[idx] += 1;
    }
  });
}

void Trainer::Impl::move_row(size_t src, size_t dst) {
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

void Trainer::Impl::clear_row(size_t row) {
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

size_t Trainer::Impl::growth_allowance() const {
  const size_t M = model.anchor_count;
  if (!(opt.growth_gaussians_per_pixel > 0) || M == 0 || last_visible == 0 || last_gaussians == 0) return SIZE_MAX;
  // Gaussians per view now: the anchors each training view sees (the decoder's visibility test)
  // times the kept Gaussians per visible anchor of this step.
  AnchorParams<float> a = params().anchors;
  double visible = 0, pixels = 0;
  size_t n = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    if (held[v]) continue;
    visible += double(select_visible_anchors(view_cameras[v], a, static_cast<uint32_t*>(nullptr)));
    pixels += double(view_cameras[v].intr.width) * double(view_cameras[v].intr.height);
    ++n;
  }
  if (n == 0 || !(visible > 0)) return SIZE_MAX;
  const double per_view = double(last_gaussians) / double(last_visible) * visible / double(n);
  const double target = opt.growth_gaussians_per_pixel * pixels / double(n);
  if (per_view >= target) return 0;
  // New anchors are seen by as many views as the present ones on average.
  return size_t(std::min(double(budget()), (target / per_view - 1.0) * double(M)));
}

size_t Trainer::Impl::grow_level(int level, double min_denom, size_t allowance) {
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
  if (nc == 0 || allowance == 0) return 0;
  // Room for every candidate cell (at most nc new anchors), within the budget.
  if (Status st = ensure_capacity(std::min(budget(), M + std::min(nc, allowance))); !st.ok()) {
    growth_status = st;
    return 0;
  }
  std::sort(cand.begin(), cand.begin() + std::ptrdiff_t(nc));
  for (size_t i = 0; i < M; ++i) existing_cells[i] = cell_of(&model.positions[3 * i], size);
  std::sort(existing_cells.begin(), existing_cells.begin() + std::ptrdiff_t(M));
  // The new cells (not holding an anchor yet). Under an allowance smaller than their number, the
  // cells whose candidates have the largest mean gradient win (ties: cell order).
  auto mean_grad = [&](uint32_t idx) { return grad_accum[idx] / float(grad_denom[idx]); };
  size_t cells = 0;
  for (size_t b = 0; b < nc;) {
    size_t e = b + 1;
    float best = mean_grad(cand[b].second);
    while (e < nc && cand[e].first == cand[b].first) best = std::max(best, mean_grad(cand[e++].second));
    if (!std::binary_search(existing_cells.begin(), existing_cells.begin() + std::ptrdiff_t(M), cand[b].first))
      cell_scores[cells++] = {-best, uint32_t(b)};
    b = e;
  }
  if (cells > allowance) {
    std::nth_element(cell_scores.begin(), cell_scores.begin() + std::ptrdiff_t(allowance - 1),
                     cell_scores.begin() + std::ptrdiff_t(cells));
    cells = allowance;
  }
  // The winners in cell order (their first candidate's index), as the candidates were sorted.
  std::sort(cell_scores.begin(), cell_scores.begin() + std::ptrdiff_t(cells),
            [](const auto& x, const auto& y) { return x.second < y.second; });
  size_t added = 0;
  for (size_t w = 0; w < cells && model.anchor_count < cap(); ++w) {
    const size_t b = cell_scores[w].second;
    size_t e = b + 1;
    while (e < nc && cand[e].first == cand[b].first) ++e;
    const detail::CellKey cell = cand[b].first;
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
  return added;
}

void Trainer::Impl::adjust_anchors() {
  const size_t K = size_t(k());
  const double min_denom = opt.update_interval * opt.success_threshold * 0.5;
  const size_t M0 = model.anchor_count;
  size_t added = 0;
  const size_t allowance = growth_allowance();
  for (int level = 0; level < opt.update_depth; ++level) {
    if (level > 0 && added == 0) break;  // deeper levels run only after a level added something
    added += grow_level(level, min_denom, allowance - std::min(allowance, added));
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

}  // namespace gs::model
