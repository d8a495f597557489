// SPDX-License-Identifier: MIT
// Reference projection of 3D Gaussians to 2D splats (EWA splatting, Zwicker et al. 2002, as used
// by 3DGS) and its hand-written backward, including the camera-pose twist gradient
// (ALGORITHM.md Part A item 14). Matrices are row-major T[9]; T is float or double.
#include <algorithm>
#include <cmath>

#include "gs/simd/quat.h"
#include "gs/simd/ref.h"

namespace gs::simd {
namespace {

template <class T>
void quat_to_rotmat(const T* q_raw, T qn[4], T R[9], T* inv_norm) {
  const T norm = std::sqrt(q_raw[0] * q_raw[0] + q_raw[1] * q_raw[1] + q_raw[2] * q_raw[2] + q_raw[3] * q_raw[3]);
  *inv_norm = T(1) / std::max(norm, T(1e-12));
  for (int k = 0; k < 4; ++k) qn[k] = q_raw[k] * *inv_norm;
  rotmat_of_unit_quat(qn[0], qn[1], qn[2], qn[3], R);
}

// v_q (raw quaternion) from v_R (gradient w.r.t. the rotation matrix of the normalised quaternion).
template <class T>
void rotmat_vjp(const T qn[4], T inv_norm, const T G[9], T v_q[4]) {
  const T w = qn[0], x = qn[1], y = qn[2], z = qn[3];
  T g[4];
  g[0] = 2 * (-z * G[1] + y * G[2] + z * G[3] - x * G[5] - y * G[6] + x * G[7]);
  g[1] = 2 * (y * G[1] + z * G[2] + y * G[3] - 2 * x * G[4] - w * G[5] + z * G[6] + w * G[7] - 2 * x * G[8]);
  g[2] = 2 * (-2 * y * G[0] + x * G[1] + w * G[2] + x * G[3] + z * G[5] - w * G[6] + z * G[7] - 2 * y * G[8]);
  g[3] = 2 * (-2 * z * G[0] - w * G[1] + x * G[2] + w * G[3] - 2 * z * G[4] + y * G[5] + x * G[6] + y * G[7]);
  // Normalisation Jacobian: d(q/|q|)/dq = (I - qn qn^T) / |q|.
  const T dot = qn[0] * g[0] + qn[1] * g[1] + qn[2] * g[2] + qn[3] * g[3];
  for (int k = 0; k < 4; ++k) v_q[k] = (g[k] - qn[k] * dot) * inv_norm;
}

template <class T> void matmul3(const T* A, const T* B, T* C) {  // C = A B
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}
template <class T> void matmul3_bt(const T* A, const T* B, T* C) {  // C = A B^T
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i * 3] * B[j * 3] + A[i * 3 + 1] * B[j * 3 + 1] + A[i * 3 + 2] * B[j * 3 + 2];
}
template <class T> void matmul3_at(const T* A, const T* B, T* C) {  // C = A^T B
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i] * B[j] + A[3 + i] * B[3 + j] + A[6 + i] * B[6 + j];
}

// Everything the forward computes for one Gaussian, kept for the backward.
template <class T>
struct Projection {
  T qn[4], inv_qnorm, Rg[9], s[3], M[9];  // M = Rg diag(s), world covariance = M M^T
  T m[3];                                 // camera-space mean
  T cov_cam[9];                           // R M M^T R^T
  T J[6];                                 // 2x3 EWA Jacobian (with the tan clamp)
  bool clamp_x, clamp_y;
  T a, b, c, det;                         // dilated 2D covariance [[a, b], [b, c]]
  bool valid;
};

