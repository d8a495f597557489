// SPDX-License-Identifier: MIT
// Hand-built 3DGS PLY files (written byte by byte here, SH degree 0 and 3) parsed by gs_io and
// rendered: Gaussians must land where the pinhole model puts them, in the colour the 3DGS SH
// convention predicts for each view, with everything expected computed independently in this file.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/gaussians.h"
#include "gs/io/ply.h"
#include "gs/render.h"

namespace {

constexpr int kWidth = 128, kHeight = 96;
constexpr double kBackground[3] = {0.05, 0.1, 0.15};
// Renderer constants the expectations need, restated from the 3DGS rasteriser rather than taken
// from the project's headers: the alpha ceiling and the anti-aliasing dilation of the 2D covariance.
constexpr double kAlphaCeiling = 0.99;
constexpr double kDilationPx2 = 0.3;
// Colours are compared to 1e-4 absolute (1/40 of an 8-bit step). Everything on the renderer side
// is float32 (projection, conic inverse, SH sum, exp, blending: each with relative error of a few
// 1e-7 on values <= 1, the 2D covariances here being well conditioned), and the other Gaussians are
// far enough away that their alpha is below the 1/255 cut-off (checked) and they add nothing. The
// observed error is ~5e-7; a convention error moves some colour by > 0.02 (see the sensitivity
// check), 200 times the tolerance.
constexpr double kColourTol = 1e-4;

// One Gaussian as the test designs it; the world position comes from a view-1 pixel and depth.
struct Design {
  double px, py, depth;  // view-1 pixel position (continuous coordinates) and camera z
  float log_scale[3];
  float rot[4];          // (w, x, y, z), unnormalised as in real checkpoints
  float opacity_logit;
};

// ---------------------------------------------------------------------------------------------
// Small double-precision linear algebra, kept local so nothing here shares code with the renderer.
struct M3 {
  double a[9];
  double operator()(int r, int c) const { return a[r * 3 + c]; }
};
M3 mul(const M3& x, const M3& y) {
  M3 z{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) z.a[r * 3 + c] += x(r, k) * y(k, c);
  return z;
}
M3 transpose(const M3& x) {
  M3 z{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) z.a[r * 3 + c] = x(c, r);
  return z;
}
void apply(const M3& m, const double v[3], double out[3]) {
  for (int r = 0; r < 3; ++r) out[r] = m(r, 0) * v[0] + m(r, 1) * v[1] + m(r, 2) * v[2];
}

// Rotation of a (w, x, y, z) quaternion after normalising it.
M3 quat_rot(const float* q4) {
  double w = q4[0], x = q4[1], y = q4[2], z = q4[3];
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  w /= n, x /= n, y /= n, z /= n;
  return M3{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
             2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
             2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
}

// Rotation about a unit axis by an angle (Rodrigues), for building camera poses.
M3 axis_angle(double ax, double ay, double az, double angle) {
  const double n = std::sqrt(ax * ax + ay * ay + az * az);
  const float q[4] = {float(std::cos(angle / 2)), float(std::sin(angle / 2) * ax / n),
                      float(std::sin(angle / 2) * ay / n), float(std::sin(angle / 2) * az / n)};
  return quat_rot(q);
}

gs::Camera make_camera(const M3& R, const double C[3]) {
  gs::Camera cam;
  cam.intr = {140.0f, 136.0f, 61.7f, 50.3f, kWidth, kHeight};  // off-centre principal point, fx != fy
  double t[3];
  apply(R, C, t);
  for (int k = 0; k < 9; ++k) cam.pose.R[k] = float(R.a[k]);
  for (int k = 0; k < 3; ++k) cam.pose.t[k] = float(-t[k]);  // t = -R C
  return cam;
}

M3 cam_R(const gs::Camera& cam) {
  M3 R{};
  for (int k = 0; k < 9; ++k) R.a[k] = cam.pose.R[k];
  return R;
}

void cam_centre(const gs::Camera& cam, double C[3]) {  // C = -R^T t
  const M3 Rt = transpose(cam_R(cam));
  const double t[3] = {cam.pose.t[0], cam.pose.t[1], cam.pose.t[2]};
  apply(Rt, t, C);
  for (int k = 0; k < 3; ++k) C[k] = -C[k];
}

// Pinhole projection of a world point: u = fx x/z + cx, v = fy y/z + cy (pixel centres at +0.5).
void project(const gs::Camera& cam, const float* mean, double uv[2], double cam_pt[3]) {
  const double m[3] = {mean[0], mean[1], mean[2]};
  apply(cam_R(cam), m, cam_pt);
  for (int k = 0; k < 3; ++k) cam_pt[k] += cam.pose.t[k];
  uv[0] = cam.intr.fx * cam_pt[0] / cam_pt[2] + cam.intr.cx;
  uv[1] = cam.intr.fy * cam_pt[1] / cam_pt[2] + cam.intr.cy;
}

// EWA splat falloff G at a pixel centre: Sigma2D = J W Sigma W^T J^T + dilation, J the pinhole
// Jacobian at the camera-space mean, W the world-to-camera rotation, Sigma = R S S^T R^T.
double falloff(const gs::Camera& cam, const float* mean, const float* log_scale, const float* rot, int px, int py) {
  double uv[2], t[3];
  project(cam, mean, uv, t);
  const M3 Rq = quat_rot(rot);
  M3 S2{};
  for (int k = 0; k < 3; ++k) S2.a[k * 4] = std::exp(2.0 * double(log_scale[k]));
  const M3 W = cam_R(cam);
  const M3 sig_cam = mul(mul(W, mul(mul(Rq, S2), transpose(Rq))), transpose(W));
  const double fx = cam.intr.fx, fy = cam.intr.fy;
  const double J[2][3] = {{fx / t[2], 0, -fx * t[0] / (t[2] * t[2])}, {0, fy / t[2], -fy * t[1] / (t[2] * t[2])}};
  double s2[2][2] = {{0, 0}, {0, 0}};
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) s2[r][c] += J[r][i] * sig_cam(i, j) * J[c][j];
  s2[0][0] += kDilationPx2;
  s2[1][1] += kDilationPx2;
  const double det = s2[0][0] * s2[1][1] - s2[0][1] * s2[1][0];
  const double dx = uv[0] - (px + 0.5), dy = uv[1] - (py + 0.5);
  const double q = (s2[1][1] * dx * dx - 2 * s2[0][1] * dx * dy + s2[0][0] * dy * dy) / det;
  return std::exp(-0.5 * q);
}

// Real SH basis in the 3DGS order and sign convention, degrees 0..3, at a unit direction.
void sh_basis(double x, double y, double z, double b[16]) {
  const double C0 = 0.28209479177387814, C1 = 0.4886025119029199;
  const double C2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
                        0.5462742152960396};
  const double C3[7] = {-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                        -0.4570457994644658, 1.445305721320277, -0.5900435899266435};
  const double xx = x * x, yy = y * y, zz = z * z;
  b[0] = C0;
  b[1] = -C1 * y;
  b[2] = C1 * z;
  b[3] = -C1 * x;
  b[4] = C2[0] * x * y;
  b[5] = C2[1] * y * z;
  b[6] = C2[2] * (2 * zz - xx - yy);
  b[7] = C2[3] * x * z;
  b[8] = C2[4] * (xx - yy);
  b[9] = C3[0] * y * (3 * xx - yy);
  b[10] = C3[1] * x * y * z;
  b[11] = C3[2] * y * (4 * zz - xx - yy);
  b[12] = C3[3] * z * (2 * zz - 3 * xx - 3 * yy);
  b[13] = C3[4] * x * (4 * zz - xx - yy);
  b[14] = C3[5] * z * (xx - yy);
  b[15] = C3[6] * x * (xx - 3 * yy);
}

