// SPDX-License-Identifier: MIT
// Scalar reference kernels of the splatting renderer: slow, readable, templated on float and
// double, never optimised. They are the spec the SIMD kernels are tested against and the
// double-precision forward the finite-difference gradient checks differentiate.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "gs/simd/isa.h"
#include "gs/simd/splat.h"

namespace gs::simd {

// Projects n Gaussians. radii[i] == 0 marks a culled Gaussian (behind the near plane, degenerate
// 2D covariance, or no tile overlap); its other outputs are then unspecified.
template <class T>
void project_fwd_ref(const ProjectParamsT<T>* p, size_t n,
                     // fwd inputs
                     const T* means,       // [n, 3] world
                     const T* log_scales,  // [n, 3]
                     const T* quats,       // [n, 4] (w, x, y, z), any norm > 0
                     // fwd outputs
                     T* means2d,           // [n, 2] px
                     T* conics,            // [n, 3] inverse 2D covariance (a, b, c)
                     T* depths,            // [n] camera z
                     int32_t* radii);      // [n] px, 0 = culled

// Backward of project_fwd_ref. Outputs are overwritten (zero for culled Gaussians); the pose
// gradient (twist of a left perturbation of the world-to-camera transform, (rho, phi)) is added
// to v_pose.
template <class T>
void project_bwd_ref(const ProjectParamsT<T>* p, size_t n,
                     // fwd inputs
                     const T* means, const T* log_scales, const T* quats, const int32_t* radii,
                     // grad inputs
                     const T* v_means2d,  // [n, 2]
                     const T* v_conics,   // [n, 3] w.r.t. (a, b, c) with b counted once
                     const T* v_depths,   // [n] or nullptr
                     // grad outputs
                     T* v_means,          // [n, 3]
                     T* v_log_scales,     // [n, 3]
                     T* v_quats,          // [n, 4]
                     double* v_pose);     // [6] (rho, phi), accumulated

// Forward-mode pose tangents of project_fwd_ref (ALGORITHM.md Part A item 14): for each of the six
// unit twists xi_k = (rho, phi) of a LEFT perturbation of the world-to-camera transform
// (T <- Exp(xi) T: camera mean m moves as dm = rho + phi x m, camera covariance S as
// dS = [phi]x S - S [phi]x), the derivative of mean2d and of the conic (a, b, c), through exactly
// the forward's EWA Jacobian (tan clamp included: a clamped x/z makes tx = z lim, so dtx = lim dz),
// the 0.3 px^2 dilation and the 2x2 inversion (d conic = -Q dCov Q). Zero for culled Gaussians
// (radii == 0). Index [i, r, k]: Gaussian i, output component r, twist k.
template <class T>
void project_pose_tangents_ref(const ProjectParamsT<T>* p, size_t n,
                               // fwd inputs
                               const T* means,        // [n, 3] world
                               const T* log_scales,   // [n, 3]
                               const T* quats,        // [n, 4]
                               const int32_t* radii,  // [n] from project_fwd_ref, 0 = culled
                               // tangent outputs
                               T* d_means2d,          // [n, 2, 6] px per unit twist
                               T* d_conics);          // [n, 3, 6]

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

// Tile rectangle [x0, x1) x [y0, y1) in tiles covered by a projected Gaussian (3DGS getRect, with
// the mean shifted by -0.5 px because hbgs puts pixel centres at +0.5). Returns the tile count.
template <class T>
inline int32_t tile_rect(const ProjectParamsT<T>* p, const T* mean2d, int32_t radius, int32_t rect[4]) {
  const T px = mean2d[0] - T(0.5), py = mean2d[1] - T(0.5), r = T(radius);
  auto clampi = [](T v, int32_t hi) {
    // Truncation toward zero as in the CUDA reference, then clamp; guard huge values before the cast.
    if (!(v > T(-1e9))) v = T(-1e9);
    if (v > T(1e9)) v = T(1e9);
    int32_t i = int32_t(v);
    return i < 0 ? 0 : (i > hi ? hi : i);
  };
  const int32_t ts = kTileSize;
  rect[0] = clampi((px - r) / T(ts), p->tiles_x);
  rect[1] = clampi((py - r) / T(ts), p->tiles_y);
  rect[2] = clampi((px + r + T(ts - 1)) / T(ts), p->tiles_x);
  rect[3] = clampi((py + r + T(ts - 1)) / T(ts), p->tiles_y);
  return (rect[2] - rect[0]) * (rect[3] - rect[1]);
}

// True if the splat can reach alpha >= 1/255 at some pixel centre of tile (tx, ty): the minimum of
// its quadratic form q(u) = a ux^2 + 2 b ux uy + c uy^2 (power = -q / 2, u = pixel - mean) over the
// rectangle spanned by the tile's pixel centres (clipped to the image) against two_tau = 2 ln(255 o).
// Exact like tile_rect_supported (a skipped tile holds only pixels the kernels would skip), with a
// relative margin of 1e-3 against float rounding; a conic that is not positive definite reaches
// every tile of its rect.
template <class T>
inline bool splat_reaches_tile(const T* mean2d, const T* conic, float two_tau, int32_t tx, int32_t ty, int32_t width,
                               int32_t height) {
  const double a = double(conic[0]), b = double(conic[1]), c = double(conic[2]);
  if (!(a > 0.0) || !(c > 0.0) || !(a * c - b * b > 0.0)) return true;
  const double limit = double(two_tau) * 1.001 + 1e-3;
  const double x0 = tx * kTileSize + 0.5 - double(mean2d[0]);
  const double x1 = double(scalar::min((tx + 1) * kTileSize, width)) - 0.5 - double(mean2d[0]);
  const double y0 = ty * kTileSize + 0.5 - double(mean2d[1]);
  const double y1 = double(scalar::min((ty + 1) * kTileSize, height)) - 0.5 - double(mean2d[1]);
  if (x0 <= 0.0 && 0.0 <= x1 && y0 <= 0.0 && 0.0 <= y1) return limit >= 0.0;
  auto clampd = [](double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); };
  auto q = [&](double ux, double uy) { return a * ux * ux + 2.0 * b * ux * uy + c * uy * uy; };
  double qmin = q(x0, clampd(-b * x0 / c, y0, y1));
  qmin = scalar::min(qmin, q(x1, clampd(-b * x1 / c, y0, y1)));
  qmin = scalar::min(qmin, q(clampd(-b * y0 / a, x0, x1), y0));
  qmin = scalar::min(qmin, q(clampd(-b * y1 / a, x0, x1), y1));
  return qmin <= limit;
}