template <class T>
Projection<T> project_one(const ProjectParamsT<T>* p, const T* mean, const T* log_scale, const T* quat) {
  Projection<T> pr{};
  quat_to_rotmat(quat, pr.qn, pr.Rg, &pr.inv_qnorm);
  for (int k = 0; k < 3; ++k) pr.s[k] = std::exp(log_scale[k]);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) pr.M[i * 3 + j] = pr.Rg[i * 3 + j] * pr.s[j];
  const T* R = p->R;
  for (int i = 0; i < 3; ++i) pr.m[i] = R[i * 3] * mean[0] + R[i * 3 + 1] * mean[1] + R[i * 3 + 2] * mean[2] + p->t[i];
  pr.valid = false;
  if (!(pr.m[2] > T(kNearPlane))) return pr;
  T A[9], S[9];
  matmul3(R, pr.M, A);     // A = R M
  matmul3_bt(A, A, S);     // S = A A^T
  std::copy(S, S + 9, pr.cov_cam);
  const T x = pr.m[0], y = pr.m[1], z = pr.m[2];
  const T xz = x / z, yz = y / z;
  pr.clamp_x = xz < -p->lim_x_neg || xz > p->lim_x_pos;
  pr.clamp_y = yz < -p->lim_y_neg || yz > p->lim_y_pos;
  const T tx = z * std::min(p->lim_x_pos, std::max(-p->lim_x_neg, xz));
  const T ty = z * std::min(p->lim_y_pos, std::max(-p->lim_y_neg, yz));
  pr.J[0] = p->fx / z; pr.J[1] = 0; pr.J[2] = -p->fx * tx / (z * z);
  pr.J[3] = 0; pr.J[4] = p->fy / z; pr.J[5] = -p->fy * ty / (z * z);
  // cov2 = J S J^T
  T JS[6];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) JS[i * 3 + j] = pr.J[i * 3] * S[j] + pr.J[i * 3 + 1] * S[3 + j] + pr.J[i * 3 + 2] * S[6 + j];
  const T c00 = JS[0] * pr.J[0] + JS[1] * pr.J[1] + JS[2] * pr.J[2];
  const T c01 = JS[0] * pr.J[3] + JS[1] * pr.J[4] + JS[2] * pr.J[5];
  const T c11 = JS[3] * pr.J[3] + JS[4] * pr.J[4] + JS[5] * pr.J[5];
  pr.a = c00 + T(kDilation);
  pr.b = c01;
  pr.c = c11 + T(kDilation);
  pr.det = pr.a * pr.c - pr.b * pr.b;
  pr.valid = pr.det > T(0);
  return pr;
}

}  // namespace

template <class T>
void project_fwd_ref(const ProjectParamsT<T>* p, size_t n, const T* means, const T* log_scales, const T* quats,
                     T* means2d, T* conics, T* depths, int32_t* radii) {
  for (size_t i = 0; i < n; ++i) {
    radii[i] = 0;
    const Projection<T> pr = project_one(p, means + 3 * i, log_scales + 3 * i, quats + 4 * i);
    if (!pr.valid) continue;
    const T inv_det = T(1) / pr.det;
    conics[3 * i + 0] = pr.c * inv_det;
    conics[3 * i + 1] = -pr.b * inv_det;
    conics[3 * i + 2] = pr.a * inv_det;
    const T mid = T(0.5) * (pr.a + pr.c);
    const T lambda = mid + std::sqrt(std::max(T(kEigenFloor), mid * mid - pr.det));
    means2d[2 * i + 0] = p->fx * pr.m[0] / pr.m[2] + p->cx;
    means2d[2 * i + 1] = p->fy * pr.m[1] / pr.m[2] + p->cy;
    depths[i] = pr.m[2];
    const T r = std::ceil(T(3) * std::sqrt(lambda));
    const int32_t radius = r > T(1 << 24) ? int32_t(1 << 24) : int32_t(r);
    int32_t rect[4];
    if (tile_rect(p, means2d + 2 * i, radius, rect) == 0) continue;
    radii[i] = radius;
  }
}