// Expected RGB of a Gaussian seen from camera centre C: 0.5 + sum_k Y_k(dir) coeff_k, clamped at 0
// from below, dir = normalise(mean - C). coeff(k, c) reads the design's coefficients.
template <class Coeff>
void sh_colour(const float* mean, const double C[3], int degree, Coeff coeff, double sign, double rgb[3]) {
  double d[3] = {mean[0] - C[0], mean[1] - C[1], mean[2] - C[2]};
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (double& v : d) v *= sign / n;
  double b[16];
  sh_basis(d[0], d[1], d[2], b);
  const int K = (degree + 1) * (degree + 1);
  for (int c = 0; c < 3; ++c) {
    double acc = 0.5;
    for (int k = 0; k < K; ++k) acc += b[k] * coeff(k, c);
    rgb[c] = std::max(acc, 0.0);
  }
}

void put_f32(std::vector<uint8_t>* out, float f) {  // little-endian regardless of the host
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  for (int i = 0; i < 4; ++i) out->push_back(uint8_t(bits >> (8 * i)));
}

// The scene: six Gaussians at distinct view-1 pixels, >= 20 px apart; #0 has its red channel far
// below zero (tests the clamp), #4 is semi-transparent (tests alpha = o G without the ceiling).
struct Scene {
  std::vector<Design> design;
  std::vector<float> means;  // [N, 3] world, as stored in the file
  std::vector<float> sh;     // [N, 16, 3] the design's coefficients (degree 3), coefficient-major
  gs::Camera view1, view2;
};

