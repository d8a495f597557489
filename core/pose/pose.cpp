// SPDX-License-Identifier: MIT
// Camera-pose utilities: se(3) twists, checked pose input, seeded pose noise, Sim(3)-aligned
// pose errors. See gs/pose/pose.h for the conventions; all arithmetic is in double.
#include "gs/constants.h"
#include "gs/pose/pose.h"
#include "gs/random.h"
#include "gs/simd/quat.h"
#include "gs/stats.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace gs::pose {
namespace {

constexpr double kRadToDeg = 180.0 / kPi;
// Below this angle the closed forms lose digits to cancellation; the Taylor series up to
// theta^6 used instead have a truncation error below 1e-17 there.
constexpr double kSeriesAngle = 1e-2;
// BARF's clamp of the arccos argument (camera.py rotation_distance).
// BARF's Blender camera radius: the noise is drawn in a frame where the scene radius is this.
constexpr double kBarfRadius = 4.03;

void skew(const double v[3], double K[9]) {
  K[0] = 0, K[1] = -v[2], K[2] = v[1];
  K[3] = v[2], K[4] = 0, K[5] = -v[0];
  K[6] = -v[1], K[7] = v[0], K[8] = 0;
}

void matmul(const double A[9], const double B[9], double C[9]) {
  double out[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
  std::copy(out, out + 9, C);
}

// C = A B^T
void matmul_bt(const double A[9], const double B[9], double C[9]) {
  double out[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[i * 3 + j] = A[i * 3] * B[j * 3] + A[i * 3 + 1] * B[j * 3 + 1] + A[i * 3 + 2] * B[j * 3 + 2];
  std::copy(out, out + 9, C);
}

void matvec(const double A[9], const double x[3], double y[3]) {
  double out[3];
  for (int i = 0; i < 3; ++i) out[i] = A[i * 3] * x[0] + A[i * 3 + 1] * x[1] + A[i * 3 + 2] * x[2];
  std::copy(out, out + 3, y);
}

// y = A^T x
void matvec_t(const double A[9], const double x[3], double y[3]) {
  double out[3];
  for (int i = 0; i < 3; ++i) out[i] = A[i] * x[0] + A[3 + i] * x[1] + A[6 + i] * x[2];
  std::copy(out, out + 3, y);
}

// M = I + a K + b K^2 with K = [v]x.
void i_plus_ab(const double v[3], double a, double b, double M[9]) {
  double K[9], K2[9];
  skew(v, K);
  matmul(K, K, K2);
  for (int i = 0; i < 9; ++i) M[i] = a * K[i] + b * K2[i];
  M[0] += 1, M[4] += 1, M[8] += 1;
}

// Coefficients of Exp (A = sin t / t, B = (1 - cos t) / t^2) and of V (C = (t - sin t) / t^3).
void so3_coeffs(double theta, double* A, double* B, double* C) {
  const double t2 = theta * theta;
  if (theta < kSeriesAngle) {
    *A = 1 - t2 / 6 * (1 - t2 / 20 * (1 - t2 / 42));
    *B = 0.5 - t2 / 24 * (1 - t2 / 30 * (1 - t2 / 56));
    *C = 1.0 / 6 - t2 / 120 * (1 - t2 / 42 * (1 - t2 / 72));
  } else {
    const double s = std::sin(theta), h = std::sin(0.5 * theta);
    *A = s / theta;
    *B = 2 * h * h / t2;
    *C = (theta - s) / (t2 * theta);
  }
}

double norm3(const double v[3]) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// R <- orthonormal polar factor of R: two Newton steps R <- (R + R^-T) / 2 (quadratic
// convergence; a float-rounded rotation, error ~1e-7, is orthonormal to double precision after two).
void orthonormalise(double R[9]) {
  for (int it = 0; it < 2; ++it) {
    const double* r0 = R;
    const double* r1 = R + 3;
    const double* r2 = R + 6;
    // Rows of the cofactor matrix: r1 x r2, r2 x r0, r0 x r1; R^-T = cof / det.
    double cof[9] = {r1[1] * r2[2] - r1[2] * r2[1], r1[2] * r2[0] - r1[0] * r2[2], r1[0] * r2[1] - r1[1] * r2[0],
                     r2[1] * r0[2] - r2[2] * r0[1], r2[2] * r0[0] - r2[0] * r0[2], r2[0] * r0[1] - r2[1] * r0[0],
                     r0[1] * r1[2] - r0[2] * r1[1], r0[2] * r1[0] - r0[0] * r1[2], r0[0] * r1[1] - r0[1] * r1[0]};
    const double det = r0[0] * cof[0] + r0[1] * cof[1] + r0[2] * cof[2];
    if (!(std::abs(det) > 1e-12)) return;  // not a rotation at all; leave it to the caller's checks
    for (int i = 0; i < 9; ++i) R[i] = 0.5 * (R[i] + cof[i] / det);
  }
}

void to_double(const Pose& p, double R[9], double t[3]) {
  for (int i = 0; i < 9; ++i) R[i] = p.R[i];
  for (int i = 0; i < 3; ++i) t[i] = p.t[i];
}

void store(const double R[9], const double t[3], Pose* p) {
  for (int i = 0; i < 9; ++i) p->R[i] = float(R[i]);
  for (int i = 0; i < 3; ++i) p->t[i] = float(t[i]);
}

double rotation_error_deg_d(const double Ra[9], const double Rb[9]) {
  double M[9], phi[3];
  matmul_bt(Ra, Rb, M);
  so3_log(M, phi);
  return std::sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]) * kRadToDeg;
}

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// One SplitMix64 stream (gs/random.h) per view.
class ViewRng {
 public:
  ViewRng(uint64_t seed, uint64_t view) : gen_{mix64(mix64(seed + 0x9E3779B97F4A7C15ull) ^ (view + 1) * 0xD1B54A32D192ED03ull)} {}
  // Uniform in the open interval (0, 1).
  double uniform() { return gen_.uniform_open(); }
  // Standard normal, Box-Muller (both values of a pair are used).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2 * std::log(uniform())), a = 2 * kPi * uniform();
    spare_ = r * std::sin(a);
    has_spare_ = true;
    return r * std::cos(a);
  }
  // Uniformly distributed unit vector (normalised isotropic Gaussian).
  void unit_vector(double u[3]) {
    for (;;) {
      for (int k = 0; k < 3; ++k) u[k] = normal();
      const double n = norm3(u);
      if (n > 1e-9) {
        for (int k = 0; k < 3; ++k) u[k] /= n;
        return;
      }
    }
  }