template <class T>
void project_bwd_ref(const ProjectParamsT<T>* p, size_t n, const T* means, const T* log_scales, const T* quats,
                     const int32_t* radii, const T* v_means2d, const T* v_conics, const T* v_depths, T* v_means,
                     T* v_log_scales, T* v_quats, double* v_pose) {
  const T* R = p->R;
  for (size_t i = 0; i < n; ++i) {
    std::fill(v_means + 3 * i, v_means + 3 * i + 3, T(0));
    std::fill(v_log_scales + 3 * i, v_log_scales + 3 * i + 3, T(0));
    std::fill(v_quats + 4 * i, v_quats + 4 * i + 4, T(0));
    if (radii[i] == 0) continue;
    const Projection<T> pr = project_one(p, means + 3 * i, log_scales + 3 * i, quats + 4 * i);
    const T x = pr.m[0], y = pr.m[1], z = pr.m[2];
    T v_m[3] = {0, 0, 0};
    // mean2d = (fx x/z + cx, fy y/z + cy)
    const T vu = v_means2d[2 * i], vv = v_means2d[2 * i + 1];
    v_m[0] += vu * p->fx / z;
    v_m[1] += vv * p->fy / z;
    v_m[2] += -vu * p->fx * x / (z * z) - vv * p->fy * y / (z * z);
    if (v_depths) v_m[2] += v_depths[i];
    // conic = inverse(cov2); the quadratic form uses the symmetric matrix Q = [[a', b'], [b', c']],
    // so the full-matrix gradient is Gq = [[va, vb/2], [vb/2, vc]] and dL/dCov2 = -Q Gq Q.
    const T inv_det = T(1) / pr.det;
    const T Q[4] = {pr.c * inv_det, -pr.b * inv_det, -pr.b * inv_det, pr.a * inv_det};
    const T Gq[4] = {v_conics[3 * i], T(0.5) * v_conics[3 * i + 1], T(0.5) * v_conics[3 * i + 1], v_conics[3 * i + 2]};
    T QG[4], V2[4];
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c) QG[r * 2 + c] = Q[r * 2] * Gq[c] + Q[r * 2 + 1] * Gq[2 + c];
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c) V2[r * 2 + c] = -(QG[r * 2] * Q[c] + QG[r * 2 + 1] * Q[2 + c]);
    // cov2 = J S J^T (+ dilation): dL/dS = J^T V2 J, dL/dJ = 2 V2 J S (V2, S symmetric).
    const T* J = pr.J;
    const T* S = pr.cov_cam;
    T V2J[6];
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 3; ++c) V2J[r * 3 + c] = V2[r * 2] * J[c] + V2[r * 2 + 1] * J[3 + c];
    T v_S[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) v_S[r * 3 + c] = J[r] * V2J[c] + J[3 + r] * V2J[3 + c];
    T v_J[6];
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 3; ++c)
        v_J[r * 3 + c] = 2 * (V2J[r * 3] * S[c] + V2J[r * 3 + 1] * S[3 + c] + V2J[r * 3 + 2] * S[6 + c]);
    // J = [[fx/z, 0, -fx tx/z^2], [0, fy/z, -fy ty/z^2]], tx = z clamp(x/z): dtx/dx = !clamped,
    // dtx/dz = clamp(x/z) - (x/z) [!clamped] (= 0 unclamped, = the limit when clamped).
    const T z2 = z * z, z3 = z2 * z;
    const T cxz = std::min(p->lim_x_pos, std::max(-p->lim_x_neg, x / z));
    const T cyz = std::min(p->lim_y_pos, std::max(-p->lim_y_neg, y / z));
    const T tx = z * cxz, ty = z * cyz;
    const T dtx_dx = pr.clamp_x ? T(0) : T(1), dty_dy = pr.clamp_y ? T(0) : T(1);
    const T dtx_dz = pr.clamp_x ? cxz : T(0), dty_dz = pr.clamp_y ? cyz : T(0);
    v_m[0] += v_J[2] * (-p->fx / z2) * dtx_dx;
    v_m[1] += v_J[5] * (-p->fy / z2) * dty_dy;
    v_m[2] += v_J[0] * (-p->fx / z2) + v_J[4] * (-p->fy / z2) +
              v_J[2] * (-p->fx * dtx_dz / z2 + 2 * p->fx * tx / z3) +
              v_J[5] * (-p->fy * dty_dz / z2 + 2 * p->fy * ty / z3);
    // S = R Sigma R^T, Sigma = M M^T, M = Rg diag(s).
    T tmp[9], v_Sigma[9];
    matmul3(v_S, R, tmp);          // v_S R
    matmul3_at(R, tmp, v_Sigma);   // R^T v_S R
    T v_M[9];
    matmul3(v_Sigma, pr.M, v_M);   // v_Sigma M, symmetric v_Sigma: dL/dM = 2 v_Sigma M
    for (int k = 0; k < 9; ++k) v_M[k] *= 2;
    T v_Rg[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        v_Rg[r * 3 + c] = v_M[r * 3 + c] * pr.s[c];
        v_log_scales[3 * i + c] += v_M[r * 3 + c] * pr.Rg[r * 3 + c] * pr.s[c];  // ds/dlog s = s
      }
    rotmat_vjp(pr.qn, pr.inv_qnorm, v_Rg, v_quats + 4 * i);
    // m = R mu + t
    for (int k = 0; k < 3; ++k) v_means[3 * i + k] = R[k] * v_m[0] + R[3 + k] * v_m[1] + R[6 + k] * v_m[2];
    // Pose twist (left perturbation): m' = m + rho + phi x m; S' = S + [phi]x S - S [phi]x.
    const T* m = pr.m;
    T A[9];  // A = S G - G S with G = v_S
    T SG[9], GS[9];
    matmul3(S, v_S, SG);
    matmul3(v_S, S, GS);
    for (int k = 0; k < 9; ++k) A[k] = SG[k] - GS[k];
    v_pose[0] += double(v_m[0]);
    v_pose[1] += double(v_m[1]);
    v_pose[2] += double(v_m[2]);
    v_pose[3] += double(m[1] * v_m[2] - m[2] * v_m[1] + 2 * A[5]);
    v_pose[4] += double(m[2] * v_m[0] - m[0] * v_m[2] + 2 * A[6]);
    v_pose[5] += double(m[0] * v_m[1] - m[1] * v_m[0] + 2 * A[1]);
  }
}

