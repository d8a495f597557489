// SPDX-License-Identifier: MIT
// xsimd projection of 3D Gaussians to 2D splats, N Gaussians per batch. Inputs are [n, 3]/[n, 4]
// interleaved, so each block of N is transposed into aligned lane arrays first (scalar copies; the
// maths after it is ~150 flops per Gaussian). Semantics are those of project_ref.cpp (the spec).
// The backward currently reuses the reference kernel (it is O(n) and a small share of a frame);
// a SIMD backward is future work.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <xsimd/xsimd.hpp>

#include "gs/simd/ref.h"
#include "gs/simd/splat.h"

namespace gs::simd::kernels {

template <class Arch>
struct ProjectKernels {
  using B = xsimd::batch<float, Arch>;
  using M = xsimd::batch_bool<float, Arch>;
  static constexpr int N = int(B::size);

  static void fwd(const ProjectParams* p, size_t n, const float* means, const float* log_scales, const float* quats,
                  float* means2d, float* conics, float* depths, int32_t* radii) {
    size_t i = 0;
    for (; i + N <= n; i += N) fwd_block(p, i, means, log_scales, quats, means2d, conics, depths, radii);
    if (i < n)  // tail: the reference is the spec, and the tail is < N Gaussians
      project_fwd_ref<float>(p, n - i, means + 3 * i, log_scales + 3 * i, quats + 4 * i, means2d + 2 * i,
                             conics + 3 * i, depths + i, radii + i);
  }

  static void bwd(const ProjectParams* p, size_t n, const float* means, const float* log_scales, const float* quats,
                  const int32_t* radii, const float* v_means2d, const float* v_conics, const float* v_depths,
                  float* v_means, float* v_log_scales, float* v_quats, double* v_pose) {
    project_bwd_ref<float>(p, n, means, log_scales, quats, radii, v_means2d, v_conics, v_depths, v_means,
                           v_log_scales, v_quats, v_pose);
  }

