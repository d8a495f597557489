// SPDX-License-Identifier: MIT
// Per-view decoding of neural Gaussians from anchors (ALGORITHM.md Part A item 4, Part B section 3),
// forward and backward, templated on float (training) and double (finite-difference checks).
//
// Shapes: M anchors, V visible anchors (rows[] indexes the anchor arrays), k offsets per anchor,
// F feature dim, G image-feature dim, D = F + G + 4 decoder input. MLP outputs per visible anchor:
// opacity [V, k] (tanh), cov [V, k, 7] = (u_s (3) ; u_q (4)), colour [V, k, 3] (sigmoid).
// A candidate (v, j) becomes a Gaussian iff its opacity > 0 (strict); kept Gaussians carry their
// source index v * k + j. No function here allocates.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <type_traits>
#include <vector>

#include "gs/camera.h"

namespace gs::model {

// Anchor parameters seen by the decoder (row-major, M rows).
template <class T>
struct AnchorParams {
  size_t count = 0;  // M
  int k = 0, feature_dim = 0;
  const T* positions = nullptr;   // [M, 3]
  const T* offsets = nullptr;     // [M, k, 3]
  const T* log_scales = nullptr;  // [M, 6]
  const T* features = nullptr;    // [M, F]
};

// Kept neural Gaussians of one view (arrays with room for V * k rows).
template <class T>
struct NeuralGaussians {
  size_t count = 0;
  T* means = nullptr;       // [N, 3] world
  T* log_scales = nullptr;  // [N, 3]
  T* quats = nullptr;       // [N, 4] raw u_q (the renderer normalises)
  T* opacities = nullptr;   // [N] tanh output in (0, 1)
  T* colors = nullptr;      // [N, 3]
  uint32_t* source = nullptr;  // [N] v * k + j
};

// Owned zeroed arrays behind a NeuralGaussians with room for n rows (ng points into them, so a
// copy would point into the original: move it, or assign again after copying).
template <class T>
struct NeuralGaussianBuffers {
  std::vector<T> means, log_scales, quats, opacities, colors;
  std::vector<uint32_t> source;
  NeuralGaussians<T> ng;