template <class T>
void project_pose_tangents_ref(const ProjectParamsT<T>* p, size_t n, const T* means, const T* log_scales,
                               const T* quats, const int32_t* radii, T* d_means2d, T* d_conics) {
  for (size_t i = 0; i < n; ++i) {
    T* dmu = d_means2d + 12 * i;  // [2, 6]
    T* dq = d_conics + 18 * i;    // [3, 6]
    std::fill(dmu, dmu + 12, T(0));
    std::fill(dq, dq + 18, T(0));
    if (radii[i] == 0) continue;
    const Projection<T> pr = project_one(p, means + 3 * i, log_scales + 3 * i, quats + 4 * i);
    if (!pr.valid) continue;
    const T x = pr.m[0], y = pr.m[1], z = pr.m[2];
    const T z2 = z * z, z3 = z2 * z;
    const T* J = pr.J;
    const T* S = pr.cov_cam;
    // Forward quantities of the clamped Jacobian (as in project_bwd_ref).
    const T cxz = std::min(p->lim_x_pos, std::max(-p->lim_x_neg, x / z));
    const T cyz = std::min(p->lim_y_pos, std::max(-p->lim_y_neg, y / z));
    const T tx = z * cxz, ty = z * cyz;
    T JS[6];  // J S
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 3; ++c) JS[r * 3 + c] = J[r * 3] * S[c] + J[r * 3 + 1] * S[3 + c] + J[r * 3 + 2] * S[6 + c];
    // Q = conic as a symmetric matrix [[q0, q1], [q1, q2]].
    const T inv_det = T(1) / pr.det;
    const T q0 = pr.c * inv_det, q1 = -pr.b * inv_det, q2 = pr.a * inv_det;
    for (int k = 0; k < 6; ++k) {
      T dm[3] = {0, 0, 0}, dS[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
      if (k < 3) {
        dm[k] = T(1);  // rho: the camera-space mean translates, the covariance does not change
      } else {
        T e[3] = {0, 0, 0};
        e[k - 3] = T(1);
        const T* m = pr.m;
        dm[0] = e[1] * m[2] - e[2] * m[1];  // phi x m
        dm[1] = e[2] * m[0] - e[0] * m[2];
        dm[2] = e[0] * m[1] - e[1] * m[0];
        const T K[9] = {0, -e[2], e[1], e[2], 0, -e[0], -e[1], e[0], 0};  // [phi]x
        T KS[9], SK[9];
        matmul3(K, S, KS);
        matmul3(S, K, SK);
        for (int q = 0; q < 9; ++q) dS[q] = KS[q] - SK[q];
      }
      // mean2d = (fx x/z + cx, fy y/z + cy)
      dmu[0 * 6 + k] = p->fx * (dm[0] / z - x * dm[2] / z2);
      dmu[1 * 6 + k] = p->fy * (dm[1] / z - y * dm[2] / z2);
      // J = [[fx/z, 0, -fx tx/z^2], [0, fy/z, -fy ty/z^2]], tx = z clamp(x/z): dtx = dx unclamped,
      // dtx = clamp(x/z) dz (the limit times dz) when clamped; likewise ty.
      const T dtx = pr.clamp_x ? cxz * dm[2] : dm[0];
      const T dty = pr.clamp_y ? cyz * dm[2] : dm[1];
      const T dJ[6] = {-p->fx * dm[2] / z2, T(0), -p->fx * (dtx / z2 - 2 * tx * dm[2] / z3),
                       T(0), -p->fy * dm[2] / z2, -p->fy * (dty / z2 - 2 * ty * dm[2] / z3)};
      // cov2 = J S J^T + 0.3 I: dCov = dJ S J^T + J S dJ^T + J dS J^T.
      T dJS[6], JdS[6];
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 3; ++c) {
          dJS[r * 3 + c] = dJ[r * 3] * S[c] + dJ[r * 3 + 1] * S[3 + c] + dJ[r * 3 + 2] * S[6 + c];
          JdS[r * 3 + c] = J[r * 3] * dS[c] + J[r * 3 + 1] * dS[3 + c] + J[r * 3 + 2] * dS[6 + c];
        }
      T dC[4];
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) {
          T acc = 0;
          for (int j = 0; j < 3; ++j)
            acc += dJS[r * 3 + j] * J[c * 3 + j] + JS[r * 3 + j] * dJ[c * 3 + j] + JdS[r * 3 + j] * J[c * 3 + j];
          dC[r * 2 + c] = acc;
        }
      // conic = Cov^-1: dQ = -Q dCov Q.
      const T da = dC[0], db = T(0.5) * (dC[1] + dC[2]), dc = dC[3];
      const T QD[4] = {q0 * da + q1 * db, q0 * db + q1 * dc, q1 * da + q2 * db, q1 * db + q2 * dc};
      dq[0 * 6 + k] = -(QD[0] * q0 + QD[1] * q1);
      dq[1 * 6 + k] = -(QD[0] * q1 + QD[1] * q2);
      dq[2 * 6 + k] = -(QD[2] * q1 + QD[3] * q2);
    }
  }
}

template void project_fwd_ref<float>(const ProjectParamsT<float>*, size_t, const float*, const float*, const float*,
                                     float*, float*, float*, int32_t*);
template void project_fwd_ref<double>(const ProjectParamsT<double>*, size_t, const double*, const double*,
                                      const double*, double*, double*, double*, int32_t*);
template void project_bwd_ref<float>(const ProjectParamsT<float>*, size_t, const float*, const float*, const float*,
                                     const int32_t*, const float*, const float*, const float*, float*, float*, float*,
                                     double*);
template void project_bwd_ref<double>(const ProjectParamsT<double>*, size_t, const double*, const double*,
                                      const double*, const int32_t*, const double*, const double*, const double*,
                                      double*, double*, double*, double*);

template void project_pose_tangents_ref<float>(const ProjectParamsT<float>*, size_t, const float*, const float*,
                                               const float*, const int32_t*, float*, float*);
template void project_pose_tangents_ref<double>(const ProjectParamsT<double>*, size_t, const double*, const double*,
                                                const double*, const int32_t*, double*, double*);

}  // namespace gs::simd
