// SPDX-License-Identifier: MIT
// Pose utilities (gs/pose/pose.h): se(3) exp/log round trips including tiny and near-pi angles, the
// left-twist convention the renderer's v_pose uses, checked pose input, the seeded pose-noise
// protocols (statistics, exactness, determinism) and Sim(3)-aligned pose errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "gs/constants.h"
#include "gs/pose/pose.h"
#include "gs/simd/quat.h"

namespace {

using gs::kPi;

// Portable seeded normals: mt19937_64's raw output is fixed by the standard; the distributions are not.
struct Rng {
  explicit Rng(uint64_t seed) : g(seed) {}
  double uniform() { return (double(g() >> 11) + 0.5) * 0x1p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  double normal() { return std::sqrt(-2 * std::log(uniform())) * std::cos(2 * kPi * uniform()); }
  void unit(double u[3]) {
    double n = 0;
    do {
      for (int k = 0; k < 3; ++k) u[k] = normal();
      n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    } while (n < 1e-6);
    for (int k = 0; k < 3; ++k) u[k] /= n;
  }
  std::mt19937_64 g;
};

double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

void matmul(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}
void matmul_bt(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i * 3] * B[j * 3] + A[i * 3 + 1] * B[j * 3 + 1] + A[i * 3 + 2] * B[j * 3 + 2];
}
void matmul_at(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i * 3 + j] = A[i] * B[j] + A[3 + i] * B[3 + j] + A[6 + i] * B[6 + j];
}
void matvec(const double A[9], const double x[3], double y[3]) {
  for (int i = 0; i < 3; ++i) y[i] = A[i * 3] * x[0] + A[i * 3 + 1] * x[1] + A[i * 3 + 2] * x[2];
}
void matvec_t(const double A[9], const double x[3], double y[3]) {
  for (int i = 0; i < 3; ++i) y[i] = A[i] * x[0] + A[3 + i] * x[1] + A[6 + i] * x[2];
}
double max_abs_diff(const double* a, const double* b, int n) {
  double m = 0;
  for (int i = 0; i < n; ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

// Independent Rodrigues (closed form only), to check so3_exp at moderate angles.
void rodrigues(const double phi[3], double R[9]) {
  const double th = norm3(phi);
  const double a[3] = {phi[0] / th, phi[1] / th, phi[2] / th};
  const double c = std::cos(th), s = std::sin(th);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[i * 3 + j] = (i == j ? c : 0.0) + (1 - c) * a[i] * a[j];
  R[1] -= s * a[2], R[2] += s * a[1], R[3] += s * a[2], R[5] -= s * a[0], R[6] -= s * a[1], R[7] += s * a[0];
}

void random_phi(Rng& rng, double max_angle, double phi[3]) {
  double u[3];
  rng.unit(u);
  const double th = rng.uniform(0, max_angle);
  for (int k = 0; k < 3; ++k) phi[k] = th * u[k];
}

gs::Pose pose_from(const double R[9], const double C[3]) {
  gs::Pose p;
  double t[3];
  matvec(R, C, t);
  for (int i = 0; i < 9; ++i) p.R[i] = float(R[i]);
  for (int k = 0; k < 3; ++k) p.t[k] = float(-t[k]);
  return p;
}

// A camera at a random centre in a box of half-size `extent` around `at`, random orientation.
gs::Pose random_pose(Rng& rng, double extent, const double at[3]) {
  double phi[3], R[9], C[3];
  random_phi(rng, kPi, phi);
  gs::pose::so3_exp(phi, R);
  for (int k = 0; k < 3; ++k) C[k] = at[k] + rng.uniform(-extent, extent);
  return pose_from(R, C);
}

void pose_d(const gs::Pose& p, double R[9], double t[3]) {
  for (int i = 0; i < 9; ++i) R[i] = p.R[i];
  for (int k = 0; k < 3; ++k) t[k] = p.t[k];
}

// Angle of Ra Rb^T in degrees, unclamped (via so3_log), for exactness checks below BARF's floor.
double angle_deg(const gs::Pose& a, const gs::Pose& b) {
  double Ra[9], Rb[9], t[3], M[9], phi[3];
  pose_d(a, Ra, t);
  pose_d(b, Rb, t);
  matmul_bt(Ra, Rb, M);
  gs::pose::so3_log(M, phi);
  return norm3(phi) * 180 / kPi;
}

double centre_distance(const gs::Pose& a, const gs::Pose& b) {
  double ca[3], cb[3];
  gs::pose::centre(a, ca);
  gs::pose::centre(b, cb);
  const double d[3] = {ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]};
  return norm3(d);
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("so3_exp matches Rodrigues and is exact at tiny angles") {
  Rng rng(11);
  for (int it = 0; it < 200; ++it) {
    double phi[3], R[9], Rr[9];
    random_phi(rng, kPi, phi);
    if (norm3(phi) < 0.05) continue;
    gs::pose::so3_exp(phi, R);
    rodrigues(phi, Rr);
    CHECK(max_abs_diff(R, Rr, 9) < 1e-14);
  }
  // At 1e-9 rad, R = I + [phi]x up to O(theta^2) = 1e-18; the closed form would lose it all.
  const double phi[3] = {1e-9, -2e-9, 0.5e-9};
  double R[9];
  gs::pose::so3_exp(phi, R);
  const double expect[9] = {1, -phi[2], phi[1], phi[2], 1, -phi[0], -phi[1], phi[0], 1};
  CHECK(max_abs_diff(R, expect, 9) < 1e-17);
  // Just above and below the series switch (1e-2) the two branches agree.
  for (double th : {0.99e-2, 1.01e-2}) {
    const double p[3] = {th * 0.6, th * 0.8, 0};
    double Rs[9], Rc[9];
    gs::pose::so3_exp(p, Rs);
    rodrigues(p, Rc);
    CHECK(max_abs_diff(Rs, Rc, 9) < 1e-15);
  }
}

TEST_CASE("rotation_from_quaternion: the axis-angle rotation, any scale or sign, identity for zero") {
  Rng rng(12);
  for (int it = 0; it < 200; ++it) {
    double phi[3], Rr[9];
    random_phi(rng, kPi, phi);
    const double th = norm3(phi);
    if (th < 1e-3) continue;
    rodrigues(phi, Rr);
    // q = (cos(th/2), sin(th/2) axis), then scaled by 2.5 and negated: one rotation.
    const double s = std::sin(0.5 * th) / th;
    const double q[4] = {std::cos(0.5 * th), s * phi[0], s * phi[1], s * phi[2]};
    const double q_scaled[4] = {-2.5 * q[0], -2.5 * q[1], -2.5 * q[2], -2.5 * q[3]};
    double R[9], Rs[9];
    gs::pose::rotation_from_quaternion(q, R);
    gs::pose::rotation_from_quaternion(q_scaled, Rs);
    CHECK(max_abs_diff(R, Rr, 9) < 1e-14);
    CHECK(max_abs_diff(Rs, Rr, 9) < 1e-14);
    // The formula in float (as the projection kernels use it) agrees to float precision.
    float Rf[9];
    gs::simd::rotmat_of_unit_quat(float(q[0]), float(q[1]), float(q[2]), float(q[3]), Rf);
    for (int k = 0; k < 9; ++k) CHECK(std::fabs(double(Rf[k]) - Rr[k]) < 1e-6);
  }
  const double zero[4] = {0, 0, 0, 0}, bad[4] = {1, std::nan(""), 0, 0};
  const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  double R[9];
  gs::pose::rotation_from_quaternion(zero, R);
  CHECK(max_abs_diff(R, identity, 9) == 0);
  gs::pose::rotation_from_quaternion(bad, R);
  CHECK(max_abs_diff(R, identity, 9) == 0);
}

TEST_CASE("so3 log inverts exp for random tiny and near-pi angles") {
  Rng rng(12);
  auto round_trip = [](const double phi[3]) {
    double R[9], back[9], p2[3];
    gs::pose::so3_exp(phi, R);
    gs::pose::so3_log(R, p2);
    gs::pose::so3_exp(p2, back);
    const double th = norm3(phi);
    INFO("theta = " << th);
    CHECK(max_abs_diff(R, back, 9) < 1e-14);
    CHECK(norm3(p2) <= kPi + 1e-15);
    if (th < kPi - 1e-6) {
      CHECK(max_abs_diff(phi, p2, 3) < 1e-12 * std::max(1.0, th));
    } else {  // at pi, phi and -phi are the same rotation
      const double neg[3] = {-phi[0], -phi[1], -phi[2]};
      CHECK(std::min(max_abs_diff(phi, p2, 3), max_abs_diff(neg, p2, 3)) < 1e-7);
    }
  };
  for (int it = 0; it < 500; ++it) {
    double phi[3];
    random_phi(rng, kPi - 1e-6, phi);
    round_trip(phi);
  }
  for (double th : {0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-3, 0.9e-2, 1.1e-2, 2.0, 2.0943, 2.0945, kPi - 1e-3, kPi - 1e-6,
                    kPi - 1e-9, kPi}) {
    for (int it = 0; it < 20; ++it) {
      double u[3];
      rng.unit(u);
      const double phi[3] = {th * u[0], th * u[1], th * u[2]};
      round_trip(phi);
    }
  }
  // Relative accuracy at 1e-9 rad (the vee of R - R^T, not arccos of the trace).
  const double tiny[3] = {3e-10, -4e-10, 12e-10};
  double R[9], p2[3];
  gs::pose::so3_exp(tiny, R);
  gs::pose::so3_log(R, p2);
  CHECK(max_abs_diff(tiny, p2, 3) < 1e-12 * 1.3e-9);
  // A rotation by exactly pi built as 2 a a^T - I (R - R^T = 0, so the axis comes from the symmetric part).
  const double a[3] = {2.0 / 7, -3.0 / 7, 6.0 / 7};
  double Rpi[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Rpi[i * 3 + j] = 2 * a[i] * a[j] - (i == j ? 1 : 0);
  gs::pose::so3_log(Rpi, p2);
  CHECK(std::abs(norm3(p2) - kPi) < 1e-12);
  CHECK(std::abs(std::abs(p2[0] * a[0] + p2[1] * a[1] + p2[2] * a[2]) - kPi) < 1e-12);
}

TEST_CASE("se3 exp and log round trip and V is the integral of Exp") {
  Rng rng(13);
  for (int it = 0; it < 300; ++it) {
    double xi[6], R[9], t[3], back[6];
    const double max_angle = it < 100 ? 1e-8 : it < 200 ? kPi - 1e-4 : 3.0;
    random_phi(rng, max_angle, xi + 3);
    for (int k = 0; k < 3; ++k) xi[k] = rng.uniform(-3, 3);
    gs::pose::se3_exp(xi, R, t);
    gs::pose::se3_log(R, t, back);
    INFO("theta = " << norm3(xi + 3));
    CHECK(max_abs_diff(xi, back, 6) < 1e-9);
  }
  // t = V rho with V = integral_0^1 Exp(s phi) ds (Simpson, 2000 panels: error ~1e-14).
  const double xi[6] = {0.3, -1.2, 0.7, 0.9, -1.6, 0.4};
  double R[9], t[3], Vrho[3] = {0, 0, 0};
  gs::pose::se3_exp(xi, R, t);
  const int m = 2000;
  for (int j = 0; j <= m; ++j) {
    const double s = double(j) / m, w = (j == 0 || j == m) ? 1 : (j % 2 ? 4 : 2);
    const double p[3] = {s * xi[3], s * xi[4], s * xi[5]};
    double E[9], Er[3];
    gs::pose::so3_exp(p, E);
    matvec(E, xi, Er);
    for (int k = 0; k < 3; ++k) Vrho[k] += w * Er[k] / (3.0 * m);
  }
  CHECK(max_abs_diff(t, Vrho, 3) < 1e-12);
}

TEST_CASE("apply_left_twist then left_difference recovers the twist") {
  Rng rng(14);
  const double origin[3] = {0, 0, 0};
  for (int it = 0; it < 200; ++it) {
    const gs::Pose from = random_pose(rng, 2.0, origin);
    double xi[6];
    random_phi(rng, it % 2 ? 0.5 : 1e-4, xi + 3);
    for (int k = 0; k < 3; ++k) xi[k] = rng.uniform(-0.5, 0.5);
    // In double, on the same maths (compose, then difference): 1e-9. The double pose must be
    // orthonormal to double precision (the float one is only to 1e-7), so build it from so3_exp.
    double Rf[9], tf[3], E[9], tE[3], Rt[9], tt[3], Rd[9], td[3], back[6], pf[3];
    random_phi(rng, kPi, pf);
    gs::pose::so3_exp(pf, Rf);
    for (double& v : tf) v = rng.uniform(-3, 3);
    gs::pose::se3_exp(xi, E, tE);
    matmul(E, Rf, Rt);
    matvec(E, tf, tt);
    for (int k = 0; k < 3; ++k) tt[k] += tE[k];
    matmul_bt(Rt, Rf, Rd);
    matvec(Rd, tf, td);
    for (int k = 0; k < 3; ++k) td[k] = tt[k] - td[k];
    gs::pose::se3_log(Rd, td, back);
    CHECK(max_abs_diff(xi, back, 6) < 1e-9);
    // Through the float Pose: limited by storing R and t as float (2^-24 relative, |t| <= ~3.5).
    gs::Pose to = from;
    gs::pose::apply_left_twist(xi, &to);
    gs::pose::left_difference(from, to, back);
    CHECK(max_abs_diff(xi, back, 6) < 2e-6);
    // And the stored pose equals the double composition of the float pose up to float rounding.
    double Rs[9], ts[3];
    pose_d(from, Rf, tf);
    matmul(E, Rf, Rt);
    matvec(E, tf, tt);
    for (int k = 0; k < 3; ++k) tt[k] += tE[k];
    pose_d(to, Rs, ts);
    CHECK(max_abs_diff(Rs, Rt, 9) < 2e-7);
    CHECK(max_abs_diff(ts, tt, 3) < 1e-6);
  }
}

TEST_CASE("apply_left_twist keeps R orthonormal over many small steps") {
  Rng rng(15);
  const double origin[3] = {0, 0, 0};
  gs::Pose p = random_pose(rng, 1.0, origin);
  for (int it = 0; it < 2000; ++it) {
    double xi[6];
    random_phi(rng, 1e-3, xi + 3);
    for (int k = 0; k < 3; ++k) xi[k] = rng.uniform(-1e-3, 1e-3);
    gs::pose::apply_left_twist(xi, &p);
  }
  double R[9], t[3], RRt[9];
  pose_d(p, R, t);
  matmul_bt(R, R, RRt);
  const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  // One float rounding of an orthonormal matrix: each entry of R R^T off by <= ~3 * 2^-24.
  CHECK(max_abs_diff(RRt, I, 9) < 3e-7);
}

TEST_CASE("left twist derivative is rho plus phi cross x_cam") {
  // The renderer's v_pose convention: d/de of x_cam(e) = [Exp(e xi) T] x_world at e = 0.
  Rng rng(16);
  const double origin[3] = {0, 0, 0};
  for (int it = 0; it < 50; ++it) {
    const gs::Pose T = random_pose(rng, 2.0, origin);
    double xi[6], xw[3], R[9], t[3], xc[3];
    for (double& v : xi) v = rng.uniform(-1, 1);
    for (double& v : xw) v = rng.uniform(-3, 3);
    pose_d(T, R, t);
    matvec(R, xw, xc);
    for (int k = 0; k < 3; ++k) xc[k] += t[k];
    const double expect[3] = {xi[0] + xi[4] * xc[2] - xi[5] * xc[1], xi[1] + xi[5] * xc[0] - xi[3] * xc[2],
                              xi[2] + xi[3] * xc[1] - xi[4] * xc[0]};
    // Central difference in double: error O(h^2) ~ 1e-10.
    auto x_of = [&](double e, double out[3]) {
      double ex[6], E[9], tE[3];
      for (int k = 0; k < 6; ++k) ex[k] = e * xi[k];
      gs::pose::se3_exp(ex, E, tE);
      matvec(E, xc, out);
      for (int k = 0; k < 3; ++k) out[k] += tE[k];
    };
    const double h = 1e-5;
    double xp[3], xm[3], d[3];
    x_of(h, xp);
    x_of(-h, xm);
    for (int k = 0; k < 3; ++k) d[k] = (xp[k] - xm[k]) / (2 * h);
    CHECK(max_abs_diff(d, expect, 3) < 1e-8);
    // Through apply_left_twist (float pose): h = 1e-2, truncation O(h^2 |xi|^2 |x|) and rounding 1e-6/h.
    auto x_pose = [&](double e, double out[3]) {
      double ex[6];
      for (int k = 0; k < 6; ++k) ex[k] = e * xi[k];
      gs::Pose P = T;
      gs::pose::apply_left_twist(ex, &P);
      double Rp[9], tp[3];
      pose_d(P, Rp, tp);
      matvec(Rp, xw, out);
      for (int k = 0; k < 3; ++k) out[k] += tp[k];
    };
    const double hp = 1e-2;
    x_pose(hp, xp);
    x_pose(-hp, xm);
    for (int k = 0; k < 3; ++k) d[k] = (xp[k] - xm[k]) / (2 * hp);
    CHECK(max_abs_diff(d, expect, 3) < 2e-3);
  }
}

TEST_CASE("centre and rotation_error_deg") {
  const double phi[3] = {0, 0, 10 * kPi / 180};
  double R[9];
  gs::pose::so3_exp(phi, R);
  const double C[3] = {1, -2, 3};
  const gs::Pose a = pose_from(R, C);
  double c[3];
  gs::pose::centre(a, c);
  CHECK(max_abs_diff(c, C, 3) < 1e-6);
  const gs::Pose b;  // identity
  CHECK(std::abs(gs::pose::rotation_error_deg(a, b) - 10) < 1e-4);
  CHECK(std::abs(gs::pose::rotation_error_deg(b, a) - 10) < 1e-4);
  // Exact near zero (no arccos floor): identical rotations report 0, a 0.001 deg turn 0.001 deg.
  CHECK(gs::pose::rotation_error_deg(a, a) < 1e-6);
  const double tiny[3] = {0, 1e-3 * kPi / 180, 0};
  double Rt[9], Rat[9];
  gs::pose::so3_exp(tiny, Rt);
  matmul(Rt, R, Rat);
  CHECK(std::abs(gs::pose::rotation_error_deg(pose_from(Rat, C), a) - 1e-3) < 2e-5);
}

TEST_CASE("relative_rotation_error_deg ignores a global rotation and sees a relative one") {
  Rng rng(17);
  const double at[3] = {0, 0, 0};
  const gs::Pose ta = random_pose(rng, 2, at), tb = random_pose(rng, 2, at);
  // The estimate is the truth seen from a rotated world frame: x_cam = R (G^T x) + t, so every R
  // becomes R G^T, and R_a R_b^T is unchanged.
  double phi[3], G[9], Ra[9], Rb[9], t[3], RaG[9], RbG[9];
  random_phi(rng, kPi, phi);
  gs::pose::so3_exp(phi, G);
  pose_d(ta, Ra, t);
  pose_d(tb, Rb, t);
  matmul_bt(Ra, G, RaG);
  matmul_bt(Rb, G, RbG);
  const double C[3] = {0, 0, 0};
  const gs::Pose ea = pose_from(RaG, C), eb = pose_from(RbG, C);
  CHECK(gs::pose::rotation_error_deg(ea, ta) > 1.0);  // the absolute error is not zero...
  CHECK(gs::pose::relative_rotation_error_deg(ta, tb, ea, eb) < 1e-4);  // ...the relative one is
  // A 3-degree turn of camera b alone is a 3-degree relative error.
  const double turn[3] = {3 * kPi / 180, 0, 0};
  double T[9], TRbG[9];
  gs::pose::so3_exp(turn, T);
  matmul(T, RbG, TRbG);
  CHECK(std::abs(gs::pose::relative_rotation_error_deg(ta, tb, ea, pose_from(TRbG, C)) - 3.0) < 1e-3);
}

TEST_CASE("pose_from_quaternion_checked accepts unit quaternions and rejects bad ones") {
  gs::Pose p;
  const double t[3] = {1, 2, 3};
  // A rotation of 0.8 rad about (0.6, 0, 0.8): q = (cos 0.4, sin 0.4 axis).
  const double q[4] = {std::cos(0.4), 0.6 * std::sin(0.4), 0, 0.8 * std::sin(0.4)};
  REQUIRE(gs::pose::pose_from_quaternion_checked(q, t, "test", &p).ok());
  const double phi[3] = {0.48, 0, 0.64};
  double R[9], Rp[9], tp[3];
  gs::pose::so3_exp(phi, R);
  pose_d(p, Rp, tp);
  CHECK(max_abs_diff(R, Rp, 9) < 1e-7);
  CHECK(max_abs_diff(t, tp, 3) == 0);
  // Within 1e-3 of unit norm: accepted and normalised.
  const double q2[4] = {q[0] * 1.0009, q[1] * 1.0009, q[2] * 1.0009, q[3] * 1.0009};
  REQUIRE(gs::pose::pose_from_quaternion_checked(q2, t, "test", &p).ok());
  pose_d(p, Rp, tp);
  CHECK(max_abs_diff(R, Rp, 9) < 1e-7);

  const double nan = std::nan(""), inf = HUGE_VAL;
  const double tn[3] = {0, nan, 0};
  gs::Status s = gs::pose::pose_from_quaternion_checked(q, tn, "--init-pose", &p);
  CHECK(s.code() == gs::StatusCode::kInvalidArgument);
  CHECK(contains(s.message(), "--init-pose: value 5 (ty) is NaN"));
  const double qi[4] = {inf, 0, 0, 0};
  s = gs::pose::pose_from_quaternion_checked(qi, t, "view 3", &p);
  CHECK(contains(s.message(), "view 3: value 0 (qw) is Inf"));
  const double q12[4] = {1.2, 0, 0, 0};
  s = gs::pose::pose_from_quaternion_checked(q12, t, "pose", &p);
  CHECK(s.code() == gs::StatusCode::kInvalidArgument);
  CHECK(contains(s.message(), "pose: quaternion (qw qx qy qz) = (1.2 0 0 0) has norm 1.2, expected 1 (±1e-3)"));
  CHECK(contains(s.message(), "normalise it or check the order: qw qx qy qz tx ty tz"));
  const double q0[4] = {0, 0, 0, 0};
  s = gs::pose::pose_from_quaternion_checked(q0, t, "pose", &p);
  CHECK(s.code() == gs::StatusCode::kInvalidArgument);
  CHECK(contains(s.message(), "is zero"));
  const double q_off[4] = {1.0011, 0, 0, 0};
  CHECK(!gs::pose::pose_from_quaternion_checked(q_off, t, "pose", &p).ok());
}

TEST_CASE("parse_pose reads seven numbers and names what is wrong") {
  gs::Pose p;
  for (const char* text : {"1 0 0 0 1 2 3", "1,0,0,0,1,2,3", " 1, 0, 0, 0,  1, 2, 3 ", "1\t0 0 0 1e0 2 3"}) {
    INFO(text);
    REQUIRE(gs::pose::parse_pose(text, "pose", &p).ok());
    CHECK(p.R[0] == 1.0f);
    CHECK(p.R[4] == 1.0f);
    CHECK(p.t[0] == 1.0f);
    CHECK(p.t[2] == 3.0f);
  }
  gs::Status s = gs::pose::parse_pose("1 0 0 0 1 2", "--pose", &p);
  CHECK(s.code() == gs::StatusCode::kInvalidArgument);
  CHECK(contains(s.message(), "--pose: expected 7 numbers qw qx qy qz tx ty tz, found 6"));
  s = gs::pose::parse_pose("1 0 0 0 1 2 3 4", "--pose", &p);
  CHECK(contains(s.message(), "found 8"));
  s = gs::pose::parse_pose("", "--pose", &p);
  CHECK(contains(s.message(), "found 0"));
  s = gs::pose::parse_pose("1 0 0 zz 1 2 3", "--pose", &p);
  CHECK(contains(s.message(), "\"zz\" (value 3, qz) is not a number"));
  s = gs::pose::parse_pose("1 0 0 0 1 2.5x 3", "--pose", &p);
  CHECK(contains(s.message(), "\"2.5x\""));
  s = gs::pose::parse_pose("1 0 0 0 nan 2 3", "--pose", &p);
  CHECK(contains(s.message(), "value 4 (tx) is NaN"));
  s = gs::pose::parse_pose("1.2 0 0 0 1 2 3", "--pose", &p);
  CHECK(contains(s.message(), "has norm 1.2"));
  s = gs::pose::parse_pose("0 0 0 0 1 2 3", "--pose", &p);
  CHECK(contains(s.message(), "is zero"));
}

TEST_CASE("parse_pose_noise grammar and describe") {
  gs::pose::PoseNoise n;
  REQUIRE(gs::pose::parse_pose_noise("none", &n).ok());
  CHECK(n.kind == gs::pose::PoseNoise::kNone);
  CHECK(gs::pose::describe(n) == "none");
  REQUIRE(gs::pose::parse_pose_noise("barf:0.15", &n).ok());
  CHECK(n.kind == gs::pose::PoseNoise::kBarf);
  CHECK(n.sigma == 0.15);
  CHECK(n.seed == 0);
  CHECK(gs::pose::describe(n) == "barf sigma 0.15 (seed 0)");
  REQUIRE(gs::pose::parse_pose_noise("rot:10,trans:0.1,seed:3", &n).ok());
  CHECK(n.kind == gs::pose::PoseNoise::kFixed);
  CHECK(n.rotation_deg == 10);
  CHECK(n.translation_frac == 0.1);
  CHECK(n.seed == 3);
  CHECK(gs::pose::describe(n) == "rotation 10 deg, translation 0.1 x radius (seed 3)");
  REQUIRE(gs::pose::parse_pose_noise("rot:5", &n).ok());
  CHECK(n.kind == gs::pose::PoseNoise::kFixed);
  CHECK(n.rotation_deg == 5);
  CHECK(n.translation_frac == 0);
  REQUIRE(gs::pose::parse_pose_noise("trans: 0.2 , seed:18446744073709551615", &n).ok());
  CHECK(n.rotation_deg == 0);
  CHECK(n.translation_frac == 0.2);
  CHECK(n.seed == 18446744073709551615ull);
  REQUIRE(gs::pose::parse_pose_noise("barf:0", &n).ok());
  CHECK(n.sigma == 0);

  struct Bad {
    const char* spec;
    const char* needle;
  };
  for (const Bad& b : {Bad{"barf:-0.1", "\"barf:-0.1\""}, Bad{"rot:-5", "\"rot:-5\""}, Bad{"trans:-1", "\"trans:-1\""},
                       Bad{"foo:1", "\"foo:1\""}, Bad{"barf:abc", "\"abc\""}, Bad{"barf:nan", "\"nan\""},
                       Bad{"barf", "\"barf\""}, Bad{"", "empty token"}, Bad{"barf:0.1,rot:5", "exclude"},
                       Bad{"none,barf:0.1", "exclude"}, Bad{"seed:3", "no noise kind"}, Bad{"rot:5,seed:-1", "\"seed:-1\""},
                       Bad{"rot:5,seed:x", "\"seed:x\""}, Bad{"rot:5,rot:6", "twice"}, Bad{"rot:200", "[0, 180]"},
                       Bad{"rot:5,", "empty token"}}) {
    INFO(b.spec);
    const gs::Status s = gs::pose::parse_pose_noise(b.spec, &n);
    CHECK(s.code() == gs::StatusCode::kInvalidArgument);
    CHECK(contains(s.message(), b.needle));
    CHECK(contains(s.message(), "accepted forms: none | barf:SIGMA | rot:DEG,trans:FRAC"));
  }
}

namespace {
std::vector<gs::Pose> camera_ring(size_t n, uint64_t seed) {
  Rng rng(seed);
  const double at[3] = {0.5, -1.0, 2.0};
  std::vector<gs::Pose> v;
  for (size_t i = 0; i < n; ++i) v.push_back(random_pose(rng, 3.0, at));
  return v;
}
}  // namespace

TEST_CASE("pose noise none and zero sizes leave poses unchanged") {
  const std::vector<gs::Pose> gt = camera_ring(20, 21);
  double c[3], r = 0;
  gs::pose::scene_frame(gt.data(), gt.size(), c, &r);
  for (const char* spec : {"none", "barf:0", "rot:0,trans:0"}) {
    INFO(spec);
    gs::pose::PoseNoise noise;
    REQUIRE(gs::pose::parse_pose_noise(spec, &noise).ok());
    std::vector<gs::Pose> p = gt;
    gs::pose::perturb_poses(noise, c, r, p.data(), p.size());
    for (size_t i = 0; i < p.size(); ++i) {
      double Ra[9], ta[3], Rb[9], tb[3];
      pose_d(p[i], Ra, ta);
      pose_d(gt[i], Rb, tb);
      CHECK(max_abs_diff(Ra, Rb, 9) < 2e-7);
      CHECK(max_abs_diff(ta, tb, 3) < 2e-6);  // |t| up to ~8: a few float ulps
    }
  }
}

TEST_CASE("barf noise draws xi with the right scale in the normalised frame") {
  const size_t n = 4000;
  const std::vector<gs::Pose> gt = camera_ring(n, 22);
  double c[3], r = 0;
  gs::pose::scene_frame(gt.data(), n, c, &r);
  gs::pose::PoseNoise noise;
  REQUIRE(gs::pose::parse_pose_noise("barf:0.15,seed:5", &noise).ok());
  std::vector<gs::Pose> p = gt;
  gs::pose::perturb_poses(noise, c, r, p.data(), n);
  const double s = 4.03 / r, sigma = 0.15;
  double sum[6] = {}, sum2[6] = {}, mean_angle = 0, mean_rho = 0;
  for (size_t i = 0; i < n; ++i) {
    // Recover xi from T_n^-1 T_n' = Exp(xi), T_n = (R, s (R c + t)).
    double R[9], t[3], R2[9], t2[3], Rc[3], R2c[3], E[9], d[3], tE[3], xi[6];
    pose_d(gt[i], R, t);
    pose_d(p[i], R2, t2);
    matvec(R, c, Rc);
    matvec(R2, c, R2c);
    matmul_at(R, R2, E);
    for (int k = 0; k < 3; ++k) d[k] = s * (R2c[k] + t2[k]) - s * (Rc[k] + t[k]);
    matvec_t(R, d, tE);
    gs::pose::se3_log(E, tE, xi);
    for (int k = 0; k < 6; ++k) sum[k] += xi[k], sum2[k] += xi[k] * xi[k];
    mean_angle += gs::pose::rotation_error_deg(p[i], gt[i]) / double(n);
    mean_rho += norm3(xi) / double(n);
  }
  for (int k = 0; k < 6; ++k) {
    const double mean = sum[k] / double(n), sd = std::sqrt(sum2[k] / double(n) - mean * mean);
    INFO("component " << k << " mean " << mean << " sd " << sd);
    CHECK(std::abs(mean) < 4 * sigma / std::sqrt(double(n)));  // 4 standard errors
    CHECK(std::abs(sd / sigma - 1) < 0.045);                   // sd of a sample sd: 1/sqrt(2n) = 1.1%
  }
  // |phi| of an isotropic 3D Gaussian is chi-distributed: mean sigma sqrt(8/pi) = 13.72 deg for 0.15.
  // Sample-mean standard error: sqrt(3 - 8/pi) / sqrt(8/pi) / sqrt(n) = 0.67%; allow 3%.
  const double expect_deg = sigma * std::sqrt(8 / kPi) * 180 / kPi;
  CHECK(std::abs(expect_deg - 13.72) < 0.01);
  CHECK(std::abs(mean_angle / expect_deg - 1) < 0.03);
  CHECK(std::abs(mean_rho / (sigma * std::sqrt(8 / kPi)) - 1) < 0.03);
}

TEST_CASE("fixed noise rotates about the camera centre by exactly the given angle and distance") {
  const size_t n = 3000;
  const std::vector<gs::Pose> gt = camera_ring(n, 23);
  double c[3], r = 0;
  gs::pose::scene_frame(gt.data(), n, c, &r);
  gs::pose::PoseNoise noise;
  REQUIRE(gs::pose::parse_pose_noise("rot:10,trans:0.1,seed:9", &noise).ok());
  std::vector<gs::Pose> p = gt;
  gs::pose::perturb_poses(noise, c, r, p.data(), n);
  double axis_mean[3] = {}, axis_sq[3] = {}, dir_mean[3] = {};
  for (size_t i = 0; i < n; ++i) {
    CHECK(std::abs(angle_deg(p[i], gt[i]) - 10) < 1e-4);
    CHECK(std::abs(centre_distance(p[i], gt[i]) / (0.1 * r) - 1) < 1e-5);
    double Ra[9], Rb[9], t[3], M[9], phi[3], ca[3], cb[3];
    pose_d(p[i], Ra, t);
    pose_d(gt[i], Rb, t);
    matmul_bt(Ra, Rb, M);
    gs::pose::so3_log(M, phi);
    gs::pose::centre(p[i], ca);
    gs::pose::centre(gt[i], cb);
    for (int k = 0; k < 3; ++k) {
      const double a = phi[k] / norm3(phi);
      axis_mean[k] += a / double(n), axis_sq[k] += a * a / double(n);
      dir_mean[k] += (ca[k] - cb[k]) / (0.1 * r) / double(n);
    }
  }
  // Uniform directions: mean 0 (standard error 1/sqrt(3n) = 0.0105), E[a_k^2] = 1/3 (se 0.0054).
  for (int k = 0; k < 3; ++k) {
    CHECK(std::abs(axis_mean[k]) < 0.045);
    CHECK(std::abs(dir_mean[k]) < 0.045);
    CHECK(std::abs(axis_sq[k] - 1.0 / 3) < 0.025);
  }
  // Rotation only: the camera centre stays where it was (rotation about the centre).
  REQUIRE(gs::pose::parse_pose_noise("rot:25", &noise).ok());
  p = gt;
  gs::pose::perturb_poses(noise, c, r, p.data(), 200);
  for (size_t i = 0; i < 200; ++i) {
    CHECK(std::abs(angle_deg(p[i], gt[i]) - 25) < 1e-4);
    CHECK(centre_distance(p[i], gt[i]) < 1e-5 * r);
  }
}

TEST_CASE("pose noise on a few views with a range of angles (rot:MIN-MAX,views:N)") {
  gs::pose::PoseNoise noise;
  REQUIRE(gs::pose::parse_pose_noise("rot:10-40,views:3,seed:4", &noise).ok());
  CHECK(noise.rotation_deg == 10);
  CHECK(noise.rotation_max_deg == 40);
  CHECK(noise.views == 3);
  CHECK(gs::pose::describe(noise) == "rotation 10-40 deg, translation 0 x radius (seed 4) on 3 views");
  for (const char* bad : {"rot:40-10", "rot:10-200", "rot:10-x", "rot:5,views:0", "rot:5,views:-2", "none,views:2"}) {
    INFO(bad);
    gs::pose::PoseNoise n;
    CHECK(gs::pose::parse_pose_noise(bad, &n).code() == gs::StatusCode::kInvalidArgument);
  }
  const std::vector<gs::Pose> gt = camera_ring(40, 25);
  double c[3], r = 0;
  gs::pose::scene_frame(gt.data(), gt.size(), c, &r);
  // Every fifth view is not eligible (a test view): never moved, never counted among the three.
  std::vector<uint8_t> eligible(gt.size(), 1);
  for (size_t i = 0; i < gt.size(); i += 5) eligible[i] = 0;
  for (uint64_t seed : {1, 2, 3, 4, 5, 6}) {
    noise.seed = seed;
    std::vector<gs::Pose> p = gt;
    gs::pose::perturb_poses(noise, c, r, p.data(), p.size(), eligible.data());
    int moved = 0;
    for (size_t i = 0; i < p.size(); ++i) {
      const double a = angle_deg(p[i], gt[i]);
      if (a < 1e-4) continue;
      ++moved;
      CHECK(eligible[i] == 1);
      CHECK(a >= 10 - 1e-4);
      CHECK(a <= 40 + 1e-4);
    }
    CHECK(moved == 3);
  }
  // Views:N above the eligible count moves all of them.
  noise.views = 100;
  std::vector<gs::Pose> p = gt;
  gs::pose::perturb_poses(noise, c, r, p.data(), p.size(), eligible.data());
  for (size_t i = 0; i < p.size(); ++i) CHECK((angle_deg(p[i], gt[i]) > 1) == bool(eligible[i]));
}

TEST_CASE("pose noise is deterministic and per view") {
  const std::vector<gs::Pose> gt = camera_ring(10, 24);
  double c[3], r = 0;
  gs::pose::scene_frame(gt.data(), gt.size(), c, &r);
  for (const char* spec : {"barf:0.15,seed:7", "rot:3,trans:0.05,seed:7"}) {
    INFO(spec);
    gs::pose::PoseNoise noise;
    REQUIRE(gs::pose::parse_pose_noise(spec, &noise).ok());
    std::vector<gs::Pose> a = gt, b = gt, prefix(gt.begin(), gt.begin() + 3), other = gt;
    gs::pose::perturb_poses(noise, c, r, a.data(), a.size());
    gs::pose::perturb_poses(noise, c, r, b.data(), b.size());
    gs::pose::perturb_poses(noise, c, r, prefix.data(), prefix.size());
    gs::pose::PoseNoise noise2 = noise;
    noise2.seed = 8;
    gs::pose::perturb_poses(noise2, c, r, other.data(), other.size());
    for (size_t i = 0; i < a.size(); ++i) {
      CHECK(std::equal(a[i].R, a[i].R + 9, b[i].R));
      CHECK(std::equal(a[i].t, a[i].t + 3, b[i].t));
      if (i < prefix.size()) {
        CHECK(std::equal(a[i].R, a[i].R + 9, prefix[i].R));
        CHECK(std::equal(a[i].t, a[i].t + 3, prefix[i].t));
      }
      CHECK(angle_deg(a[i], other[i]) > 1e-3);  // another seed, other noise
      CHECK(angle_deg(a[i], gt[i]) > 1e-3);
    }
    // Views draw different noise: relative motion of view 0 and view 1 differ.
    double x0[6], x1[6];
    gs::pose::left_difference(gt[0], a[0], x0);
    gs::pose::left_difference(gt[1], a[1], x1);
    CHECK(max_abs_diff(x0, x1, 6) > 1e-3);
  }
}

TEST_CASE("pose_errors without alignment reports the known errors") {
  const std::vector<gs::Pose> gt = camera_ring(5, 25);
  std::vector<gs::Pose> est = gt;
  Rng rng(26);
  const double rot_deg[5] = {1, 2, 3, 4, 10}, dist[5] = {0.1, 0.4, 0.2, 0.3, 0.5};
  for (size_t i = 0; i < 5; ++i) {
    double u[3], dir[3], R[9], E[9], R2[9], t[3], C[3];
    rng.unit(u);
    rng.unit(dir);
    const double phi[3] = {rot_deg[i] * kPi / 180 * u[0], rot_deg[i] * kPi / 180 * u[1], rot_deg[i] * kPi / 180 * u[2]};
    gs::pose::so3_exp(phi, E);
    pose_d(gt[i], R, t);
    matmul(E, R, R2);
    gs::pose::centre(gt[i], C);
    for (int k = 0; k < 3; ++k) C[k] += dist[i] * dir[k];
    est[i] = pose_from(R2, C);
  }
  const gs::pose::PoseErrors e = gs::pose::pose_errors(est.data(), gt.data(), 5, 2.0, false);
  CHECK(e.count == 5);
  CHECK(!e.aligned);
  CHECK(e.scale == 1);
  REQUIRE(e.rotation_deg.size() == 5);
  REQUIRE(e.translation.size() == 5);
  for (size_t i = 0; i < 5; ++i) {
    CHECK(std::abs(e.rotation_deg[i] - rot_deg[i]) < 1e-3);
    CHECK(std::abs(e.translation[i] - dist[i]) < 2e-6);
  }
  CHECK(std::abs(e.rotation_mean_deg - 4) < 1e-3);
  CHECK(std::abs(e.rotation_median_deg - 3) < 1e-3);
  CHECK(std::abs(e.rotation_max_deg - 10) < 1e-3);
  CHECK(std::abs(e.translation_mean - 0.3) < 2e-6);
  CHECK(std::abs(e.translation_median - 0.3) < 2e-6);
  CHECK(std::abs(e.translation_mean_frac - 0.15) < 1e-6);
  CHECK(std::abs(e.ate_rmse - std::sqrt((0.01 + 0.16 + 0.04 + 0.09 + 0.25) / 5)) < 2e-6);
  // Even count: the median averages the two middle values.
  const gs::pose::PoseErrors e4 = gs::pose::pose_errors(est.data(), gt.data(), 4, 2.0, false);
  CHECK(std::abs(e4.rotation_median_deg - 2.5) < 1e-3);
  CHECK(std::abs(e4.translation_median - 0.25) < 2e-6);
}

namespace {
// Estimates in another frame: x_est = s0 R0 x + t0, so centre_est = s0 R0 C and R_est = R R0^T.
std::vector<gs::Pose> similar(const std::vector<gs::Pose>& gt, double s0, const double R0[9], const double t0[3]) {
  std::vector<gs::Pose> est;
  for (const gs::Pose& g : gt) {
    double R[9], t[3], C[3], Ce[3], Re[9];
    pose_d(g, R, t);
    gs::pose::centre(g, C);
    matvec(R0, C, Ce);
    for (int k = 0; k < 3; ++k) Ce[k] = s0 * Ce[k] + t0[k];
    matmul_bt(R, R0, Re);
    est.push_back(pose_from(Re, Ce));
  }
  return est;
}
}  // namespace

TEST_CASE("pose_errors Sim3 alignment recovers a known similarity") {
  Rng rng(27);
  for (int trial = 0; trial < 40; ++trial) {
    // Half the trials: coplanar centres (a ring at z = 1), where the SVD's third singular vectors
    // have an arbitrary sign and about half the trials need the determinant fix.
    std::vector<gs::Pose> gt;
    const bool planar = trial % 2 == 1;
    const size_t n = planar ? 8 : 12;
    for (size_t i = 0; i < n; ++i) {
      double phi[3], R[9], C[3];
      random_phi(rng, kPi, phi);
      gs::pose::so3_exp(phi, R);
      if (planar) {
        const double a = 2 * kPi * double(i) / double(n);
        C[0] = 3 * std::cos(a), C[1] = 2 * std::sin(a), C[2] = 1;
      } else {
        for (double& v : C) v = rng.uniform(-2, 2);
      }
      gt.push_back(pose_from(R, C));
    }
    double phi0[3], R0[9], t0[3];
    random_phi(rng, kPi, phi0);
    gs::pose::so3_exp(phi0, R0);
    for (double& v : t0) v = rng.uniform(-5, 5);
    const double s0 = rng.uniform(0.3, 3);
    const std::vector<gs::Pose> est = similar(gt, s0, R0, t0);
    double c[3], r = 0;
    gs::pose::scene_frame(gt.data(), n, c, &r);
    const gs::pose::PoseErrors e = gs::pose::pose_errors(est.data(), gt.data(), n, r, true);
    INFO("trial " << trial << " planar " << planar << " s0 " << s0);
    CHECK(e.aligned);
    CHECK(std::abs(e.scale * s0 - 1) < 1e-6);
    // Float storage of the estimates (|t| up to ~15): centres good to ~1e-6.
    CHECK(e.ate_rmse < 1e-5 * r);
    CHECK(e.translation_mean_frac < 1e-5);
    CHECK(e.rotation_max_deg < 1e-4);
    // Without alignment the same estimates are far off.
    const gs::pose::PoseErrors raw = gs::pose::pose_errors(est.data(), gt.data(), n, r, false);
    CHECK(raw.ate_rmse > 0.1);
  }
}

TEST_CASE("pose_errors does not absorb a mirrored camera set") {
  // Mirrored centres (x -> -x) cannot be matched by a proper rotation: the determinant fix must
  // keep det(R) = +1, so the aligned centres stay measurably off (a reflection would fit them exactly).
  Rng rng(28);
  std::vector<gs::Pose> gt, est;
  for (int i = 0; i < 10; ++i) {
    double phi[3], R[9], C[3];
    random_phi(rng, kPi, phi);
    gs::pose::so3_exp(phi, R);
    for (double& v : C) v = rng.uniform(-2, 2);
    gt.push_back(pose_from(R, C));
    C[0] = -C[0];
    est.push_back(pose_from(R, C));
  }
  const gs::pose::PoseErrors e = gs::pose::pose_errors(est.data(), gt.data(), gt.size(), 2.0, true);
  CHECK(e.aligned);
  CHECK(e.scale > 0);
  CHECK(e.ate_rmse > 0.1);
}

TEST_CASE("pose_errors falls back to no alignment for degenerate centres") {
  Rng rng(29);
  auto check_fallback = [](const std::vector<gs::Pose>& est, const std::vector<gs::Pose>& gt) {
    const gs::pose::PoseErrors a = gs::pose::pose_errors(est.data(), gt.data(), gt.size(), 1.0, true);
    const gs::pose::PoseErrors b = gs::pose::pose_errors(est.data(), gt.data(), gt.size(), 1.0, false);
    CHECK(!a.aligned);
    CHECK(a.scale == 1);
    CHECK(a.rotation_deg == b.rotation_deg);
    CHECK(a.translation == b.translation);
    CHECK(a.ate_rmse == b.ate_rmse);
  };
  auto make = [&](const double (*C)[3], size_t n) {
    std::vector<gs::Pose> v;
    for (size_t i = 0; i < n; ++i) {
      double phi[3], R[9];
      random_phi(rng, kPi, phi);
      gs::pose::so3_exp(phi, R);
      v.push_back(pose_from(R, C[i]));
    }
    return v;
  };
  const double line[6][3] = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {-1, -1, -1}, {0.5, 0.5, 0.5}, {3, 3, 3}};
  const double line2[6][3] = {{1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}, {5, 0, 0}, {6, 0, 0}};
  const double same[6][3] = {{1, 2, 3}, {1, 2, 3}, {1, 2, 3}, {1, 2, 3}, {1, 2, 3}, {1, 2, 3}};
  const double spread[6][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0, 1, 1}};
  check_fallback(make(line, 6), make(line2, 6));      // collinear estimates and truth
  check_fallback(make(spread, 6), make(line, 6));     // collinear truth
  check_fallback(make(line, 6), make(spread, 6));     // collinear estimates
  check_fallback(make(same, 6), make(spread, 6));     // coincident estimates
  check_fallback(make(spread, 2), make(spread + 1, 2));  // n < 3
  // n = 0: nothing to report.
  const gs::pose::PoseErrors z = gs::pose::pose_errors(nullptr, nullptr, 0, 1.0, true);
  CHECK(z.count == 0);
  CHECK(z.ate_rmse == 0);
  // Control: a non-degenerate set of the same size aligns.
  const std::vector<gs::Pose> a = make(spread, 6);
  CHECK(gs::pose::pose_errors(a.data(), a.data(), 6, 1.0, true).aligned);
}

TEST_CASE("scene_frame is the mean centre and the largest distance from it") {
  const double Cs[4][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 2, 0}, {0, -2, 4}};
  std::vector<gs::Pose> v;
  Rng rng(30);
  for (const auto& C : Cs) {
    double phi[3], R[9];
    random_phi(rng, kPi, phi);
    gs::pose::so3_exp(phi, R);
    v.push_back(pose_from(R, C));
  }
  double c[3], r = 0;
  gs::pose::scene_frame(v.data(), v.size(), c, &r);
  const double expect[3] = {0, 0, 1};
  CHECK(max_abs_diff(c, expect, 3) < 1e-6);
  CHECK(std::abs(r - std::sqrt(13.0)) < 1e-6);  // (0, -2, 4) - (0, 0, 1)
  gs::pose::scene_frame(v.data(), 1, c, &r);
  CHECK(r == 1e-9);
  CHECK(std::abs(c[0] - 1) < 1e-6);
}