  void assign_rows(size_t n) {
    for (auto* v : {&means, &log_scales, &colors}) v->assign(n * 3, T(0));
    quats.assign(n * 4, T(0));
    opacities.assign(n, T(0));
    source.assign(n, 0);
    ng.means = means.data();
    ng.log_scales = log_scales.data();
    ng.quats = quats.data();
    ng.opacities = opacities.data();
    ng.colors = colors.data();
    ng.source = source.data();
  }
};

// Camera centre C = -R^T t, world units.
inline void camera_centre(const Pose& pose, double c[3]) {
  for (int i = 0; i < 3; ++i) c[i] = -(pose.R[0 + i] * double(pose.t[0]) + pose.R[3 + i] * double(pose.t[1]) + pose.R[6 + i] * double(pose.t[2]));
}

// Visibility pre-filter: the anchor as an isotropic blob of radius 3 max(s[0:3]) must be in front
// of the camera (z > 0.2, the renderer's near plane) and its projected disc must touch the image.
// Writes the visible rows among anchors [begin, end) in increasing order (rows null: only counts
// them); returns their count. (The step graph runs ranges in parallel and joins them: step_graph.h.)
template <class T>
size_t select_visible_anchor_range(const Camera& cam, const AnchorParams<T>& a, size_t begin, size_t end,
                                   uint32_t* rows) {
  size_t V = 0;
  const float* R = cam.pose.R;
  const float* t = cam.pose.t;
  const double fmax = std::max(cam.intr.fx, cam.intr.fy);
  for (size_t i = begin; i < end; ++i) {
    const T* p = a.positions + 3 * i;
    const double x = R[0] * double(p[0]) + R[1] * double(p[1]) + R[2] * double(p[2]) + t[0];
    const double y = R[3] * double(p[0]) + R[4] * double(p[1]) + R[5] * double(p[2]) + t[1];
    const double z = R[6] * double(p[0]) + R[7] * double(p[1]) + R[8] * double(p[2]) + t[2];
    if (!(z > 0.2)) continue;
    const T* ls = a.log_scales + 6 * i;
    const double s = std::exp(double(std::max(ls[0], std::max(ls[1], ls[2]))));
    const double r = 3.0 * s * fmax / z + 1.0;  // px
    const double u = cam.intr.fx * x / z + cam.intr.cx, v = cam.intr.fy * y / z + cam.intr.cy;
    if (u + r < 0 || u - r > cam.intr.width || v + r < 0 || v - r > cam.intr.height) continue;
    if (rows) rows[V] = uint32_t(i);
    ++V;
  }
  return V;
}

// All anchors: writes the visible anchor rows in increasing order (rows null: only counts); returns V.
template <class T>
size_t select_visible_anchors(const Camera& cam, const AnchorParams<T>& a, uint32_t* rows) {
  return select_visible_anchor_range(cam, a, 0, a.count, rows);
}

// Decoder input X [V, D] = [f ; g ; (a - C) / |a - C| ; |a - C|], g [V, G] may be null when G = 0.
// The distance is floored at 1e-6 so an anchor at the camera centre gives a finite direction.
// build_decoder_input_range fills the rows [v0, v1) of X only.
template <class T>
void build_decoder_input_range(const AnchorParams<T>& a, const uint32_t* rows, size_t v0, size_t v1, const T* g,
                               int G, const double centre[3], T* X) {
  const int F = a.feature_dim;
  const size_t D = size_t(F + G + 4);
  for (size_t v = v0; v < v1; ++v) {
    T* x = X + v * D;
    const size_t row = rows[v];
    std::copy(a.features + row * size_t(F), a.features + (row + 1) * size_t(F), x);
    if (G > 0) std::copy(g + v * size_t(G), g + (v + 1) * size_t(G), x + F);
    const T* p = a.positions + 3 * row;
    const double d[3] = {double(p[0]) - centre[0], double(p[1]) - centre[1], double(p[2]) - centre[2]};
    const double dist = std::max(std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1e-6);
    for (int c = 0; c < 3; ++c) x[F + G + c] = T(d[c] / dist);
    x[F + G + 3] = T(dist);
  }
}

template <class T>
void build_decoder_input(const AnchorParams<T>& a, const uint32_t* rows, size_t V, const T* g, int G,
                         const double centre[3], T* X) {
  build_decoder_input_range(a, rows, 0, V, g, G, centre, X);
}

// Backward of the direction and distance columns of build_decoder_input w.r.t. the camera centre
// C (ACCUMULATED into v_centre [3]). With d = a - C, dir = d / |d|, dist = |d|:
// dL/dd = (v_dir - dir (dir . v_dir)) / dist + dir v_dist, and dL/dC = -sum over anchors of dL/dd.
// An anchor on the distance floor (1e-6) contributes nothing (the floored value is constant).
template <class T>
void decoder_input_centre_bwd(const AnchorParams<T>& a, const uint32_t* rows, size_t V, int G, const double centre[3],
                              const T* v_X, double v_centre[3]) {
  const int F = a.feature_dim;
  const size_t D = size_t(F + G + 4);
  for (size_t v = 0; v < V; ++v) {
    const T* p = a.positions + 3 * size_t(rows[v]);
    const double d[3] = {double(p[0]) - centre[0], double(p[1]) - centre[1], double(p[2]) - centre[2]};
    const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(dist > 1e-6)) continue;
    const T* g = v_X + v * D + size_t(F + G);
    const double dir[3] = {d[0] / dist, d[1] / dist, d[2] / dist};
    const double dot = dir[0] * double(g[0]) + dir[1] * double(g[1]) + dir[2] * double(g[2]);
    for (int c = 0; c < 3; ++c) v_centre[c] -= (double(g[c]) - dir[c] * dot) / dist + dir[c] * double(g[3]);
  }
}

// Pose gradient of a camera-centre gradient: C = -R^T t moves as C' = C - R^T rho under the left
// twist (rho, phi) (the phi terms cancel), so dL/drho += -R g_C (ALGORITHM.md Part A item 14).
inline void centre_grad_to_pose(const Pose& pose, const double g_centre[3], double v_pose[6]) {
  for (int r = 0; r < 3; ++r)
    v_pose[r] -= pose.R[3 * r] * g_centre[0] + pose.R[3 * r + 1] * g_centre[1] + pose.R[3 * r + 2] * g_centre[2];
}