 private:
  static void fwd_block(const ProjectParams* p, size_t i0, const float* means, const float* log_scales,
                        const float* quats, float* means2d, float* conics, float* depths, int32_t* radii) {
    alignas(64) float mu[3][N], ls[3][N], q[4][N];
    for (int l = 0; l < N; ++l) {
      const size_t i = i0 + l;
      for (int k = 0; k < 3; ++k) mu[k][l] = means[3 * i + k];
      for (int k = 0; k < 3; ++k) ls[k][l] = log_scales[3 * i + k];
      for (int k = 0; k < 4; ++k) q[k][l] = quats[4 * i + k];
    }
    B w = B::load_aligned(q[0]), x = B::load_aligned(q[1]), y = B::load_aligned(q[2]), z = B::load_aligned(q[3]);
    const B inv_norm = B(1.0f) / xsimd::max(xsimd::sqrt(w * w + x * x + y * y + z * z), B(1e-12f));
    w *= inv_norm; x *= inv_norm; y *= inv_norm; z *= inv_norm;
    const B Rg[9] = {B(1.0f) - B(2.0f) * (y * y + z * z), B(2.0f) * (x * y - w * z), B(2.0f) * (x * z + w * y),
                     B(2.0f) * (x * y + w * z), B(1.0f) - B(2.0f) * (x * x + z * z), B(2.0f) * (y * z - w * x),
                     B(2.0f) * (x * z - w * y), B(2.0f) * (y * z + w * x), B(1.0f) - B(2.0f) * (x * x + y * y)};
    const B s[3] = {xsimd::exp(B::load_aligned(ls[0])), xsimd::exp(B::load_aligned(ls[1])),
                    xsimd::exp(B::load_aligned(ls[2]))};
    const B mx = B::load_aligned(mu[0]), my = B::load_aligned(mu[1]), mz = B::load_aligned(mu[2]);
    const float* R = p->R;
    const B cx = B(R[0]) * mx + B(R[1]) * my + B(R[2]) * mz + B(p->t[0]);
    const B cy = B(R[3]) * mx + B(R[4]) * my + B(R[5]) * mz + B(p->t[1]);
    const B cz = B(R[6]) * mx + B(R[7]) * my + B(R[8]) * mz + B(p->t[2]);
    // A = R Rg diag(s); camera covariance S = A A^T.
    B A[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        A[r * 3 + c] = (B(R[r * 3]) * Rg[c] + B(R[r * 3 + 1]) * Rg[3 + c] + B(R[r * 3 + 2]) * Rg[6 + c]) * s[c];
    B S[6];  // upper triangle 00 01 02 11 12 22
    const int pairs[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int k = 0; k < 6; ++k) {
      const int r = pairs[k][0], c = pairs[k][1];
      S[k] = A[r * 3] * A[c * 3] + A[r * 3 + 1] * A[c * 3 + 1] + A[r * 3 + 2] * A[c * 3 + 2];
    }
    const M in_front = cz > B(kNearPlane);
    const B zs = xsimd::select(in_front, cz, B(1.0f));  // keep culled lanes finite
    const B xz = cx / zs, yz = cy / zs;
    const B tx = zs * xsimd::min(B(p->lim_x_pos), xsimd::max(B(-p->lim_x_neg), xz));
    const B ty = zs * xsimd::min(B(p->lim_y_pos), xsimd::max(B(-p->lim_y_neg), yz));
    const B j00 = B(p->fx) / zs, j02 = B(-p->fx) * tx / (zs * zs);
    const B j11 = B(p->fy) / zs, j12 = B(-p->fy) * ty / (zs * zs);
    // cov2 = J S J^T with J = [[j00, 0, j02], [0, j11, j12]]
    const B js00 = j00 * S[0] + j02 * S[2], js01 = j00 * S[1] + j02 * S[4], js02 = j00 * S[2] + j02 * S[5];
    const B js11 = j11 * S[3] + j12 * S[4], js12 = j11 * S[4] + j12 * S[5];
    const B a = js00 * j00 + js02 * j02 + B(kDilation);
    const B b = js01 * j11 + js02 * j12;
    const B c = js11 * j11 + js12 * j12 + B(kDilation);
    const B det = a * c - b * b;
    const M valid = in_front & (det > B(0.0f));
    const B inv_det = B(1.0f) / xsimd::select(valid, det, B(1.0f));
    const B mid = B(0.5f) * (a + c);
    const B lambda = mid + xsimd::sqrt(xsimd::max(B(kEigenFloor), mid * mid - det));
    const B radius = xsimd::ceil(B(3.0f) * xsimd::sqrt(lambda));
    alignas(64) float o_u[N], o_v[N], o_a[N], o_b[N], o_c[N], o_z[N], o_r[N], o_ok[N];
    (B(p->fx) * cx / zs + B(p->cx)).store_aligned(o_u);
    (B(p->fy) * cy / zs + B(p->cy)).store_aligned(o_v);
    (c * inv_det).store_aligned(o_a);
    (-b * inv_det).store_aligned(o_b);
    (a * inv_det).store_aligned(o_c);
    cz.store_aligned(o_z);
    xsimd::min(radius, B(float(1 << 24))).store_aligned(o_r);
    xsimd::select(valid, B(1.0f), B(0.0f)).store_aligned(o_ok);
    for (int l = 0; l < N; ++l) {
      const size_t i = i0 + l;
      radii[i] = 0;
      if (o_ok[l] == 0.0f) continue;
      means2d[2 * i] = o_u[l];
      means2d[2 * i + 1] = o_v[l];
      conics[3 * i] = o_a[l];
      conics[3 * i + 1] = o_b[l];
      conics[3 * i + 2] = o_c[l];
      depths[i] = o_z[l];
      int32_t rect[4];
      const int32_t r = int32_t(o_r[l]);
      if (tile_rect(p, means2d + 2 * i, r, rect) > 0) radii[i] = r;
    }
  }
};

}  // namespace gs::simd::kernels
