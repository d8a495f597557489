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

#include "gs/simd/isa.h"

#include "gs/simd/quat.h"
#include "gs/simd/ref.h"
#include "gs/simd/splat.h"

namespace gs::simd {
inline namespace GS_SIMD_ISA_NS {  // compiled per ISA: see gs/simd/isa.h
namespace kernels {

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
    size_t i = 0;
    for (; i + N <= n; i += N)
      bwd_block(p, i, means, log_scales, quats, radii, v_means2d, v_conics, v_depths, v_means, v_log_scales, v_quats,
                v_pose);
    if (i < n)
      project_bwd_ref<float>(p, n - i, means + 3 * i, log_scales + 3 * i, quats + 4 * i, radii + i, v_means2d + 2 * i,
                             v_conics + 3 * i, v_depths ? v_depths + i : nullptr, v_means + 3 * i,
                             v_log_scales + 3 * i, v_quats + 4 * i, v_pose);
  }

 private:
  static void bwd_block(const ProjectParams* p, size_t i0, const float* means, const float* log_scales,
                        const float* quats, const int32_t* radii, const float* v_means2d, const float* v_conics,
                        const float* v_depths, float* v_means, float* v_log_scales, float* v_quats, double* v_pose) {
    alignas(64) float mu[3][N], ls[3][N], q[4][N], vm2[2][N], vc[3][N], vd[N], ok[N];
    for (int l = 0; l < N; ++l) {
      const size_t i = i0 + l;
      for (int k = 0; k < 3; ++k) mu[k][l] = means[3 * i + k];
      for (int k = 0; k < 3; ++k) ls[k][l] = log_scales[3 * i + k];
      for (int k = 0; k < 4; ++k) q[k][l] = quats[4 * i + k];
      ok[l] = radii[i] > 0 ? 1.0f : 0.0f;
      // Culled lanes get zero cotangents so their (finite, masked) arithmetic adds nothing.
      for (int k = 0; k < 2; ++k) vm2[k][l] = radii[i] > 0 ? v_means2d[2 * i + k] : 0.0f;
      for (int k = 0; k < 3; ++k) vc[k][l] = radii[i] > 0 ? v_conics[3 * i + k] : 0.0f;
      vd[l] = (radii[i] > 0 && v_depths) ? v_depths[i] : 0.0f;
    }
    const M valid = B::load_aligned(ok) != B(0.0f);
    // Forward recomputation (as project_one in the reference).
    const B qw = B::load_aligned(q[0]), qx = B::load_aligned(q[1]), qy = B::load_aligned(q[2]), qz = B::load_aligned(q[3]);
    const B inv_norm = B(1.0f) / xsimd::max(xsimd::sqrt(qw * qw + qx * qx + qy * qy + qz * qz), B(1e-12f));
    const B w = qw * inv_norm, x = qx * inv_norm, y = qy * inv_norm, z = qz * inv_norm;
    B Rg[9];
    rotmat_of_unit_quat(w, x, y, z, Rg);
    const B s[3] = {xsimd::exp(B::load_aligned(ls[0])), xsimd::exp(B::load_aligned(ls[1])),
                    xsimd::exp(B::load_aligned(ls[2]))};
    B Mg[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Mg[r * 3 + c] = Rg[r * 3 + c] * s[c];
    const float* R = p->R;
    const B wx = B::load_aligned(mu[0]), wy = B::load_aligned(mu[1]), wz = B::load_aligned(mu[2]);
    const B m0 = B(R[0]) * wx + B(R[1]) * wy + B(R[2]) * wz + B(p->t[0]);
    const B m1 = B(R[3]) * wx + B(R[4]) * wy + B(R[5]) * wz + B(p->t[1]);
    const B m2 = xsimd::select(valid, B(R[6]) * wx + B(R[7]) * wy + B(R[8]) * wz + B(p->t[2]), B(1.0f));
    B A[9];  // R M
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) A[r * 3 + c] = B(R[r * 3]) * Mg[c] + B(R[r * 3 + 1]) * Mg[3 + c] + B(R[r * 3 + 2]) * Mg[6 + c];
    B S[9];  // A A^T, camera covariance
    for (int r = 0; r < 3; ++r)
      for (int c = r; c < 3; ++c)
        S[r * 3 + c] = S[c * 3 + r] = A[r * 3] * A[c * 3] + A[r * 3 + 1] * A[c * 3 + 1] + A[r * 3 + 2] * A[c * 3 + 2];
    const B xz = m0 / m2, yz = m1 / m2;
    const M clamp_x = (xz < B(-p->lim_x_neg)) | (xz > B(p->lim_x_pos));
    const M clamp_y = (yz < B(-p->lim_y_neg)) | (yz > B(p->lim_y_pos));
    const B cxz = xsimd::min(B(p->lim_x_pos), xsimd::max(B(-p->lim_x_neg), xz));
    const B cyz = xsimd::min(B(p->lim_y_pos), xsimd::max(B(-p->lim_y_neg), yz));
    const B tx = m2 * cxz, ty = m2 * cyz;
    const B z2 = m2 * m2, z3 = z2 * m2;
    const B fx(p->fx), fy(p->fy);
    const B j00 = fx / m2, j02 = -fx * tx / z2, j11 = fy / m2, j12 = -fy * ty / z2;
    const B js00 = j00 * S[0] + j02 * S[6], js01 = j00 * S[1] + j02 * S[7], js02 = j00 * S[2] + j02 * S[8];
    const B js11 = j11 * S[4] + j12 * S[7], js12 = j11 * S[5] + j12 * S[8];
    const B ca = js00 * j00 + js02 * j02 + B(kDilation);
    const B cb = js01 * j11 + js02 * j12;
    const B cc = js11 * j11 + js12 * j12 + B(kDilation);
    const B det = xsimd::select(valid, ca * cc - cb * cb, B(1.0f));
    // Backward.
    const B vu = B::load_aligned(vm2[0]), vv = B::load_aligned(vm2[1]);
    B v_m0 = vu * fx / m2, v_m1 = vv * fy / m2;
    B v_m2 = -vu * fx * m0 / z2 - vv * fy * m1 / z2 + B::load_aligned(vd);
    const B inv_det = B(1.0f) / det;
    const B Q00 = cc * inv_det, Q01 = -cb * inv_det, Q11 = ca * inv_det;
    const B g00 = B::load_aligned(vc[0]), g01 = B(0.5f) * B::load_aligned(vc[1]), g11 = B::load_aligned(vc[2]);
    const B qg00 = Q00 * g00 + Q01 * g01, qg01 = Q00 * g01 + Q01 * g11;
    const B qg10 = Q01 * g00 + Q11 * g01, qg11 = Q01 * g01 + Q11 * g11;
    const B V00 = -(qg00 * Q00 + qg01 * Q01), V01 = -(qg00 * Q01 + qg01 * Q11), V11 = -(qg10 * Q01 + qg11 * Q11);
    // V2 J (2x3) with J = [[j00, 0, j02], [0, j11, j12]]
    const B a00 = V00 * j00, a01 = V01 * j11, a02 = V00 * j02 + V01 * j12;
    const B a10 = V01 * j00, a11 = V11 * j11, a12 = V01 * j02 + V11 * j12;
    B vS[9];  // J^T (V2 J), symmetric
    vS[0] = j00 * a00; vS[1] = j00 * a01; vS[2] = j00 * a02;
    vS[4] = j11 * a11; vS[5] = j11 * a12;
    vS[8] = j02 * a02 + j12 * a12;
    vS[3] = vS[1]; vS[6] = vS[2]; vS[7] = vS[5];
    // v_J = 2 (V2 J) S, only the entries that depend on m.
    const B vJ00 = B(2.0f) * (a00 * S[0] + a01 * S[3] + a02 * S[6]);
    const B vJ02 = B(2.0f) * (a00 * S[2] + a01 * S[5] + a02 * S[8]);
    const B vJ11 = B(2.0f) * (a10 * S[1] + a11 * S[4] + a12 * S[7]);
    const B vJ12 = B(2.0f) * (a10 * S[2] + a11 * S[5] + a12 * S[8]);
    const B dtx_dx = xsimd::select(clamp_x, B(0.0f), B(1.0f)), dty_dy = xsimd::select(clamp_y, B(0.0f), B(1.0f));
    const B dtx_dz = xsimd::select(clamp_x, cxz, B(0.0f)), dty_dz = xsimd::select(clamp_y, cyz, B(0.0f));
    v_m0 += vJ02 * (-fx / z2) * dtx_dx;
    v_m1 += vJ12 * (-fy / z2) * dty_dy;
    v_m2 += vJ00 * (-fx / z2) + vJ11 * (-fy / z2) + vJ02 * (-fx * dtx_dz / z2 + B(2.0f) * fx * tx / z3) +
            vJ12 * (-fy * dty_dz / z2 + B(2.0f) * fy * ty / z3);
    // v_Sigma = R^T vS R, v_M = 2 v_Sigma M.
    B tmp[9], vSig[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) tmp[r * 3 + c] = vS[r * 3] * B(R[c]) + vS[r * 3 + 1] * B(R[3 + c]) + vS[r * 3 + 2] * B(R[6 + c]);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) vSig[r * 3 + c] = B(R[r]) * tmp[c] + B(R[3 + r]) * tmp[3 + c] + B(R[6 + r]) * tmp[6 + c];
    B vRg[9], vls[3] = {B(0.0f), B(0.0f), B(0.0f)};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        const B vM = B(2.0f) * (vSig[r * 3] * Mg[c] + vSig[r * 3 + 1] * Mg[3 + c] + vSig[r * 3 + 2] * Mg[6 + c]);
        vRg[r * 3 + c] = vM * s[c];
        vls[c] += vM * Rg[r * 3 + c] * s[c];
      }
    const B* G = vRg;
    const B two(2.0f);
    const B gw = two * (-z * G[1] + y * G[2] + z * G[3] - x * G[5] - y * G[6] + x * G[7]);
    const B gx = two * (y * G[1] + z * G[2] + y * G[3] - two * x * G[4] - w * G[5] + z * G[6] + w * G[7] - two * x * G[8]);
    const B gy = two * (-two * y * G[0] + x * G[1] + w * G[2] + x * G[3] + z * G[5] - w * G[6] + z * G[7] - two * y * G[8]);
    const B gz = two * (-two * z * G[0] - w * G[1] + x * G[2] + w * G[3] - two * z * G[4] + y * G[5] + x * G[6] + y * G[7]);
    const B dot = w * gw + x * gx + y * gy + z * gz;
    const B zero(0.0f);
    alignas(64) float o[13][N];
    xsimd::select(valid, (gw - w * dot) * inv_norm, zero).store_aligned(o[0]);
    xsimd::select(valid, (gx - x * dot) * inv_norm, zero).store_aligned(o[1]);
    xsimd::select(valid, (gy - y * dot) * inv_norm, zero).store_aligned(o[2]);
    xsimd::select(valid, (gz - z * dot) * inv_norm, zero).store_aligned(o[3]);
    for (int c = 0; c < 3; ++c) xsimd::select(valid, vls[c], zero).store_aligned(o[4 + c]);
    for (int k = 0; k < 3; ++k)
      xsimd::select(valid, B(R[k]) * v_m0 + B(R[3 + k]) * v_m1 + B(R[6 + k]) * v_m2, zero).store_aligned(o[7 + k]);
    // Pose: rho += v_m; phi += m x v_m + 2 (A12, A20, A01), A = S G - G S with G = vS.
    auto sg = [&](int r, int c) { return S[r * 3] * vS[c] + S[r * 3 + 1] * vS[3 + c] + S[r * 3 + 2] * vS[6 + c]; };
    auto gs_ = [&](int r, int c) { return vS[r * 3] * S[c] + vS[r * 3 + 1] * S[3 + c] + vS[r * 3 + 2] * S[6 + c]; };
    const B phi0 = m1 * v_m2 - m2 * v_m1 + two * (sg(1, 2) - gs_(1, 2));
    const B phi1 = m2 * v_m0 - m0 * v_m2 + two * (sg(2, 0) - gs_(2, 0));
    const B phi2 = m0 * v_m1 - m1 * v_m0 + two * (sg(0, 1) - gs_(0, 1));
    alignas(64) float pose[6][N];
    xsimd::select(valid, v_m0, zero).store_aligned(pose[0]);
    xsimd::select(valid, v_m1, zero).store_aligned(pose[1]);
    xsimd::select(valid, v_m2, zero).store_aligned(pose[2]);
    xsimd::select(valid, phi0, zero).store_aligned(pose[3]);
    xsimd::select(valid, phi1, zero).store_aligned(pose[4]);
    xsimd::select(valid, phi2, zero).store_aligned(pose[5]);
    for (int l = 0; l < N; ++l) {
      const size_t i = i0 + l;
      for (int k = 0; k < 4; ++k) v_quats[4 * i + k] = o[k][l];
      for (int k = 0; k < 3; ++k) v_log_scales[3 * i + k] = o[4 + k][l];
      for (int k = 0; k < 3; ++k) v_means[3 * i + k] = o[7 + k][l];
      for (int k = 0; k < 6; ++k) v_pose[k] += double(pose[k][l]);
    }
  }

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
    B Rg[9];
    rotmat_of_unit_quat(w, x, y, z, Rg);
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

}  // namespace kernels
}  // inline namespace GS_SIMD_ISA_NS
}  // namespace gs::simd
