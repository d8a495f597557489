// SPDX-License-Identifier: MIT
// Reference spherical-harmonics colour evaluation (real SH up to degree 3, 3DGS constants and
// sign convention) and its backward through the view direction.
#include <algorithm>
#include <cmath>

#include "gs/simd/ref.h"

namespace gs::simd {
namespace {

constexpr double kC0 = 0.28209479177387814;
constexpr double kC1 = 0.4886025119029199;
constexpr double kC2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
                           0.5462742152960396};
constexpr double kC3[7] = {-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                           -0.4570457994644658, 1.445305721320277, -0.5900435899266435};

// Basis values b[k] and, if db is not null, their gradient w.r.t. the unit direction db[k][3].
template <class T>
void sh_basis(int degree, T x, T y, T z, T b[16], T db[16][3]) {
  const T C0 = T(kC0), C1 = T(kC1);
  b[0] = C0;
  if (db) db[0][0] = db[0][1] = db[0][2] = 0;
  if (degree < 1) return;
  b[1] = -C1 * y; b[2] = C1 * z; b[3] = -C1 * x;
  if (db) {
    db[1][0] = 0; db[1][1] = -C1; db[1][2] = 0;
    db[2][0] = 0; db[2][1] = 0;   db[2][2] = C1;
    db[3][0] = -C1; db[3][1] = 0; db[3][2] = 0;
  }
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  const T c20 = T(kC2[0]), c21 = T(kC2[1]), c22 = T(kC2[2]), c23 = T(kC2[3]), c24 = T(kC2[4]);
  b[4] = c20 * x * y; b[5] = c21 * y * z; b[6] = c22 * (2 * zz - xx - yy); b[7] = c23 * x * z; b[8] = c24 * (xx - yy);
  if (db) {
    db[4][0] = c20 * y; db[4][1] = c20 * x; db[4][2] = 0;
    db[5][0] = 0; db[5][1] = c21 * z; db[5][2] = c21 * y;
    db[6][0] = -2 * c22 * x; db[6][1] = -2 * c22 * y; db[6][2] = 4 * c22 * z;
    db[7][0] = c23 * z; db[7][1] = 0; db[7][2] = c23 * x;
    db[8][0] = 2 * c24 * x; db[8][1] = -2 * c24 * y; db[8][2] = 0;
  }
  if (degree < 3) return;
  const T c0 = T(kC3[0]), c1 = T(kC3[1]), c2 = T(kC3[2]), c3 = T(kC3[3]), c4 = T(kC3[4]), c5 = T(kC3[5]),
          c6 = T(kC3[6]);
  b[9] = c0 * y * (3 * xx - yy);
  b[10] = c1 * x * y * z;
  b[11] = c2 * y * (4 * zz - xx - yy);
  b[12] = c3 * z * (2 * zz - 3 * xx - 3 * yy);
  b[13] = c4 * x * (4 * zz - xx - yy);
  b[14] = c5 * z * (xx - yy);
  b[15] = c6 * x * (xx - 3 * yy);
  if (db) {
    db[9][0] = 6 * c0 * x * y; db[9][1] = c0 * (3 * xx - 3 * yy); db[9][2] = 0;
    db[10][0] = c1 * y * z; db[10][1] = c1 * x * z; db[10][2] = c1 * x * y;
    db[11][0] = -2 * c2 * x * y; db[11][1] = c2 * (4 * zz - xx - 3 * yy); db[11][2] = 8 * c2 * y * z;
    db[12][0] = -6 * c3 * x * z; db[12][1] = -6 * c3 * y * z; db[12][2] = c3 * (6 * zz - 3 * xx - 3 * yy);
    db[13][0] = c4 * (4 * zz - 3 * xx - yy); db[13][1] = -2 * c4 * x * y; db[13][2] = 8 * c4 * x * z;
    db[14][0] = 2 * c5 * x * z; db[14][1] = -2 * c5 * y * z; db[14][2] = c5 * (xx - yy);
    db[15][0] = c6 * (3 * xx - 3 * yy); db[15][1] = -6 * c6 * x * y; db[15][2] = 0;
  }
}

// Unit view direction from the camera centre to the mean; norm is guarded against a Gaussian sitting
// exactly on the camera centre.
template <class T>
T view_dir(const T* mean, const T* campos, T dir[3]) {
  T d[3] = {mean[0] - campos[0], mean[1] - campos[1], mean[2] - campos[2]};
  const T norm = std::max(std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), T(1e-12));
  for (int k = 0; k < 3; ++k) dir[k] = d[k] / norm;
  return norm;
}

}  // namespace

template <class T>
void sh_basis_ref(int32_t degree, const T dir[3], T b[16]) {
  sh_basis<T>(degree, dir[0], dir[1], dir[2], b, nullptr);
}

template <class T>
void sh_fwd_ref(size_t n, int32_t degree, const T* means, const T* sh, const T* campos, T* colors) {
  const int K = (degree + 1) * (degree + 1);
  for (size_t i = 0; i < n; ++i) {
    T dir[3], b[16];
    view_dir(means + 3 * i, campos, dir);
    sh_basis<T>(degree, dir[0], dir[1], dir[2], b, nullptr);
    for (int c = 0; c < 3; ++c) {
      T v = 0;
      for (int k = 0; k < K; ++k) v += b[k] * sh[(i * K + k) * 3 + c];
      colors[3 * i + c] = std::max(v + T(0.5), T(0));
    }
  }
}

template <class T>
void sh_bwd_ref(size_t n, int32_t degree, const T* means, const T* sh, const T* campos, const T* v_colors, T* v_sh,
                T* v_means, T* v_campos) {
  const int K = (degree + 1) * (degree + 1);
  for (size_t i = 0; i < n; ++i) {
    T dir[3], b[16], db[16][3];
    const T norm = view_dir(means + 3 * i, campos, dir);
    sh_basis<T>(degree, dir[0], dir[1], dir[2], b, db);
    T v_dir[3] = {0, 0, 0};
    for (int c = 0; c < 3; ++c) {
      T v = 0;
      for (int k = 0; k < K; ++k) v += b[k] * sh[(i * K + k) * 3 + c];
      const T g = (v + T(0.5) < T(0)) ? T(0) : v_colors[3 * i + c];  // clamped channel: no gradient
      for (int k = 0; k < K; ++k) {
        v_sh[(i * K + k) * 3 + c] = b[k] * g;
        for (int a = 0; a < 3; ++a) v_dir[a] += g * sh[(i * K + k) * 3 + c] * db[k][a];
      }
    }
    // dir = d / |d|: v_d = (v_dir - dir (dir . v_dir)) / |d|
    const T dot = dir[0] * v_dir[0] + dir[1] * v_dir[1] + dir[2] * v_dir[2];
    for (int a = 0; a < 3; ++a) {
      const T v_d = (v_dir[a] - dir[a] * dot) / norm;
      v_means[3 * i + a] += v_d;
      v_campos[a] -= v_d;
    }
  }
}

template void sh_basis_ref<float>(int32_t, const float*, float*);
template void sh_basis_ref<double>(int32_t, const double*, double*);
template void sh_fwd_ref<float>(size_t, int32_t, const float*, const float*, const float*, float*);
template void sh_fwd_ref<double>(size_t, int32_t, const double*, const double*, const double*, double*);
template void sh_bwd_ref<float>(size_t, int32_t, const float*, const float*, const float*, const float*, float*,
                                float*, float*);
template void sh_bwd_ref<double>(size_t, int32_t, const double*, const double*, const double*, const double*, double*,
                                 double*, double*);

}  // namespace gs::simd