// splat_reaches_tile for every tile of rect [rect[0], rect[2]) x [rect[1], rect[3]) of at most 64
// tiles, as bit (ty - rect[1]) * (rect[2] - rect[0]) + (tx - rect[0]). The same double operations
// in the same order as splat_reaches_tile (so the same bits; the build sets -ffp-contract=off),
// with the edge terms of each tile column and row (and their divisions) computed once.
template <class T>
inline uint64_t splat_reaches_tiles(const T* mean2d, const T* conic, float two_tau, const int32_t rect[4], int32_t width,
                                    int32_t height) {
  const int32_t rw = rect[2] - rect[0], rh = rect[3] - rect[1];
  if (rw <= 0 || rh <= 0 || rw * rh > 64) return 0;
  const double a = double(conic[0]), b = double(conic[1]), c = double(conic[2]);
  if (!(a > 0.0) || !(c > 0.0) || !(a * c - b * b > 0.0)) return rw * rh == 64 ? ~uint64_t(0) : (uint64_t(1) << (rw * rh)) - 1;
  const double limit = double(two_tau) * 1.001 + 1e-3;
  double x0[64], x1[64], bx0[64], bx1[64], y0[64], y1[64], by0[64], by1[64];
  for (int32_t i = 0; i < rw; ++i) {
    const int32_t tx = rect[0] + i;
    x0[i] = tx * kTileSize + 0.5 - double(mean2d[0]);
    x1[i] = double(scalar::min((tx + 1) * kTileSize, width)) - 0.5 - double(mean2d[0]);
    bx0[i] = -b * x0[i] / c;
    bx1[i] = -b * x1[i] / c;
  }
  for (int32_t i = 0; i < rh; ++i) {
    const int32_t ty = rect[1] + i;
    y0[i] = ty * kTileSize + 0.5 - double(mean2d[1]);
    y1[i] = double(scalar::min((ty + 1) * kTileSize, height)) - 0.5 - double(mean2d[1]);
    by0[i] = -b * y0[i] / a;
    by1[i] = -b * y1[i] / a;
  }
  auto clampd = [](double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); };
  auto q = [&](double ux, double uy) { return a * ux * ux + 2.0 * b * ux * uy + c * uy * uy; };
  uint64_t mask = 0;
  for (int32_t j = 0, bit = 0; j < rh; ++j)
    for (int32_t i = 0; i < rw; ++i, ++bit) {
      bool reaches;
      if (x0[i] <= 0.0 && 0.0 <= x1[i] && y0[j] <= 0.0 && 0.0 <= y1[j]) {
        reaches = limit >= 0.0;
      } else {
        double qmin = q(x0[i], clampd(bx0[i], y0[j], y1[j]));
        qmin = scalar::min(qmin, q(x1[i], clampd(bx1[i], y0[j], y1[j])));
        qmin = scalar::min(qmin, q(clampd(by0[j], x0[i], x1[i]), y0[j]));
        qmin = scalar::min(qmin, q(clampd(by1[j], x0[i], x1[i]), y1[j]));
        reaches = qmin <= limit;
      }
      mask |= uint64_t(reaches) << bit;
    }
  return mask;
}