 private:
  SplitMix64 gen_;
  double spare_ = 0;
  bool has_spare_ = false;
};

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const size_t e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

bool parse_double(const std::string& tok, double* v) {
  if (tok.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *v = std::strtod(tok.c_str(), &end);
  return end == tok.c_str() + tok.size() && errno != ERANGE;
}

}  // namespace

void so3_exp(const double phi[3], double R[9]) {
  double A, B, C;
  so3_coeffs(norm3(phi), &A, &B, &C);
  i_plus_ab(phi, A, B, R);
}

void so3_log(const double R[9], double phi[3]) {
  // v = vee(R - R^T) = 2 sin(theta) a; c = cos(theta).
  const double v[3] = {R[7] - R[5], R[2] - R[6], R[3] - R[1]};
  const double s = 0.5 * norm3(v);
  const double c = 0.5 * (R[0] + R[4] + R[8] - 1);
  const double theta = std::atan2(s, c);
  if (c > -0.5) {
    // theta < 120 deg: the axis from v is well conditioned; theta / sin(theta) -> 1 at 0.
    const double ratio = s > 0 ? theta / s : 1.0;
    for (int k = 0; k < 3; ++k) phi[k] = 0.5 * ratio * v[k];
    return;
  }
  // Near pi sin(theta) vanishes: take the axis from the symmetric part,
  // (R + R^T) / 2 = c I + (1 - c) a a^T, using its largest diagonal entry, and the sign from v.
  double M[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M[i * 3 + j] = (0.5 * (R[i * 3 + j] + R[j * 3 + i]) - (i == j ? c : 0.0)) / (1 - c);
  int k = 0;
  if (M[4] > M[k * 4]) k = 1;
  if (M[8] > M[k * 4]) k = 2;
  const double ak = std::sqrt(std::max(M[k * 4], 0.0));
  double a[3];
  for (int j = 0; j < 3; ++j) a[j] = j == k ? ak : (ak > 0 ? M[j * 3 + k] / ak : 0.0);
  const double n = norm3(a);
  if (!(n > 0)) {
    phi[0] = phi[1] = phi[2] = 0;
    return;
  }
  const double sign = (a[0] * v[0] + a[1] * v[1] + a[2] * v[2]) < 0 ? -1.0 : 1.0;
  for (int j = 0; j < 3; ++j) phi[j] = sign * theta * a[j] / n;
}

void se3_exp(const double xi[6], double R[9], double t[3]) {
  const double* rho = xi;
  const double* phi = xi + 3;
  double A, B, C;
  so3_coeffs(norm3(phi), &A, &B, &C);
  i_plus_ab(phi, A, B, R);
  double V[9];
  i_plus_ab(phi, B, C, V);
  matvec(V, rho, t);
}

void se3_log(const double R[9], const double t[3], double xi[6]) {
  double* rho = xi;
  double* phi = xi + 3;
  so3_log(R, phi);
  // V^-1 = I - K / 2 + D K^2, D = (1 - (theta/2) cot(theta/2)) / theta^2.
  const double theta = norm3(phi);
  double D;
  if (theta < kSeriesAngle) {
    const double t2 = theta * theta;
    D = 1.0 / 12 + t2 / 720 + t2 * t2 / 30240;
  } else {
    const double h = 0.5 * theta;
    D = (1 - h * std::cos(h) / std::sin(h)) / (theta * theta);
  }
  double Vinv[9];
  i_plus_ab(phi, -0.5, D, Vinv);
  matvec(Vinv, t, rho);
}

void apply_left_twist(const double xi[6], Pose* pose) {
  double E[9], tE[3], R[9], t[3];
  se3_exp(xi, E, tE);
  to_double(*pose, R, t);
  double R2[9], t2[3];
  matmul(E, R, R2);
  matvec(E, t, t2);
  for (int k = 0; k < 3; ++k) t2[k] += tE[k];
  orthonormalise(R2);
  store(R2, t2, pose);
}

void left_difference(const Pose& from, const Pose& to, double xi[6]) {
  double Rf[9], tf[3], Rt[9], tt[3];
  to_double(from, Rf, tf);
  to_double(to, Rt, tt);
  // Exp(xi) = to * from^-1 = (Rt Rf^T, tt - Rt Rf^T tf).
  double Rd[9], td[3];
  matmul_bt(Rt, Rf, Rd);
  matvec(Rd, tf, td);
  for (int k = 0; k < 3; ++k) td[k] = tt[k] - td[k];
  se3_log(Rd, td, xi);
}

double centre_distance(const Pose& a, const Pose& b) {
  double ca[3], cb[3];
  centre(a, ca);
  centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

double rotation_error_deg(const Pose& a, const Pose& b) {
  double Ra[9], Rb[9], t[3];
  to_double(a, Ra, t);
  to_double(b, Rb, t);
  return rotation_error_deg_d(Ra, Rb);
}

double relative_rotation_error_deg(const Pose& truth_a, const Pose& truth_b, const Pose& estimate_a, const Pose& estimate_b) {
  double Ta[9], Tb[9], Ea[9], Eb[9], t[3], rel_truth[9], rel_estimate[9];
  to_double(truth_a, Ta, t);
  to_double(truth_b, Tb, t);
  to_double(estimate_a, Ea, t);
  to_double(estimate_b, Eb, t);
  matmul_bt(Ta, Tb, rel_truth);
  matmul_bt(Ea, Eb, rel_estimate);
  return rotation_error_deg_d(rel_truth, rel_estimate);
}

void centre(const Pose& pose, double c[3]) {
  double R[9], t[3];
  to_double(pose, R, t);
  matvec_t(R, t, c);
  for (int k = 0; k < 3; ++k) c[k] = -c[k];
}

void rotation_from_quaternion(const double q[4], double R[9]) {
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(n > 0) || !std::isfinite(n)) {
    for (int i = 0; i < 9; ++i) R[i] = (i % 4 == 0) ? 1.0 : 0.0;
    return;
  }
  simd::rotmat_of_unit_quat(q[0] / n, q[1] / n, q[2] / n, q[3] / n, R);
}

Status pose_from_quaternion_checked(const double q[4], const double t[3], const std::string& what, Pose* out) {
  static const char* const kNames[7] = {"qw", "qx", "qy", "qz", "tx", "ty", "tz"};
  const double vals[7] = {q[0], q[1], q[2], q[3], t[0], t[1], t[2]};
  for (int i = 0; i < 7; ++i) {
    if (!std::isfinite(vals[i])) {
      return invalid_argument(what + ": value " + std::to_string(i) + " (" + kNames[i] + ") is " +
                              (std::isnan(vals[i]) ? "NaN" : "Inf") + "; expected 7 finite numbers qw qx qy qz tx ty tz");
    }
  }
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const std::string qs = "(" + fmt(q[0]) + " " + fmt(q[1]) + " " + fmt(q[2]) + " " + fmt(q[3]) + ")";
  if (n == 0) {
    return invalid_argument(what + ": quaternion (qw qx qy qz) = " + qs +
                            " is zero; expected a unit quaternion in the order qw qx qy qz tx ty tz");
  }
  if (std::abs(n - 1) > 1e-3) {
    return invalid_argument(what + ": quaternion (qw qx qy qz) = " + qs + " has norm " + fmt(n) +
                            ", expected 1 (±1e-3); normalise it or check the order: qw qx qy qz tx ty tz");
  }
  double R[9];
  rotation_from_quaternion(q, R);
  store(R, t, out);
  return Status::Ok();
}

Status parse_pose(const std::string& text, const std::string& what, Pose* out) {
  static const char* const kNames[7] = {"qw", "qx", "qy", "qz", "tx", "ty", "tz"};
  std::vector<std::string> tokens;
  std::string cur;
  for (char ch : text) {
    if (ch == ' ' || ch == ',' || ch == '\t' || ch == '\n' || ch == '\r') {
      if (!cur.empty()) tokens.push_back(cur);
      cur.clear();
    } else {
      cur += ch;
    }
  }
  if (!cur.empty()) tokens.push_back(cur);
  double v[7] = {0, 0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < tokens.size(); ++i) {
    double x = 0;
    if (!parse_double(tokens[i], &x)) {
      return invalid_argument(what + ": \"" + tokens[i] + "\" (value " + std::to_string(i) +
                              (i < 7 ? std::string(", ") + kNames[i] : std::string()) +
                              ") is not a number; expected 7 numbers qw qx qy qz tx ty tz separated by spaces or commas");
    }
    if (i < 7) v[i] = x;
  }
  if (tokens.size() != 7) {
    return invalid_argument(what + ": expected 7 numbers qw qx qy qz tx ty tz, found " + std::to_string(tokens.size()) +
                            " in \"" + text + "\"");
  }
  return pose_from_quaternion_checked(v, v + 4, what, out);
}

Status parse_pose_noise(const std::string& spec, PoseNoise* out) {
  static const char* const kForms =
      "accepted forms: none | barf:SIGMA | rot:DEG,trans:FRAC (either part may be omitted; rot:MIN-MAX draws the angle "
      "per view), each optionally followed by ,seed:N and ,views:N (only N views); e.g. barf:0.15, rot:10,trans:0.1,seed:3 "
      "or rot:10-40,views:3";
  const std::string head = "pose noise \"" + spec + "\": ";
  PoseNoise r;
  bool none = false, barf = false, rot = false, trans = false, seed = false, views = false;
  std::vector<std::string> tokens;
  size_t start = 0;
  for (;;) {
    const size_t comma = spec.find(',', start);
    tokens.push_back(trim(spec.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  for (const std::string& tok : tokens) {
    if (tok.empty()) return invalid_argument(head + "empty token; " + kForms);
    if (tok == "none") {
      if (none) return invalid_argument(head + "\"none\" given twice; " + kForms);
      none = true;
      continue;
    }
    const size_t colon = tok.find(':');
    if (colon == std::string::npos) return invalid_argument(head + "unknown token \"" + tok + "\"; " + kForms);
    const std::string key = trim(tok.substr(0, colon)), val = trim(tok.substr(colon + 1));
    bool* seen = key == "barf" ? &barf : key == "rot" ? &rot : key == "trans" ? &trans : key == "seed" ? &seed
               : key == "views" ? &views : nullptr;
    if (!seen) return invalid_argument(head + "unknown token \"" + tok + "\"; " + kForms);
    if (*seen) return invalid_argument(head + "\"" + key + "\" given twice; " + kForms);
    *seen = true;
    if (key == "seed" || key == "views") {
      errno = 0;
      char* end = nullptr;
      const unsigned long long s = val.empty() || val[0] == '-' || val[0] == '+' ? 0 : std::strtoull(val.c_str(), &end, 10);
      if (val.empty() || val[0] == '-' || val[0] == '+' || end != val.c_str() + val.size() || errno == ERANGE ||
          (key == "views" && s == 0)) {
        return invalid_argument(head + "bad token \"" + tok + "\": the " + (key == "seed" ? "seed" : "view count") + " must be a " +
                                (key == "seed" ? "non-negative" : "positive") + " integer; " + kForms);
      }
      if (key == "seed") r.seed = uint64_t(s);
      else r.views = size_t(s);
      continue;
    }
    if (key == "rot" && val.find('-', 1) != std::string::npos) {  // rot:MIN-MAX
      const size_t dash = val.find('-', 1);
      double lo = 0, hi = 0;
      if (!parse_double(trim(val.substr(0, dash)), &lo) || !parse_double(trim(val.substr(dash + 1)), &hi) || !std::isfinite(lo) ||
          !std::isfinite(hi) || lo < 0 || hi > 180 || !(lo < hi))
        return invalid_argument(head + "bad token \"" + tok + "\": a rotation range must be MIN-MAX with 0 <= MIN < MAX <= 180 deg; " + kForms);
      r.rotation_deg = lo;
      r.rotation_max_deg = hi;
      continue;
    }
    double x = 0;
    if (!parse_double(val, &x) || !std::isfinite(x)) {
      return invalid_argument(head + "bad token \"" + tok + "\": \"" + val + "\" is not a finite number; " + kForms);
    }
    if (x < 0) return invalid_argument(head + "bad token \"" + tok + "\": the value must be >= 0; " + kForms);
    if (key == "barf") r.sigma = x;
    if (key == "rot") {
      if (x > 180) return invalid_argument(head + "bad token \"" + tok + "\": the rotation must be in [0, 180] deg; " + kForms);
      r.rotation_deg = x;
    }
    if (key == "trans") r.translation_frac = x;
  }
  const int kinds = int(none) + int(barf) + int(rot || trans);
  if (kinds == 0) return invalid_argument(head + "no noise kind given; " + kForms);
  if (kinds > 1) return invalid_argument(head + "none, barf and rot/trans exclude each other; " + kForms);
  if (views && none) return invalid_argument(head + "\"views\" needs a noise kind; " + kForms);
  r.kind = none ? PoseNoise::kNone : barf ? PoseNoise::kBarf : PoseNoise::kFixed;
  *out = r;
  return Status::Ok();
}

std::string describe(const PoseNoise& noise) {
  const std::string seed = " (seed " + std::to_string(noise.seed) + ")";
  switch (noise.kind) {
    case PoseNoise::kBarf:
      return "barf sigma " + fmt(noise.sigma) + seed + (noise.views > 0 ? " on " + std::to_string(noise.views) + " views" : "");
    case PoseNoise::kFixed:
      return "rotation " + fmt(noise.rotation_deg) + (noise.rotation_max_deg > noise.rotation_deg ? "-" + fmt(noise.rotation_max_deg) : "") +
             " deg, translation " + fmt(noise.translation_frac) + " x radius" + seed +
             (noise.views > 0 ? " on " + std::to_string(noise.views) + " views" : "");
    case PoseNoise::kNone:
      break;
  }
  return "none";
}

void perturb_poses(const PoseNoise& noise, const double scene_centre[3], double scene_radius, Pose* poses, size_t n,
                   const uint8_t* eligible) {
  if (noise.kind == PoseNoise::kNone) return;
  // Only a subset (views > 0) needs a list of the chosen views: perturbing every view allocates
  // nothing (registration tests draw their starts inside allocation-counting scopes).
  std::vector<uint8_t> chosen;
  if (noise.views > 0) {
    chosen.assign(n, 0);
    std::vector<size_t> order;
    for (size_t i = 0; i < n; ++i)
      if (eligible == nullptr || eligible[i]) order.push_back(i);
    ViewRng pick(noise.seed, ~uint64_t(0));  // a stream no view uses
    for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[size_t(pick.uniform() * double(i)) % i]);
    for (size_t i = 0; i < std::min(order.size(), noise.views); ++i) chosen[order[i]] = 1;
  }
  for (size_t i = 0; i < n; ++i) {
    if (noise.views > 0 ? !chosen[i] : (eligible != nullptr && !eligible[i])) continue;
    ViewRng rng(noise.seed, uint64_t(i));
    double R[9], t[3];
    to_double(poses[i], R, t);
    double R2[9], t2[3];
    if (noise.kind == PoseNoise::kBarf) {
      // Normalised frame x_n = s (x - c): x_cam_n = s x_cam = R x_n + s (R c + t).
      // Noisy: T_n' = T_n Exp(xi) = (R E, R tE + t_n); back: t' = t_n' / s - R' c.
      const double s = kBarfRadius / scene_radius;
      double xi[6];
      for (double& x : xi) x = noise.sigma * rng.normal();
      double E[9], tE[3];
      se3_exp(xi, E, tE);
      double Rc[3], RtE[3];
      matvec(R, scene_centre, Rc);
      matvec(R, tE, RtE);
      matmul(R, E, R2);
      orthonormalise(R2);
      double R2c[3];
      matvec(R2, scene_centre, R2c);
      for (int k = 0; k < 3; ++k) {
        const double tn = s * (Rc[k] + t[k]) + RtE[k];
        t2[k] = tn / s - R2c[k];
      }
    } else {
      // Rotation by exactly rotation_deg about a random axis through the camera centre, then
      // the centre moved by exactly translation_frac * radius in a random direction.
      double axis[3], dir[3];
      rng.unit_vector(axis);
      rng.unit_vector(dir);
      const double deg = noise.rotation_max_deg > noise.rotation_deg
                             ? noise.rotation_deg + (noise.rotation_max_deg - noise.rotation_deg) * rng.uniform()
                             : noise.rotation_deg;
      const double angle = deg * kPi / 180;
      const double phi[3] = {angle * axis[0], angle * axis[1], angle * axis[2]};
      double E[9], C[3];
      so3_exp(phi, E);
      matmul(E, R, R2);
      orthonormalise(R2);
      matvec_t(R, t, C);
      const double d = noise.translation_frac * scene_radius;
      for (int k = 0; k < 3; ++k) C[k] = -C[k] + d * dir[k];
      matvec(R2, C, t2);
      for (int k = 0; k < 3; ++k) t2[k] = -t2[k];
    }
    store(R2, t2, &poses[i]);
  }
}

bool fit_sim3(const double* x, const double* y, const double* weights, size_t n, Sim3* out) {
  if (n < 3) return false;
  auto X = [&](size_t i) { return Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]); };
  auto Y = [&](size_t i) { return Eigen::Vector3d(y[3 * i], y[3 * i + 1], y[3 * i + 2]); };
  double wsum = 0;
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), my = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const double w = weights != nullptr ? weights[i] : 1.0;
    mx += w * X(i), my += w * Y(i), wsum += w;
  }
  if (!(wsum > 0)) return false;
  mx /= wsum, my /= wsum;
  Eigen::Matrix3d Sxy = Eigen::Matrix3d::Zero(), Sxx = Eigen::Matrix3d::Zero(), Syy = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const double w = weights != nullptr ? weights[i] : 1.0;
    const Eigen::Vector3d dx = X(i) - mx, dy = Y(i) - my;
    Sxy += w * dy * dx.transpose();
    Sxx += w * dx * dx.transpose();
    Syy += w * dy * dy.transpose();
  }
  Sxy /= wsum, Sxx /= wsum, Syy /= wsum;
  // Degenerate (coincident or collinear points in either set, or a rank-1 cross-covariance): the
  // rotation about the line is undetermined. A covariance's singular values are squared spreads;
  // the second spread must exceed 1e-5 of the set's length scale (spread + |mean|), 100x above the
  // ~1e-7 relative noise of centres computed from float poses.
  auto spread_2d = [](const Eigen::Matrix3d& S, const Eigen::Vector3d& mean) {
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(S).singularValues();
    const double length = std::sqrt(std::max(sv[0], 0.0)) + mean.norm();
    return length > 0 && std::sqrt(std::max(sv[1], 0.0)) > 1e-5 * length;
  };
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(Sxy, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  if (!(spread_2d(Sxx, mx) && spread_2d(Syy, my) && d[0] > 0 && d[1] > 1e-10 * d[0])) return false;
  Eigen::Vector3d S(1, 1, 1);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S[2] = -1;  // reflection fix
  const Eigen::Matrix3d R = svd.matrixU() * S.asDiagonal() * svd.matrixV().transpose();
  const double scale = d.dot(S) / Sxx.trace();
  const Eigen::Vector3d t = my - scale * R * mx;
  out->s = scale;
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) out->R[3 * r + k] = R(r, k);
    out->t[r] = t[r];
  }
  return true;
}