Scene make_scene() {
  Scene s;
  // View 1: a rotated camera away from the origin. Pixel positions are exact pixel centres so that
  // the projected mean sits on one (G = 1 up to float rounding of the stored position).
  const double C1[3] = {0.3, -0.2, -0.5};
  s.view1 = make_camera(axis_angle(0.2, 1.0, 0.1, 0.15), C1);
  s.design = {
      {20.5, 18.5, 3.2, {std::log(0.035f), std::log(0.025f), std::log(0.030f)}, {1.0f, 0.2f, -0.3f, 0.1f}, 6.0f},
      {62.5, 24.5, 3.8, {std::log(0.030f), std::log(0.040f), std::log(0.028f)}, {0.7f, -0.1f, 0.4f, 0.3f}, 6.5f},
      {104.5, 20.5, 3.5, {std::log(0.028f), std::log(0.028f), std::log(0.036f)}, {1.3f, 0.0f, 0.0f, 0.5f}, 7.0f},
      {28.5, 70.5, 4.1, {std::log(0.040f), std::log(0.030f), std::log(0.030f)}, {0.2f, 0.9f, 0.1f, -0.2f}, 5.5f},
      {74.5, 66.5, 3.0, {std::log(0.025f), std::log(0.030f), std::log(0.022f)}, {1.0f, 0.0f, 0.0f, 0.0f}, 1.5f},
      {110.5, 78.5, 3.6, {std::log(0.032f), std::log(0.030f), std::log(0.034f)}, {0.5f, 0.5f, -0.5f, 0.5f}, 6.0f},
  };
  const M3 Rt1 = transpose(cam_R(s.view1));
  double C[3];
  cam_centre(s.view1, C);
  for (const Design& d : s.design) {
    const double ray[3] = {(d.px - s.view1.intr.cx) / s.view1.intr.fx * d.depth,
                           (d.py - s.view1.intr.cy) / s.view1.intr.fy * d.depth, d.depth};
    double w[3];
    apply(Rt1, ray, w);  // world = R^T x_cam + C
    for (int k = 0; k < 3; ++k) s.means.push_back(float(w[k] + C[k]));
  }
  // SH: DC terms give base colours in about [0.2, 0.8]; higher orders +-0.12 so colours stay in
  // (0, 1) while the view change moves them by a few hundredths.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> dc(-1.0f, 1.0f), rest(-0.12f, 0.12f);
  for (size_t i = 0; i < s.design.size(); ++i)
    for (int k = 0; k < 16; ++k)
      for (int c = 0; c < 3; ++c) s.sh.push_back(k == 0 ? dc(rng) : rest(rng));
  s.sh[0] = -2.5f;  // Gaussian 0, red DC: 0.5 + C0 * -2.5 = -0.21, so red is clamped to 0 in every view
  // View 2: the camera centre moved 0.9 sideways and 0.3 up, turned to look at the scene centroid.
  double centroid[3] = {0, 0, 0};
  for (size_t i = 0; i < s.design.size(); ++i)
    for (int k = 0; k < 3; ++k) centroid[k] += s.means[3 * i + size_t(k)] / double(s.design.size());
  const double C2[3] = {C[0] + 0.9, C[1] - 0.3, C[2] + 0.1};
  double z[3] = {centroid[0] - C2[0], centroid[1] - C2[1], centroid[2] - C2[2]};
  double zn = std::sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  for (double& v : z) v /= zn;
  const double up[3] = {Rt1(0, 1), Rt1(1, 1), Rt1(2, 1)};  // view 1's y (down) axis in world
  double x[3] = {up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]};
  const double xn = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (double& v : x) v /= xn;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  const M3 R2{{x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]}};  // rows: camera axes in world
  s.view2 = make_camera(R2, C2);
  return s;
}