// log(sigmoid(u)) without overflow, and sigmoid(u). In float, log(1 + e) replaces log1p(e) (glibc's
// log1pf cost ~2.5 % of a training iteration, logf a fraction of it): they differ only for
// e < 2^-24, by less than e, which moves a log-scale by under 6e-8.
template <class T>
inline T log_sigmoid(T u) {
  const T e = std::exp(-std::abs(u));
  if constexpr (std::is_same_v<T, float>) return -(std::max(-u, T(0)) + std::log(T(1) + e));
  return -(std::max(-u, T(0)) + std::log1p(e));
}
template <class T>
inline T sigmoid(T u) {
  return T(1) / (T(1) + std::exp(-u));
}

// Whether candidate s = v k + j becomes a Gaussian: opacity > 0 and |u_q|^2 > 1e-24.
template <class T>
inline bool kept_candidate(const T* y_opacity, const T* y_cov, size_t s) {
  const T* c = y_cov + 7 * s;
  const T qn = c[3] * c[3] + c[4] * c[4] + c[5] * c[5] + c[6] * c[6];
  return y_opacity[s] > T(0) && qn > T(1e-24);
}

// How many candidates of the visible anchors [v0, v1) are kept.
template <class T>
size_t count_kept_range(int k, size_t v0, size_t v1, const T* y_opacity, const T* y_cov) {
  size_t n = 0;
  for (size_t s = v0 * size_t(k); s < v1 * size_t(k); ++s) n += kept_candidate(y_opacity, y_cov, s) ? 1 : 0;
  return n;
}

// Forward: kept Gaussians of the V visible anchors. mean = a + O_j * exp(l[0:3]);
// log-scale = l[3:6] + log sigmoid(u_s); quaternion = u_q (candidates with |u_q|^2 <= 1e-24 are
// dropped: they have no orientation); opacity = tanh output; colour = sigmoid output.
// decode_fwd_range decodes the visible anchors [v0, v1) into out's rows from n0 on (n0: the kept
// count of the anchors before v0) and returns the number it wrote; it leaves out->count alone.
template <class T>
size_t decode_fwd_range(const AnchorParams<T>& a, const uint32_t* rows, size_t v0, size_t v1, const T* y_opacity,
                        const T* y_cov, const T* y_color, size_t n0, NeuralGaussians<T>* out) {
  const int k = a.k;
  size_t n = n0;
  for (size_t v = v0; v < v1; ++v) {
    const size_t row = rows[v];
    const T* pos = a.positions + 3 * row;
    const T* ls = a.log_scales + 6 * row;
    const T os[3] = {std::exp(ls[0]), std::exp(ls[1]), std::exp(ls[2])};
    for (int j = 0; j < k; ++j) {
      const size_t s = v * size_t(k) + size_t(j);
      if (!kept_candidate(y_opacity, y_cov, s)) continue;
      const T alpha = y_opacity[s];
      const T* c = y_cov + 7 * s;
      const T* off = a.offsets + (row * size_t(k) + size_t(j)) * 3;
      for (int l = 0; l < 3; ++l) {
        out->means[3 * n + l] = pos[l] + off[l] * os[l];
        out->log_scales[3 * n + l] = ls[3 + l] + log_sigmoid(c[l]);
        out->colors[3 * n + l] = y_color[3 * s + l];
      }
      for (int l = 0; l < 4; ++l) out->quats[4 * n + l] = c[3 + l];
      out->opacities[n] = alpha;
      out->source[n] = uint32_t(s);
      ++n;
    }
  }
  return n - n0;
}

template <class T>
size_t decode_fwd(const AnchorParams<T>& a, const uint32_t* rows, size_t V, const T* y_opacity, const T* y_cov,
                  const T* y_color, NeuralGaussians<T>* out) {
  out->count = decode_fwd_range(a, rows, 0, V, y_opacity, y_cov, y_color, 0, out);
  return out->count;
}

// Gradients of the kept Gaussians (any pointer non-null; [N, 3] / [N, 3] / [N, 4] / [N] / [N, 3]).
template <class T>
struct GaussianGradsT {
  const T* v_means;
  const T* v_log_scales;
  const T* v_quats;
  const T* v_opacities;
  const T* v_colors;
};

