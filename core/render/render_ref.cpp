// SPDX-License-Identifier: MIT
// Reference renderer pipeline (see gs/render_ref.h): the readable twin of renderer.cpp.
#include "gs/render_ref.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include "gs/hash.h"
#include "gs/simd/ref.h"

namespace gs::ref {
namespace {

template <class T>
simd::ProjectParamsT<T> project_params(const View<T>& v) {
  simd::ProjectParamsT<T> p{};
  std::copy(v.R, v.R + 9, p.R);
  std::copy(v.t, v.t + 3, p.t);
  p.fx = v.fx; p.fy = v.fy; p.cx = v.cx; p.cy = v.cy;
  p.width = v.width; p.height = v.height;
  simd::finish_project_params(&p);
  return p;
}

template <class T>
void campos_of(const View<T>& v, T c[3]) {
  for (int k = 0; k < 3; ++k) c[k] = -(v.R[k] * v.t[0] + v.R[3 + k] * v.t[1] + v.R[6 + k] * v.t[2]);
}

}  // namespace

template <class T>
Forward<T> render_fwd(const Scene<T>& s, const View<T>& v) {
  Forward<T> f;
  const size_t n = s.n;
  const simd::ProjectParamsT<T> p = project_params(v);
  f.means2d.assign(2 * n, T(0));
  f.conics.assign(3 * n, T(0));
  f.depths.assign(n, T(0));
  f.radii.assign(n, 0);
  simd::project_fwd_ref<T>(&p, n, s.means.data(), s.log_scales.data(), s.quats.data(), f.means2d.data(),
                           f.conics.data(), f.depths.data(), f.radii.data());
  if (s.sh_degree >= 0) {
    T c[3];
    campos_of(v, c);
    f.colors.assign(3 * n, T(0));
    simd::sh_fwd_ref<T>(n, s.sh_degree, s.means.data(), s.sh.data(), c, f.colors.data());
  } else {
    f.colors = s.colors;
  }
  // Bin: (tile, depth, id) triples, sorted.
  const int tiles = p.tiles_x * p.tiles_y;
  struct Isect { int tile; T depth; uint32_t id; };
  std::vector<Isect> isects;
  uint64_t sig = 0;
  for (size_t i = 0; i < n; ++i) {
    sig = hash_combine(sig, uint64_t(f.radii[i] > 0));
    if (f.radii[i] == 0) continue;
    int32_t r[4];
    float support[3];
    const float conic[3] = {float(f.conics[3 * i]), float(f.conics[3 * i + 1]), float(f.conics[3 * i + 2])};
    simd::splat_support(conic, float(s.opacities[i]), support);
    simd::tile_rect_supported(&p, &f.means2d[2 * i], f.radii[i], support, r);
    for (int k = 0; k < 4; ++k) sig = hash_combine(sig, uint64_t(r[k]));
    for (int ty = r[1]; ty < r[3]; ++ty)
      for (int tx = r[0]; tx < r[2]; ++tx)
        if (simd::splat_reaches_tile(&f.means2d[2 * i], &f.conics[3 * i], support[0], tx, ty, p.width, p.height)) {
          isects.push_back({ty * p.tiles_x + tx, f.depths[i], uint32_t(i)});
          sig = hash_combine(sig, uint64_t(ty * p.tiles_x + tx));
        }
  }
  std::sort(isects.begin(), isects.end(), [](const Isect& a, const Isect& b) {
    if (a.tile != b.tile) return a.tile < b.tile;
    if (a.depth != b.depth) return a.depth < b.depth;
    return a.id < b.id;
  });
  f.tile_offsets.assign(tiles + 1, 0);
  for (const Isect& is : isects) f.tile_offsets[is.tile + 1]++;
  for (int t = 0; t < tiles; ++t) f.tile_offsets[t + 1] += f.tile_offsets[t];
  f.tile_ids.resize(isects.size());
  f.splats.resize(isects.size() * simd::kSplatStride);
  for (size_t k = 0; k < isects.size(); ++k) {
    const uint32_t g = isects[k].id;
    f.tile_ids[k] = g;
    sig = hash_combine(sig, g);
    T* r = &f.splats[k * simd::kSplatStride];
    r[simd::kSplatMx] = f.means2d[2 * g]; r[simd::kSplatMy] = f.means2d[2 * g + 1];
    r[simd::kSplatA] = f.conics[3 * g]; r[simd::kSplatB] = f.conics[3 * g + 1]; r[simd::kSplatC] = f.conics[3 * g + 2];
    r[simd::kSplatOpacity] = s.opacities[g];
    r[simd::kSplatR] = f.colors[3 * g]; r[simd::kSplatG] = f.colors[3 * g + 1]; r[simd::kSplatBlue] = f.colors[3 * g + 2];
    r[simd::kSplatDepth] = f.depths[g];
    float support[3];
    const float conic[3] = {float(f.conics[3 * g]), float(f.conics[3 * g + 1]), float(f.conics[3 * g + 2])};
    simd::splat_support(conic, float(s.opacities[g]), support);
    for (int k = 0; k < 3; ++k) r[simd::kSplatTwoTau + k] = T(support[k]);
  }
  // Blend.
  const size_t P = size_t(v.width) * v.height;
  f.rgb.assign(3 * P, T(0));
  f.final_T.assign(P, T(1));
  f.depth.assign(P, T(0));
  f.last.assign(P, 0);
  simd::RasterParamsT<T> rp{};
  rp.width = v.width; rp.height = v.height;
  std::copy(v.background, v.background + 3, rp.background);
  for (int t = 0; t < tiles; ++t) {
    const uint32_t b = f.tile_offsets[t], e = f.tile_offsets[t + 1];
    simd::raster_fwd_tile_ref<T>(&rp, t % p.tiles_x, t / p.tiles_x, f.splats.data() + size_t(b) * simd::kSplatStride,
                                 int32_t(e - b), f.rgb.data(), f.final_T.data(), f.last.data(), f.depth.data());
  }
  // Signature of the per-pixel decisions.
  for (int y = 0; y < v.height; ++y) {
    for (int x = 0; x < v.width; ++x) {
      const int t = (y / simd::kTileSize) * p.tiles_x + x / simd::kTileSize;
      const size_t pix = size_t(y) * v.width + x;
      sig = hash_combine(sig, uint64_t(f.last[pix]));
      for (int32_t k = 0; k < f.last[pix]; ++k) {
        simd::SplatEval<T> e;
        const bool c = simd::eval_splat_ref(&f.splats[(f.tile_offsets[t] + k) * simd::kSplatStride], T(x) + T(0.5),
                                            T(y) + T(0.5), &e);
        sig = hash_combine(sig, uint64_t(c) * 2 + uint64_t(c && e.clamped));
      }
    }
  }
  f.signature = sig;
  return f;
}

template <class T>
Grads<T> render_bwd(const Scene<T>& s, const View<T>& v, const Forward<T>& f, const T* v_rgb) {
  Grads<T> g;
  const size_t n = s.n;
  const simd::ProjectParamsT<T> p = project_params(v);
  simd::RasterParamsT<T> rp{};
  rp.width = v.width; rp.height = v.height;
  std::copy(v.background, v.background + 3, rp.background);
  std::vector<T> v_splats(f.splats.size(), T(0));
  const int tiles = p.tiles_x * p.tiles_y;
  for (int t = 0; t < tiles; ++t) {
    const uint32_t b = f.tile_offsets[t], e = f.tile_offsets[t + 1];
    simd::raster_bwd_tile_ref<T>(&rp, t % p.tiles_x, t / p.tiles_x, f.splats.data() + size_t(b) * simd::kSplatStride,
                                 int32_t(e - b), f.final_T.data(), f.last.data(), v_rgb,
                                 v_splats.data() + size_t(b) * simd::kSplatStride);
  }
  g.v_means2d.assign(2 * n, T(0));
  std::vector<T> v_conics(3 * n, T(0));
  g.v_opacities.assign(n, T(0));
  std::vector<T> v_colors(3 * n, T(0));
  for (size_t k = 0; k < f.tile_ids.size(); ++k) {
    const uint32_t id = f.tile_ids[k];
    const T* vs = &v_splats[k * simd::kSplatStride];
    g.v_means2d[2 * id] += vs[simd::kSplatMx];
    g.v_means2d[2 * id + 1] += vs[simd::kSplatMy];
    for (int c = 0; c < 3; ++c) v_conics[3 * id + c] += vs[simd::kSplatA + c];
    g.v_opacities[id] += vs[simd::kSplatOpacity];
    for (int c = 0; c < 3; ++c) v_colors[3 * id + c] += vs[simd::kSplatR + c];
  }
  g.v_means.assign(3 * n, T(0));
  g.v_log_scales.assign(3 * n, T(0));
  g.v_quats.assign(4 * n, T(0));
  simd::project_bwd_ref<T>(&p, n, s.means.data(), s.log_scales.data(), s.quats.data(), f.radii.data(),
                           g.v_means2d.data(), v_conics.data(), nullptr, g.v_means.data(), g.v_log_scales.data(),
                           g.v_quats.data(), g.v_pose);
  if (s.sh_degree >= 0) {
    T c[3], v_c[3] = {0, 0, 0};
    campos_of(v, c);
    g.v_sh.assign(s.sh.size(), T(0));
    simd::sh_bwd_ref<T>(n, s.sh_degree, s.means.data(), s.sh.data(), c, v_colors.data(), g.v_sh.data(),
                        g.v_means.data(), v_c);
    for (int k = 0; k < 3; ++k) g.v_pose[k] -= double(v.R[k * 3] * v_c[0] + v.R[k * 3 + 1] * v_c[1] + v.R[k * 3 + 2] * v_c[2]);
  } else {
    g.v_colors = std::move(v_colors);
  }
  return g;
}

template <class T>
std::vector<T> render_pose_jacobian(const Scene<T>& s, const View<T>& v, const Forward<T>& f) {
  const size_t n = s.n;
  const simd::ProjectParamsT<T> p = project_params(v);
  std::vector<T> d_means2d(12 * n), d_conics(18 * n);
  simd::project_pose_tangents_ref<T>(&p, n, s.means.data(), s.log_scales.data(), s.quats.data(), f.radii.data(),
                                     d_means2d.data(), d_conics.data());
  // Per-intersection tangent records [isects, 5, 6] in the tile lists' order.
  std::vector<T> tangents(f.tile_ids.size() * 30);
  for (size_t k = 0; k < f.tile_ids.size(); ++k) {
    const uint32_t g = f.tile_ids[k];
    std::copy(&d_means2d[12 * g], &d_means2d[12 * g] + 12, &tangents[30 * k]);
    std::copy(&d_conics[18 * g], &d_conics[18 * g] + 18, &tangents[30 * k + 12]);
  }
  simd::RasterParamsT<T> rp{};
  rp.width = v.width; rp.height = v.height;
  std::copy(v.background, v.background + 3, rp.background);
  std::vector<T> jac(size_t(v.width) * v.height * 18, T(0));
  const int tiles = p.tiles_x * p.tiles_y;
  for (int t = 0; t < tiles; ++t) {
    const uint32_t b = f.tile_offsets[t], e = f.tile_offsets[t + 1];
    simd::raster_pose_jacobian_tile_ref<T>(&rp, t % p.tiles_x, t / p.tiles_x,
                                           f.splats.data() + size_t(b) * simd::kSplatStride,
                                           tangents.data() + size_t(b) * 30, int32_t(e - b), jac.data());
  }
  return jac;
}

template Forward<float> render_fwd<float>(const Scene<float>&, const View<float>&);
template Forward<double> render_fwd<double>(const Scene<double>&, const View<double>&);
template Grads<float> render_bwd<float>(const Scene<float>&, const View<float>&, const Forward<float>&, const float*);
template Grads<double> render_bwd<double>(const Scene<double>&, const View<double>&, const Forward<double>&,
                                          const double*);

template std::vector<float> render_pose_jacobian<float>(const Scene<float>&, const View<float>&, const Forward<float>&);
template std::vector<double> render_pose_jacobian<double>(const Scene<double>&, const View<double>&,
                                                          const Forward<double>&);

}  // namespace gs::ref
