// SPDX-License-Identifier: MIT
// Kernel ABI of the tile splatting renderer: constants, per-camera parameters and the packed
// per-intersection record. Plain data only; this header includes nothing of the project
// but gs/simd/isa.h.
//
// Semantics follow the 3DGS tile rasteriser (Kerbl et al. 2023, and gsplat's conventions):
// near cull at z <= 0.2, EWA Jacobian with tan-clamp 1.3 x field of view, +0.3 px^2 dilation,
// radius = ceil(3 sigma_max), 16x16 tiles, front-to-back blending with alpha <= 0.99, alpha < 1/255
// skipped, stop before transmittance falls below 1e-4.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "gs/simd/isa.h"

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
// [mean2d.x, mean2d.y, conic.a, conic.b, conic.c, opacity, r, g, b, depth, two_tau, ext_x, ext_y];
// power at pixel offset d = mean2d - pixel_centre is -0.5 (a dx^2 + 2 b dx dy + c dy^2). The last
// three (see splat_support) depend only on the Gaussian, so they are computed once per Gaussian
// rather than once per tile it touches; the reference kernels do not read them.
constexpr int kSplatStride = 13;
enum SplatField {
  kSplatMx = 0, kSplatMy, kSplatA, kSplatB, kSplatC, kSplatOpacity, kSplatR, kSplatG, kSplatBlue, kSplatDepth,
  kSplatTwoTau, kSplatExtX, kSplatExtY
};

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

// Support of a splat: two_tau = 2 ln(255 o), so alpha >= 1/255 needs power >= -two_tau / 2, and the
// half-extents (px) of the box outside which alpha is provably below 1/255 (|d_x| <= sqrt(two_tau
// cov_xx), cov = conic^-1). The extents are computed in double (the determinant cancels for slanted,
// thin splats) and widened by 0.1 % + 0.05 px: the kernels' float exponent errs by about 1e-7 x
// (a dx^2 + |2 b dx dy| + c dy^2), which stays under that margin for any splat up to a standard
// deviation of about 100 px along its major axis (the +0.3 px^2 dilation bounds how thin it is);
// beyond that a pixel at the exact edge may flip, a threshold tie. (A 1 px margin, with the box
// rounded outwards on top, added up to two rows and columns on each side that the ellipse never
// reaches: blend steps for nothing.) out = [two_tau, ext_x, ext_y]; a splat that can never reach
// 1/255 gets negative extents; a non-positive-definite conic gets an unbounded box (1e30), which the
// kernels clip to the tile.
inline void splat_support(const float* conic, float opacity, float* out) {
  const double a = conic[0], b = conic[1], c = conic[2];
  if (!(opacity * 255.0f >= 1.0f)) {
    out[0] = -1.0f; out[1] = out[2] = -1.0f;
    return;
  }
  const float two_tau = 2.0f * scalar::log(255.0f * opacity);
  const double det = a * c - b * b;
  out[0] = two_tau;
  if (det > 0.0 && a > 0.0) {
    out[1] = float(scalar::sqrt(double(two_tau) * c / det) * 1.001 + 0.05);
    out[2] = float(scalar::sqrt(double(two_tau) * a / det) * 1.001 + 0.05);
  } else {
    out[1] = out[2] = 1e30f;
  }
}

}  // inline namespace GS_SIMD_ISA_NS

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

inline namespace GS_SIMD_ISA_NS {

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

}  // inline namespace GS_SIMD_ISA_NS

}  // namespace gs::simd