// 3DGS PLY bytes for the scene at an SH degree: ASCII header, then per vertex x y z nx ny nz
// f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3 as little-endian float32, f_rest channel-major.
std::vector<uint8_t> build_ply(const Scene& s, int degree) {
  const int K = (degree + 1) * (degree + 1);
  const size_t n = s.design.size();
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment hand-built by test_ply_render\n";
  h += "element vertex " + std::to_string(n) + "\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"}) h += std::string("property float ") + p + "\n";
  for (int j = 0; j < 3 * (K - 1); ++j) h += "property float f_rest_" + std::to_string(j) + "\n";
  h += "property float opacity\n";
  for (int j = 0; j < 3; ++j) h += "property float scale_" + std::to_string(j) + "\n";
  for (int j = 0; j < 4; ++j) h += "property float rot_" + std::to_string(j) + "\n";
  h += "end_header\n";
  std::vector<uint8_t> out(h.begin(), h.end());
  for (size_t i = 0; i < n; ++i) {
    const Design& d = s.design[i];
    for (int k = 0; k < 3; ++k) put_f32(&out, s.means[3 * i + size_t(k)]);
    for (int k = 0; k < 3; ++k) put_f32(&out, 0.0f);
    for (int c = 0; c < 3; ++c) put_f32(&out, s.sh[i * 48 + size_t(c)]);
    for (int c = 0; c < 3; ++c)  // channel-major: all R coefficients 1..K-1, then G, then B
      for (int k = 1; k < K; ++k) put_f32(&out, s.sh[(i * 16 + size_t(k)) * 3 + size_t(c)]);
    put_f32(&out, d.opacity_logit);
    for (float v : d.log_scale) put_f32(&out, v);
    for (float v : d.rot) put_f32(&out, v);
  }
  return out;
}

struct Render {
  std::vector<float> rgb;
  std::vector<int> dominant;  // [H, W]
};

Render render(const gs::GaussianCloud& cloud, const std::vector<float>& opacities, const gs::Camera& cam) {
  gs::GaussianParams p;
  p.count = cloud.size();
  p.means = cloud.means.data();
  p.log_scales = cloud.log_scales.data();
  p.quats = cloud.quats.data();
  p.opacities = opacities.data();
  p.sh = cloud.sh.data();
  p.sh_degree = cloud.sh_degree;
  gs::RenderCapacity cap;
  cap.max_gaussians = cloud.size();
  cap.max_width = kWidth;
  cap.max_height = kHeight;
  gs::Renderer r;
  Render out;
  const gs::Status init = r.init(cap, nullptr);
  REQUIRE_MESSAGE(init.ok(), init.to_string());
  gs::RenderOptions opt;
  for (int c = 0; c < 3; ++c) opt.background[c] = float(kBackground[c]);
  out.rgb.assign(size_t(kWidth) * kHeight * 3, -1.0f);
  const gs::Status st = r.forward(cam, p, opt, out.rgb.data());
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x) out.dominant.push_back(r.dominant_gaussian(x, y));
  return out;
}