bool fit_sim3_trimmed(const double* x, const double* y, size_t n, Sim3* out, size_t* inliers) {
  Sim3 fit;
  if (!fit_sim3(x, y, nullptr, n, &fit)) return false;
  std::vector<double> weights(n, 1.0), residual(n);
  size_t used = n;
  for (int round = 0; round < 5; ++round) {
    for (size_t i = 0; i < n; ++i) {
      double m[3];
      transform_point(fit, x + 3 * i, m);
      residual[i] = std::hypot(m[0] - y[3 * i], m[1] - y[3 * i + 1], m[2] - y[3 * i + 2]);
    }
    std::vector<double> sorted = residual;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(n / 2), sorted.end());
    const double limit = 3 * sorted[n / 2];
    std::vector<double> next(n);
    size_t kept = 0;
    for (size_t i = 0; i < n; ++i) kept += (next[i] = residual[i] <= limit ? 1.0 : 0.0) > 0;
    if (kept == used && next == weights) break;  // the same set: converged
    if (kept < 3 || 2 * kept < n) break;
    Sim3 refit;
    if (!fit_sim3(x, y, next.data(), n, &refit)) break;
    fit = refit, weights = std::move(next), used = kept;
  }
  *out = fit;
  if (inliers != nullptr) *inliers = used;
  return true;
}