// The tiles a splat is binned to: its 3-sigma tile_rect narrowed to the tiles that hold a pixel
// inside its alpha >= 1/255 support box (support = [two_tau, ext_x, ext_y], splat_support). Exact
// with respect to the image: a pixel outside that box gets alpha < 1/255 and is skipped by every
// tile kernel, so dropping tiles that hold only such pixels changes no output value, only the
// per-tile lists (fewer intersections to sort and blend). Widened by half a pixel against rounding.
template <class T>
inline int32_t tile_rect_supported(const ProjectParamsT<T>* p, const T* mean2d, int32_t radius, const float* support,
                                   int32_t rect[4]) {
  tile_rect(p, mean2d, radius, rect);
  const double ext[2] = {double(support[1]), double(support[2])};
  if (!(ext[0] >= 0.0) || !(ext[1] >= 0.0)) {
    rect[2] = rect[0];  // no pixel reaches 1/255: an empty rect
    rect[3] = rect[1];
    return 0;
  }
  for (int axis = 0; axis < 2; ++axis) {
    if (!(ext[axis] < 1e6)) continue;  // unbounded support: keep the 3-sigma rect
    const double centre = double(mean2d[axis]) - 0.5;  // in pixel-index units
    const double lo = scalar::floor((centre - ext[axis] - 0.5) / kTileSize);
    const double hi = scalar::floor((centre + ext[axis] + 0.5) / kTileSize) + 1;
    if (lo > double(rect[axis])) rect[axis] = int32_t(scalar::min(lo, double(rect[axis + 2])));
    if (hi < double(rect[axis + 2])) rect[axis + 2] = int32_t(scalar::max(hi, double(rect[axis])));
  }
  return (rect[2] - rect[0]) * (rect[3] - rect[1]);
}

}  // inline namespace GS_SIMD_ISA_NS

// One splat evaluated at a pixel centre (px, py): offsets, Gaussian falloff G and alpha.
template <class T>
struct SplatEval {
  T dx, dy, G, alpha;
  bool clamped;  // alpha hit the 0.99 ceiling: no gradient flows to opacity or the Gaussian
};