// Backward of decode_fwd. Overwrites v_y_opacity [V, k], v_y_cov [V, k, 7], v_y_color [V, k, 3]
// (zero for dropped candidates) and ACCUMULATES into the anchor gradients v_offsets [M, k, 3] and
// v_anchor_log_scales [M, 6] at the visible rows. decode_bwd_range does the visible anchors
// [v0, v1) only (their kept Gaussians, found in ng.source, which increases); the rows are
// distinct, so ranges touch disjoint gradients and may run in parallel.
template <class T>
void decode_bwd_range(const AnchorParams<T>& a, const uint32_t* rows, size_t v0, size_t v1, const T* y_cov,
                      const NeuralGaussians<T>& ng, const GaussianGradsT<T>& g, T* v_y_opacity, T* v_y_cov,
                      T* v_y_color, T* v_offsets, T* v_anchor_log_scales) {
  const size_t k = size_t(a.k);
  std::fill(v_y_opacity + v0 * k, v_y_opacity + v1 * k, T(0));
  std::fill(v_y_cov + v0 * k * 7, v_y_cov + v1 * k * 7, T(0));
  std::fill(v_y_color + v0 * k * 3, v_y_color + v1 * k * 3, T(0));
  const uint32_t* src = ng.source;
  const uint32_t* src_end = src + ng.count;
  const size_t n0 = size_t(std::lower_bound(src, src_end, uint32_t(v0 * k)) - src);
  const size_t n1 = size_t(std::lower_bound(src + n0, src_end, uint32_t(v1 * k)) - src);
  for (size_t n = n0; n < n1; ++n) {
    const size_t s = ng.source[n];
    const size_t v = s / k, j = s % k;
    const size_t row = rows[v];
    const T* ls = a.log_scales + 6 * row;
    const T* off = a.offsets + (row * k + j) * 3;
    const T* c = y_cov + 7 * s;
    T* v_ls = v_anchor_log_scales + 6 * row;
    T* v_off = v_offsets + (row * k + j) * 3;
    v_y_opacity[s] = g.v_opacities[n];
    for (int l = 0; l < 3; ++l) {
      v_y_color[3 * s + l] = g.v_colors[3 * n + l];
      const T gl = g.v_log_scales[3 * n + l];
      v_y_cov[7 * s + l] = gl * (T(1) - sigmoid(c[l]));  // d log sigmoid(u) / du = 1 - sigmoid(u)
      v_ls[3 + l] += gl;
      const T os = std::exp(ls[l]);
      const T gm = g.v_means[3 * n + l];
      v_off[l] += gm * os;
      v_ls[l] += gm * off[l] * os;
    }
    for (int l = 0; l < 4; ++l) v_y_cov[7 * s + 3 + l] = g.v_quats[4 * n + l];
  }
}

template <class T>
void decode_bwd(const AnchorParams<T>& a, const uint32_t* rows, size_t V, const T* y_cov,
                const NeuralGaussians<T>& ng, const GaussianGradsT<T>& g, T* v_y_opacity, T* v_y_cov,
                T* v_y_color, T* v_offsets, T* v_anchor_log_scales) {
  decode_bwd_range(a, rows, 0, V, y_cov, ng, g, v_y_opacity, v_y_cov, v_y_color, v_offsets, v_anchor_log_scales);
}

// Volume regulariser weight * mean over kept Gaussians of s_x s_y s_z (the reference code's form);
// returns its value and ACCUMULATES its gradient into v_log_scales [N, 3]. 0 when N == 0.
template <class T>
double volume_fwd_bwd(size_t N, const T* log_scales, double weight, T* v_log_scales) {
  if (N == 0 || weight == 0) return 0.0;
  double sum = 0;
  const double w = weight / double(N);
  for (size_t n = 0; n < N; ++n) {
    const double vol = std::exp(double(log_scales[3 * n]) + double(log_scales[3 * n + 1]) + double(log_scales[3 * n + 2]));
    sum += vol;
    if (v_log_scales)
      for (int l = 0; l < 3; ++l) v_log_scales[3 * n + l] += T(w * vol);  // d vol / d log s_l = vol
  }
  return w * sum;
}

}  // namespace gs::model