// A Gaussian's colour recovered from its centre pixel by undoing the blend,
// (pixel - (1 - alpha) bg) / alpha, and that alpha.
struct Recovered {
  std::array<double, 3> rgb;
  double alpha;
};

// Per Gaussian in one view: checks position and colour, returns the recovered colours.
std::vector<Recovered> check_view(const Scene& s, const gs::GaussianCloud& cloud, const std::vector<float>& opacities,
                                  const gs::Camera& cam, const char* view_name, double* max_err) {
  const Render img = render(cloud, opacities, cam);
  double C[3];
  cam_centre(cam, C);
  std::vector<Recovered> recovered;
  // Precondition of the tolerance argument: at each Gaussian's centre pixel, every other one's
  // alpha o G is below the rasteriser's 1/255 cut-off, so it is skipped and adds nothing.
  for (size_t i = 0; i < cloud.size(); ++i) {
    double uv[2], t[3];
    project(cam, &s.means[3 * i], uv, t);
    for (size_t j = 0; j < cloud.size(); ++j) {
      if (j == i) continue;
      const double G = falloff(cam, &s.means[3 * j], cloud.log_scales.data() + 3 * j, cloud.quats.data() + 4 * j,
                               int(std::floor(uv[0])), int(std::floor(uv[1])));
      REQUIRE(double(opacities[j]) * G < 1.0 / 255.0);
    }
  }
  const int K = gs::sh_coeff_count(cloud.sh_degree);
  for (size_t i = 0; i < cloud.size(); ++i) {
    CAPTURE(view_name);
    CAPTURE(cloud.sh_degree);
    CAPTURE(i);
    const float* mean = &s.means[3 * i];
    double uv[2], t[3];
    project(cam, mean, uv, t);
    const int px = int(std::floor(uv[0])), py = int(std::floor(uv[1]));
    REQUIRE(px >= 8);  // the test's own precondition: every Gaussian well inside both views
    REQUIRE(py >= 8);
    REQUIRE(px < kWidth - 8);
    REQUIRE(py < kHeight - 8);

    // (a) Position: the projection's pixel is the Gaussian's, and its brightest pixel (its alpha
    // peak: one Gaussian has one colour) is within 1 px of it.
    CHECK(img.dominant[size_t(py) * kWidth + size_t(px)] == int(i));
    int best_x = -1, best_y = -1;
    double best = -1;
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) {
        const size_t o = size_t(y) * kWidth + size_t(x);
        if (img.dominant[o] != int(i)) continue;
        const double lum = img.rgb[3 * o] + img.rgb[3 * o + 1] + img.rgb[3 * o + 2];
        if (lum > best) best = lum, best_x = x, best_y = y;
      }
    CHECK(std::abs(best_x - px) <= 1);
    CHECK(std::abs(best_y - py) <= 1);

    // (b) Colour at the projection's pixel: alpha c + (1 - alpha) bg, alpha = min(0.99, o G).
    auto coeff = [&](int k, int c) { return double(cloud.sh[(i * size_t(K) + size_t(k)) * 3 + size_t(c)]); };
    double rgb[3];
    sh_colour(mean, C, cloud.sh_degree, coeff, 1.0, rgb);
    const double G = falloff(cam, mean, cloud.log_scales.data() + 3 * i, cloud.quats.data() + 4 * i, px, py);
    const double alpha = std::min(kAlphaCeiling, double(opacities[i]) * G);
    const float* got = &img.rgb[3 * (size_t(py) * kWidth + size_t(px))];
    Recovered rec{{}, alpha};
    for (int c = 0; c < 3; ++c) {
      const double want = alpha * rgb[c] + (1 - alpha) * kBackground[c];
      CAPTURE(c);
      CHECK(std::abs(double(got[c]) - want) <= kColourTol);
      *max_err = std::max(*max_err, std::abs(double(got[c]) - want));
      rec.rgb[size_t(c)] = (double(got[c]) - (1 - alpha) * kBackground[c]) / alpha;
    }
    recovered.push_back(rec);
  }
  return recovered;
}