void transform_point(const Sim3& T, const double x[3], double y[3]) {
  double r[3];
  matvec(T.R, x, r);
  for (int i = 0; i < 3; ++i) y[i] = T.s * r[i] + T.t[i];
}

Pose transform_pose(const Sim3& T, const Pose& pose) {
  double R[9], t[3], Rn[9], Rt_t[3];
  to_double(pose, R, t);
  matmul_bt(R, T.R, Rn);  // R R_T^T
  matvec(Rn, T.t, Rt_t);
  double tn[3];
  for (int i = 0; i < 3; ++i) tn[i] = T.s * t[i] - Rt_t[i];
  orthonormalise(Rn);
  Pose out;
  store(Rn, tn, &out);
  return out;
}

Sim3 compose(const Sim3& b, const Sim3& a) {
  Sim3 c;
  c.s = b.s * a.s;
  matmul(b.R, a.R, c.R);
  transform_point(b, a.t, c.t);
  return c;
}

PoseErrors pose_errors(const Pose* estimated, const Pose* truth, size_t n, double scene_radius, bool align) {
  PoseErrors e;
  e.count = n;
  if (n == 0) return e;
  std::vector<Eigen::Vector3d> ce(n), ct(n);
  for (size_t i = 0; i < n; ++i) {
    centre(estimated[i], ce[i].data());
    centre(truth[i], ct[i].data());
  }
  // Sim(3) y ~ s R x + t with x the estimated centres, y the true ones.
  double s = 1;
  Eigen::Matrix3d Ra = Eigen::Matrix3d::Identity();
  Eigen::Vector3d ta = Eigen::Vector3d::Zero();
  Sim3 fit;
  if (align && fit_sim3_trimmed(ce[0].data(), ct[0].data(), n, &fit)) {
    s = fit.s;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) Ra(r, k) = fit.R[3 * r + k];
    ta = Eigen::Vector3d(fit.t[0], fit.t[1], fit.t[2]);
    e.aligned = true;
  }
  e.scale = s;
  e.rotation_deg.resize(n);
  e.translation.resize(n);
  double sum_r = 0, sum_t = 0, sum_t2 = 0, max_r = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d c = s * Ra * ce[i] + ta;
    // World-to-camera rotation of the aligned estimate: R_est Ra^T; in row-major arrays.
    double Rest[9], Rgt[9], tmp[3], Raa[9], Rx[9];
    to_double(estimated[i], Rest, tmp);
    to_double(truth[i], Rgt, tmp);
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) Raa[r * 3 + k] = Ra(r, k);
    matmul_bt(Rest, Raa, Rx);
    const double er = rotation_error_deg_d(Rx, Rgt);
    const double et = (c - ct[i]).norm();
    e.rotation_deg[i] = er;
    e.translation[i] = et;
    sum_r += er, sum_t += et, sum_t2 += et * et;
    max_r = std::max(max_r, er);
  }
  e.rotation_mean_deg = sum_r / double(n);
  e.rotation_median_deg = median(e.rotation_deg);
  e.rotation_max_deg = max_r;
  e.translation_mean = sum_t / double(n);
  e.translation_median = median(e.translation);
  e.translation_mean_frac = scene_radius > 0 ? e.translation_mean / scene_radius : 0;
  e.ate_rmse = std::sqrt(sum_t2 / double(n));
  return e;
}

void scene_frame(const Pose* poses, size_t n, double c[3], double* radius) {
  c[0] = c[1] = c[2] = 0;
  double r = 0;
  if (n > 0) {
    std::vector<double> cs(3 * n);
    for (size_t i = 0; i < n; ++i) {
      centre(poses[i], &cs[3 * i]);
      for (int k = 0; k < 3; ++k) c[k] += cs[3 * i + k];
    }
    for (int k = 0; k < 3; ++k) c[k] /= double(n);
    for (size_t i = 0; i < n; ++i) {
      const double d[3] = {cs[3 * i] - c[0], cs[3 * i + 1] - c[1], cs[3 * i + 2] - c[2]};
      r = std::max(r, norm3(d));
    }
  }
  *radius = std::max(r, 1e-9);
}

}  // namespace gs::pose
