// SPDX-License-Identifier: MIT
// The whole renderer written the slow, obvious way, templated on float and double: project every
// Gaussian, bin into tiles with std::sort, blend with the reference tile kernels. It allocates and
// is never used at run time; it is the spec for gs::Renderer and the double-precision forward that
// the finite-difference gradient checks differentiate.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace gs::ref {

template <class T>
struct Scene {
  size_t n = 0;
  std::vector<T> means, log_scales, quats, opacities;  // [n,3] [n,3] [n,4] [n]
  std::vector<T> colors;                               // [n,3], used when sh_degree < 0
  std::vector<T> sh;                                   // [n,K,3], used when sh_degree >= 0
  int sh_degree = -1;
};

template <class T>
struct View {
  T R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  T t[3] = {0, 0, 0};
  T fx = 1, fy = 1, cx = 0, cy = 0;
  int width = 1, height = 1;
  T background[3] = {0, 0, 0};
};

template <class T>
struct Forward {
  std::vector<T> rgb, final_T, depth;  // [H,W,3] [H,W] [H,W]
  std::vector<int32_t> last, radii;
  std::vector<T> means2d, conics, depths, colors;
  std::vector<uint32_t> tile_offsets;  // [tiles+1]
  std::vector<uint32_t> tile_ids;      // Gaussian id per intersection, depth-sorted within each tile
  std::vector<T> splats;               // packed records per intersection
  // Hash of every discrete decision (tile coverage, depth order, which splats contribute to which
  // pixel, alpha clamps, early stops). Equal signatures at x +- eps mean the forward is smooth
  // between them, so a finite difference there is meaningful (the boundary band of the FD test).
  uint64_t signature = 0;
};

template <class T>
struct Grads {
  std::vector<T> v_means, v_log_scales, v_quats, v_opacities, v_colors, v_sh, v_means2d;
  double v_pose[6] = {0, 0, 0, 0, 0, 0};
};

template <class T>
Forward<T> render_fwd(const Scene<T>& scene, const View<T>& view);
template <class T>
Grads<T> render_bwd(const Scene<T>& scene, const View<T>& view, const Forward<T>& fwd, const T* v_rgb);

// Forward-mode pose Jacobian of the rendered image, [H, W, 3, 6]: d rgb / d xi for a LEFT twist
// xi = (rho, phi) of the world-to-camera transform (T <- Exp(xi) T, the twist of Grads::v_pose), so
// sum over pixels of J^T v_rgb equals render_bwd's v_pose for a colour scene. Colours and
// opacities are held fixed: for an SH scene the colours are those evaluated at this view (the
// view-direction dependence through the camera centre is ignored, unlike render_bwd). fwd must be
// render_fwd(scene, view).
template <class T>
std::vector<T> render_pose_jacobian(const Scene<T>& scene, const View<T>& view, const Forward<T>& fwd);

}  // namespace gs::ref