inline namespace GS_SIMD_ISA_NS {  // inline code: per-ISA copies (gs/simd/isa.h)

// Returns false when the splat does not contribute to the pixel (power > 0, which only a
// non-positive-definite conic gives, or alpha below 1/255).
template <class T>
inline bool eval_splat_ref(const T* s, T px, T py, SplatEval<T>* e) {
  e->dx = s[kSplatMx] - px;
  e->dy = s[kSplatMy] - py;
  const T power = T(-0.5) * (s[kSplatA] * e->dx * e->dx + s[kSplatC] * e->dy * e->dy) - s[kSplatB] * e->dx * e->dy;
  if (power > T(0)) return false;
  e->G = scalar::exp(power);
  const T raw = s[kSplatOpacity] * e->G;
  e->clamped = raw > T(kAlphaMax);
  e->alpha = e->clamped ? T(kAlphaMax) : raw;
  return e->alpha >= T(kAlphaMin);
}

}  // inline namespace GS_SIMD_ISA_NS

// Blends one tile front to back. splats holds `count` packed records sorted by depth.
// Writes the tile's pixels of out_rgb [H, W, 3], out_T [H, W] (final transmittance), out_last
// [H, W] (1 + index of the last contributing record, 0 if none) and, if not null, out_depth [H, W]
// (alpha-weighted depth, not normalised).
template <class T>
void raster_fwd_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y,
                         const T* splats, int32_t count,
                         T* out_rgb, T* out_T, int32_t* out_last, T* out_depth);

// Backward of raster_fwd_tile_ref for one tile. v_splats [count, kSplatStride] is overwritten
// with the gradient w.r.t. each record's mean2d, conic, opacity and colour (depth slot = 0).
template <class T>
void raster_bwd_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y,
                         const T* splats, int32_t count,
                         const T* final_T, const int32_t* last,
                         const T* v_rgb,  // [H, W, 3]
                         T* v_splats);

// Forward-mode pose Jacobian of raster_fwd_tile_ref for one tile: the six twist tangents of each
// record's mean2d and conic carried through front-to-back blending with the forward's exact skip
// (alpha < 1/255, power > 0), clamp (alpha = 0.99 has zero tangent) and early-stop rules:
//   dalpha_i = alpha_i dpower_i (0 if clamped), dT_{i+1} = dT_i (1 - alpha_i) - T_i dalpha_i,
//   dC = sum_i c_i (dalpha_i T_i + alpha_i dT_i) + background dT_final.
// Colours and opacities are pose-independent here. Writes the tile's pixels of out_jacobian.
template <class T>
void raster_pose_jacobian_tile_ref(const RasterParamsT<T>* p, int32_t tile_x, int32_t tile_y,
                                   // fwd inputs
                                   const T* splats,          // [count, kSplatStride] depth-sorted
                                   const T* splat_tangents,  // [count, 5, 6]: mean2d x, y, conic a, b, c
                                   int32_t count,
                                   // tangent outputs
                                   T* out_jacobian);         // [H, W, 3, 6] d rgb / d xi

// The real SH basis values b[0 .. (degree + 1)^2) for a unit direction (3DGS constants and signs):
// what sh_fwd_ref sums its coefficients against (fitting SH colours needs the basis itself).
template <class T>
void sh_basis_ref(int32_t degree, const T dir[3], T b[16]);

// Colour from spherical harmonics (3DGS convention: value + 0.5, clamped at 0 from below).
// sh [n, K, 3] with K = (degree + 1)^2; campos = camera centre in world coordinates.
template <class T>
void sh_fwd_ref(size_t n, int32_t degree, const T* means, const T* sh, const T* campos, T* colors);
// Backward: v_sh [n, K, 3] overwritten; v_means [n, 3] (view-direction path) and v_campos [3]
// accumulated.
template <class T>
void sh_bwd_ref(size_t n, int32_t degree, const T* means, const T* sh, const T* campos,
                const T* v_colors, T* v_sh, T* v_means, T* v_campos);

}  // namespace gs::simd