TEST_CASE("pose: fit_sim3_trimmed leaves gross outliers out where the plain fit is tilted by them") {
  gs::pose::Sim3 T;
  const double phi[3] = {0.1, 0.2, -0.3};
  gs::pose::so3_exp(phi, T.R);
  T.s = 0.8;
  T.t[0] = 1.0, T.t[1] = 0.5, T.t[2] = -0.25;
  std::vector<double> x, y;
  for (int i = 0; i < 40; ++i) {  // a ring of cameras with small noise, 4 of them far off
    const double a = 0.157 * i;
    const double p[3] = {2 * std::cos(a), 0.3 * std::sin(3 * a), 2 * std::sin(a)};
    double q[3];
    gs::pose::transform_point(T, p, q);
    for (int k = 0; k < 3; ++k) q[k] += 1e-3 * std::sin(7.0 * i + k);
    if (i % 10 == 3) q[1] += i < 20 ? 0.8 : -0.8;  // half up, half down: they tilt the ring
    x.insert(x.end(), p, p + 3);
    y.insert(y.end(), q, q + 3);
  }
  auto rotation_off_deg = [&](const gs::pose::Sim3& f) {
    gs::Pose a, b;
    for (int k = 0; k < 9; ++k) a.R[k] = float(f.R[k]), b.R[k] = float(T.R[k]);
    return gs::pose::rotation_error_deg(a, b);
  };
  gs::pose::Sim3 plain, trimmed;
  size_t inliers = 0;
  REQUIRE(gs::pose::fit_sim3(x.data(), y.data(), nullptr, 40, &plain));
  REQUIRE(gs::pose::fit_sim3_trimmed(x.data(), y.data(), 40, &trimmed, &inliers));
  MESSAGE("rotation off by " << rotation_off_deg(plain) << " deg (plain) and " << rotation_off_deg(trimmed) << " deg (trimmed, "
                             << inliers << " of 40 pairs)");
  CHECK(rotation_off_deg(plain) > 1.0);
  CHECK(rotation_off_deg(trimmed) < 0.05);
  CHECK(inliers >= 30);
  CHECK(inliers <= 36);
  CHECK(trimmed.s == doctest::Approx(T.s).epsilon(1e-3));
  // Without outliers the trimmed fit is the plain one.
  std::vector<double> clean_y;
  for (int i = 0; i < 40; ++i) {
    double q[3];
    gs::pose::transform_point(T, &x[3 * i], q);
    clean_y.insert(clean_y.end(), q, q + 3);
  }
  REQUIRE(gs::pose::fit_sim3_trimmed(x.data(), clean_y.data(), 40, &trimmed));
  CHECK(trimmed.s == doctest::Approx(T.s).epsilon(1e-12));
  for (int k = 0; k < 9; ++k) CHECK(trimmed.R[k] == doctest::Approx(T.R[k]).epsilon(1e-12));
}