// Tolerance on the difference of two recovered colours: each pixel is within kColourTol, undoing
// the blend divides that by alpha, and the difference adds the two.
double recovered_tol(const Recovered& a, const Recovered& b) { return kColourTol / a.alpha + kColourTol / b.alpha; }

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

gs::GaussianCloud parse_checked(const std::vector<uint8_t>& bytes, const Scene& s, int degree) {
  auto parsed = gs::io::parse_splat_ply(bytes.data(), bytes.size(), "hand-built.ply");
  REQUIRE_MESSAGE(parsed.ok(), parsed.status().to_string());
  gs::GaussianCloud cloud = std::move(parsed.value());
  REQUIRE(cloud.size() == s.design.size());
  REQUIRE(cloud.sh_degree == degree);
  REQUIRE(cloud.sh.size() == s.design.size() * size_t(gs::sh_coeff_count(degree)) * 3);
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) CHECK(cloud.means[3 * i + size_t(k)] == s.means[3 * i + size_t(k)]);
    CHECK(cloud.opacity_logits[i] == s.design[i].opacity_logit);
  }
  return cloud;
}

}  // namespace

TEST_CASE("ply_render: hand-built 3DGS PLY files render at the projected positions in the SH colours") {
  const Scene s = make_scene();
  // View 1 puts every projected mean on a pixel centre, so there G = 1 and the opaque Gaussians
  // (logit >= 5.5, o >= 0.9959) blend at exactly the 0.99 ceiling: the view-1 colour checks then do
  // not depend on this file's EWA falloff at all.
  for (size_t i = 0; i < s.design.size(); ++i) {
    double uv[2], t[3];
    project(s.view1, &s.means[3 * i], uv, t);
    CHECK(std::abs(uv[0] - s.design[i].px) < 1e-4);
    CHECK(std::abs(uv[1] - s.design[i].py) < 1e-4);
  }
  double max_err = 0;
  std::vector<Recovered> deg3_view[2];
  for (int degree : {0, 3}) {
    const std::vector<uint8_t> bytes = build_ply(s, degree);
    const gs::GaussianCloud cloud = parse_checked(bytes, s, degree);
    // The reader hands back what the file says; activation is the caller's: opacity = sigmoid(logit).
    std::vector<float> opacities;
    for (float l : cloud.opacity_logits) opacities.push_back(float(sigmoid(double(l))));
    const auto v1 = check_view(s, cloud, opacities, s.view1, "view 1", &max_err);
    const auto v2 = check_view(s, cloud, opacities, s.view2, "view 2", &max_err);
    if (degree == 0) {
      // Degree 0 has no view dependence: the unblended colour is the same from both views.
      for (size_t i = 0; i < v1.size(); ++i)
        for (size_t c = 0; c < 3; ++c) CHECK(std::abs(v1[i].rgb[c] - v2[i].rgb[c]) <= recovered_tol(v1[i], v2[i]));
    } else {
      deg3_view[0] = v1;
      deg3_view[1] = v2;
    }
  }

  // Degree 3: the change between the views is what the SH predicts, and big enough to matter.
  double C1[3], C2[3];
  cam_centre(s.view1, C1);
  cam_centre(s.view2, C2);
  double largest_change = 0;
  for (size_t i = 0; i < s.design.size(); ++i) {
    auto coeff = [&](int k, int c) { return double(s.sh[(i * 16 + size_t(k)) * 3 + size_t(c)]); };
    double a[3], b[3];
    sh_colour(&s.means[3 * i], C1, 3, coeff, 1.0, a);
    sh_colour(&s.means[3 * i], C2, 3, coeff, 1.0, b);
    for (size_t c = 0; c < 3; ++c) {
      CAPTURE(i);
      CAPTURE(c);
      const double predicted = b[c] - a[c], measured = deg3_view[1][i].rgb[c] - deg3_view[0][i].rgb[c];
      CHECK(std::abs(measured - predicted) <= recovered_tol(deg3_view[0][i], deg3_view[1][i]));
      largest_change = std::max(largest_change, std::abs(predicted));
    }
  }
  CHECK(largest_change > 0.02);  // the view change is at least 200x the tolerance on some channel

  // Sensitivity: the cheapest convention mistakes (f_rest read coefficient-major instead of
  // channel-major; the view direction reversed) would move some colour by far more than the
  // tolerance, so passing the checks above means the conventions are right.
  double transposed = 0, reversed = 0;
  for (size_t i = 0; i < s.design.size(); ++i) {
    const float* file = &s.sh[i * 48];  // design order [k][c]
    auto right = [&](int k, int c) { return double(file[k * 3 + c]); };
    // Channel-major f_rest read as if it were [k][c]: rest index j = c * 15 + (k - 1) reinterpreted.
    auto wrong = [&](int k, int c) {
      if (k == 0) return double(file[c]);
      const int j = (k - 1) * 3 + c, cc = j / 15, kk = j % 15 + 1;
      return double(file[kk * 3 + cc]);
    };
    double a[3], b[3], r[3];
    sh_colour(&s.means[3 * i], C1, 3, right, 1.0, a);
    sh_colour(&s.means[3 * i], C1, 3, wrong, 1.0, b);
    sh_colour(&s.means[3 * i], C1, 3, right, -1.0, r);
    for (int c = 0; c < 3; ++c) {
      transposed = std::max(transposed, std::abs(a[c] - b[c]));
      reversed = std::max(reversed, std::abs(a[c] - r[c]));
    }
  }
  CHECK(transposed > 0.02);
  CHECK(reversed > 0.02);
  std::printf("ply_render: max colour error %.2e (tolerance %.0e), largest predicted view change %.4f, "
              "sensitivity: transposed f_rest %.4f, reversed view direction %.4f\n",
              max_err, kColourTol, largest_change, transposed, reversed);
}

