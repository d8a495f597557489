// SPDX-License-Identifier: MIT
// Kernel ABI of the tile splatting renderer: constants, per-camera parameters and the packed
// per-intersection record. Plain data only; this header includes nothing of the project.
//
// Semantics follow the 3DGS tile rasteriser (Kerbl et al. 2023, and gsplat's conventions):
// near cull at z <= 0.2, EWA Jacobian with tan-clamp 1.3 x field of view, +0.3 px^2 dilation,
// radius = ceil(3 sigma_max), 16x16 tiles, front-to-back blending with alpha <= 0.99, alpha < 1/255
// skipped, stop before transmittance falls below 1e-4.
#pragma once

#include <cstddef>
#include <cstdint>

#if defined(__GNUC__)
#define GS_RESTRICT __restrict__
#else
#define GS_RESTRICT
#endif

namespace gs::simd {

constexpr int kTileSize = 16;            // pixels per tile side
constexpr float kNearPlane = 0.2f;       // camera-space z below which a Gaussian is culled
constexpr float kDilation = 0.3f;        // added to the 2D covariance diagonal, px^2 (anti-aliasing)
constexpr float kFovClampFactor = 1.3f;  // Jacobian evaluated at x/z clamped to 1.3 x the image extent
constexpr float kAlphaMax = 0.99f;
constexpr float kAlphaMin = 1.0f / 255.0f;
constexpr float kTransmittanceMin = 1e-4f;
constexpr float kEigenFloor = 0.1f;      // floor under (mid^2 - det) before the sqrt for the radius

// Packed per-intersection record written by binning, read by the tile kernels (front to back).
// [mean2d.x, mean2d.y, conic.a, conic.b, conic.c, opacity, r, g, b, depth]; power at pixel offset
// d = mean2d - pixel_centre is -0.5 (a dx^2 + 2 b dx dy + c dy^2).
constexpr int kSplatStride = 10;
enum SplatField { kSplatMx = 0, kSplatMy, kSplatA, kSplatB, kSplatC, kSplatOpacity, kSplatR, kSplatG, kSplatBlue, kSplatDepth };

// Per-camera constants for projection, precomputed once per frame.
template <class T>
struct ProjectParamsT {
  T R[9];              // world-to-camera rotation, row-major
  T t[3];              // world-to-camera translation
  T fx, fy, cx, cy;    // pinhole intrinsics, px
  T lim_x_pos, lim_x_neg, lim_y_pos, lim_y_neg;  // x/z and y/z clamp limits for the EWA Jacobian
  int32_t width, height, tiles_x, tiles_y;
};
using ProjectParams = ProjectParamsT<float>;

// Per-frame constants for the tile kernels.
template <class T>
struct RasterParamsT {
  int32_t width, height;  // image size, px
  T background[3];        // colour blended behind the last Gaussian (black by default)
};
using RasterParams = RasterParamsT<float>;

// Fills the derived fields of a ProjectParamsT from R, t and intrinsics (gsplat's limits, which
// reduce to 1.3 tan(fov/2) for a centred principal point).
template <class T>
inline void finish_project_params(ProjectParamsT<T>* p) {
  const T half_tan_x = T(0.5) * T(p->width) / p->fx, half_tan_y = T(0.5) * T(p->height) / p->fy;
  const T extra = T(kFovClampFactor) - T(1);
  p->lim_x_pos = (T(p->width) - p->cx) / p->fx + extra * half_tan_x;
  p->lim_x_neg = p->cx / p->fx + extra * half_tan_x;
  p->lim_y_pos = (T(p->height) - p->cy) / p->fy + extra * half_tan_y;
  p->lim_y_neg = p->cy / p->fy + extra * half_tan_y;
  p->tiles_x = (p->width + kTileSize - 1) / kTileSize;
  p->tiles_y = (p->height + kTileSize - 1) / kTileSize;
}

}  // namespace gs::simd