TEST_CASE("pose: fit_sim3 recovers a similarity and transform_pose moves cameras with the world") {
  gs::pose::Sim3 T;
  const double phi[3] = {0.3, -0.5, 0.8};
  gs::pose::so3_exp(phi, T.R);
  T.s = 1.7;
  T.t[0] = 0.5, T.t[1] = -2.0, T.t[2] = 3.0;
  std::vector<double> x, y;
  for (int i = 0; i < 20; ++i) {
    const double p[3] = {std::sin(1.3 * i), std::cos(0.7 * i) * 2.0, 0.1 * i - 1.0};
    double q[3];
    gs::pose::transform_point(T, p, q);
    x.insert(x.end(), p, p + 3);
    y.insert(y.end(), q, q + 3);
  }
  gs::pose::Sim3 fit;
  REQUIRE(gs::pose::fit_sim3(x.data(), y.data(), nullptr, 20, &fit));
  CHECK(fit.s == doctest::Approx(T.s).epsilon(1e-12));
  for (int k = 0; k < 9; ++k) CHECK(fit.R[k] == doctest::Approx(T.R[k]).epsilon(1e-12));
  for (int k = 0; k < 3; ++k) CHECK(fit.t[k] == doctest::Approx(T.t[k]).epsilon(1e-12));
  // Collinear points are refused.
  std::vector<double> line;
  for (int i = 0; i < 5; ++i) line.insert(line.end(), {double(i), 2.0 * i, -1.0 * i});
  CHECK(!gs::pose::fit_sim3(line.data(), line.data(), nullptr, 5, &fit));

  // A camera sees a world point at the same pixel before and after the world moves, at s x depth.
  gs::Pose cam;
  const double xi[6] = {0.2, -0.1, 0.4, 0.05, 0.3, -0.2};
  gs::pose::apply_left_twist(xi, &cam);
  const gs::Pose moved = gs::pose::transform_pose(T, cam);
  const double X[3] = {0.3, 0.2, 4.0};
  double Xw[3];
  gs::pose::transform_point(T, X, Xw);
  double a[3], b[3];
  for (int r = 0; r < 3; ++r) {
    a[r] = cam.t[r], b[r] = moved.t[r];
    for (int k = 0; k < 3; ++k) a[r] += double(cam.R[3 * r + k]) * X[k], b[r] += double(moved.R[3 * r + k]) * Xw[k];
  }
  for (int r = 0; r < 3; ++r) CHECK(b[r] == doctest::Approx(T.s * a[r]).epsilon(1e-5));
  // compose: (b after a) applied to a point equals applying a then b.
  const gs::pose::Sim3 both = gs::pose::compose(T, fit);
  double p1[3], p2[3], p3[3];
  gs::pose::transform_point(fit, X, p1);
  gs::pose::transform_point(T, p1, p2);
  gs::pose::transform_point(both, X, p3);
  for (int r = 0; r < 3; ++r) CHECK(p3[r] == doctest::Approx(p2[r]).epsilon(1e-12));
}