TEST_CASE("ply_render: read_splat_ply reads the same cloud from disk") {
  // The file path variant of the reader, on the degree-3 bytes written to a temporary file.
  const Scene s = make_scene();
  const std::vector<uint8_t> bytes = build_ply(s, 3);
  const std::string path = std::string(std::getenv("TMPDIR") ? std::getenv("TMPDIR") : "/tmp") +
                           "/hbgs_test_ply_render_" + std::to_string(uint64_t(std::random_device()())) + ".ply";
  FILE* f = std::fopen(path.c_str(), "wb");
  REQUIRE(f != nullptr);
  REQUIRE(std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
  REQUIRE(std::fclose(f) == 0);
  auto from_disk = gs::io::read_splat_ply(path);
  std::remove(path.c_str());
  REQUIRE_MESSAGE(from_disk.ok(), from_disk.status().to_string());
  auto from_memory = gs::io::parse_splat_ply(bytes.data(), bytes.size(), "memory");
  REQUIRE(from_memory.ok());
  CHECK(from_disk->sh_degree == 3);
  CHECK(from_disk->means == from_memory->means);
  CHECK(from_disk->log_scales == from_memory->log_scales);
  CHECK(from_disk->quats == from_memory->quats);
  CHECK(from_disk->opacity_logits == from_memory->opacity_logits);
  CHECK(from_disk->sh == from_memory->sh);
}
