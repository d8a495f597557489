// SPDX-License-Identifier: MIT
// Forward-mode pose Jacobian of the renderer (ALGORITHM.md Part A item 14, last paragraph):
// - the double reference gs::ref::render_pose_jacobian against central finite differences of
//   gs::ref::render_fwd with the pose perturbed by Exp(h xi) T for each unit twist, with the
//   forward's signature as the boundary band (STYLE.md 8; see test_grad_fd.cpp);
// - sum over pixels of J^T v_rgb against the already FD-checked backward's v_pose;
// - gs::Renderer::pose_normal_equations (float) against normal equations built in double from the
//   reference Jacobian, with and without mask and Huber weights; thread-count invariance (bit
//   for bit) and zero allocations after the first call.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/render_ref.h"
#include "gs/simd/ref.h"
#include "support/alloc_counter.h"
#include "support/random_scene.h"

namespace {

using gs::ref::Forward;
using gs::ref::Scene;
using gs::ref::View;

// SE(3) exponential of xi = (rho, phi): R = Exp(phi), t = V(phi) rho, V = I + b K + c K^2.
void se3_exp(const double xi[6], double R[9], double t[3]) {
  const double* rho = xi;
  const double* phi = xi + 3;
  gs::test::so3_exp(phi, R);
  const double th2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2], th = std::sqrt(th2);
  const double b = th < 1e-4 ? 0.5 - th2 / 24 : (1 - std::cos(th)) / th2;
  const double c = th < 1e-4 ? 1.0 / 6 - th2 / 120 : (th - std::sin(th)) / (th2 * th);
  const double K[9] = {0, -phi[2], phi[1], phi[2], 0, -phi[0], -phi[1], phi[0], 0};
  double V[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double k2 = 0;
      for (int q = 0; q < 3; ++q) k2 += K[i * 3 + q] * K[q * 3 + j];
      V[i * 3 + j] = (i == j ? 1.0 : 0.0) + b * K[i * 3 + j] + c * k2;
    }
  for (int i = 0; i < 3; ++i) t[i] = V[i * 3] * rho[0] + V[i * 3 + 1] * rho[1] + V[i * 3 + 2] * rho[2];
}

// The view with its world-to-camera transform replaced by Exp(xi) T (left perturbation).
View<double> perturbed(const View<double>& v, const double xi[6]) {
  double dR[9], dt[3];
  se3_exp(xi, dR, dt);
  View<double> out = v;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      out.R[r * 3 + c] = dR[r * 3] * v.R[c] + dR[r * 3 + 1] * v.R[3 + c] + dR[r * 3 + 2] * v.R[6 + c];
    out.t[r] = dR[r * 3] * v.t[0] + dR[r * 3 + 1] * v.t[1] + dR[r * 3 + 2] * v.t[2] + dt[r];
  }
  return out;
}

struct Case {
  View<double> view;
  Scene<double> scene;
};

// saturate: every third Gaussian gets opacity 0.999, so alpha = o G hits the 0.99 clamp near its
// centre (uniform opacities in [0.6, 1] almost never do).
Case make_case(uint64_t seed, const gs::test::SceneSpec& spec, bool saturate = false) {
  std::mt19937_64 rng(seed);
  Case c;
  c.view = gs::test::random_view(rng, spec.width, spec.height);
  c.view.background[0] = 0.2;
  c.view.background[1] = 0.1;
  c.view.background[2] = 0.4;
  c.scene = gs::test::random_scene(rng, c.view, spec);
  if (saturate)
    for (size_t i = 0; i < c.scene.n; i += 3) c.scene.opacities[i] = 0.999;
  return c;
}

// 4-point central differences, h = 1e-6 (rad or world units; ~4e-5 px of motion at these focal
// lengths), falling back to h / 4 when the +-2h forwards change a discrete decision (signature).
// Rounding noise of the double forward is ~1e-15 per pixel value, so ~1e-9 of derivative at
// h = 2.5e-7; truncation is O(h^4). Tolerance: relative 1e-5 of max(|fd|, |J|) plus an absolute
// 1e-8 for that noise; the analytic Jacobian is exact, so anything above is a bug.
constexpr double kSteps[2] = {1e-6, 2.5e-7};
constexpr double kRelTol = 1e-5;
constexpr double kAbsTol = 1e-8;

struct FdTally {
  int probes = 0, flipped = 0, failures = 0;
  size_t checked = 0;  // Jacobian entries with |J| > 1e-3 compared
  double worst = 0;    // relative error over those entries
};

void check_fd(uint64_t seed, const gs::test::SceneSpec& spec, FdTally* total, bool saturate = false) {
  CAPTURE(seed);
  const Case cs = make_case(seed, spec, saturate);
  const Forward<double> f0 = gs::ref::render_fwd(cs.scene, cs.view);
  const std::vector<double> J = gs::ref::render_pose_jacobian(cs.scene, cs.view, f0);
  REQUIRE(J.size() == f0.rgb.size() * 6);
  FdTally t;
  for (int k = 0; k < 6; ++k) {
    ++t.probes;
    bool done = false;
    for (double h : kSteps) {
      std::vector<double> img[4];
      bool flip = false;
      const double offsets[4] = {-2 * h, -h, h, 2 * h};
      for (int q = 0; q < 4 && !flip; ++q) {
        double xi[6] = {0, 0, 0, 0, 0, 0};
        xi[k] = offsets[q];
        const Forward<double> f = gs::ref::render_fwd(cs.scene, perturbed(cs.view, xi));
        flip = f.signature != f0.signature;
        img[q] = f.rgb;
      }
      if (flip) continue;
      for (size_t e = 0; e < f0.rgb.size(); ++e) {
        const double fd = (8 * (img[2][e] - img[1][e]) - (img[3][e] - img[0][e])) / (12 * h);
        const double an = J[e * 6 + size_t(k)];
        const double diff = std::fabs(fd - an);
        const double scale = std::max(std::fabs(fd), std::fabs(an));
        if (scale > 1e-3) {
          ++t.checked;
          t.worst = std::max(t.worst, diff / scale);
        }
        if (diff > kRelTol * scale + kAbsTol) {
          if (++t.failures <= 5) MESSAGE("twist " << k << " entry " << e << ": fd " << fd << " vs J " << an);
        }
      }
      done = true;
      break;
    }
    if (!done) ++t.flipped;
  }
  MESSAGE("seed " << seed << ": " << t.probes << " twists, " << t.flipped << " in the boundary band, " << t.checked
                  << " entries with |J| > 1e-3, worst relative error " << t.worst);
  CHECK(t.failures == 0);
  CHECK(t.flipped <= 1);
  CHECK(t.checked >= 100);
  total->probes += t.probes;
  total->flipped += t.flipped;
  total->failures += t.failures;
  total->checked += t.checked;
  total->worst = std::max(total->worst, t.worst);
}

// v_rgb-weighted sum of the Jacobian over pixels vs the backward's v_pose (both double).
void check_backward_consistency(uint64_t seed, const gs::test::SceneSpec& spec, bool saturate = false) {
  CAPTURE(seed);
  const Case cs = make_case(seed, spec, saturate);
  const Forward<double> f0 = gs::ref::render_fwd(cs.scene, cs.view);
  const std::vector<double> J = gs::ref::render_pose_jacobian(cs.scene, cs.view, f0);
  std::mt19937_64 rng(seed * 31 + 7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> v(f0.rgb.size());
  for (double& x : v) x = u(rng);
  const gs::ref::Grads<double> g = gs::ref::render_bwd(cs.scene, cs.view, f0, v.data());
  double jtv[6] = {0, 0, 0, 0, 0, 0};
  for (size_t e = 0; e < v.size(); ++e)
    for (int k = 0; k < 6; ++k) jtv[k] += J[e * 6 + size_t(k)] * v[e];
  double scale = 0;
  for (double x : g.v_pose) scale = std::max(scale, std::fabs(x));
  REQUIRE(scale > 1e-3);
  double worst = 0;
  for (int k = 0; k < 6; ++k) {
    INFO("twist " << k << ": J^T v " << jtv[k] << " vs backward " << g.v_pose[k]);
    const double err = std::fabs(jtv[k] - g.v_pose[k]) / scale;
    worst = std::max(worst, err);
    CHECK(err <= 1e-8);
  }
  MESSAGE("seed " << seed << ": J^T v vs backward v_pose, worst relative error " << worst);
}

}  // namespace

TEST_CASE("pose jacobian: reference matches central finite differences") {
  FdTally total;
  gs::test::SceneSpec spec;
  for (uint64_t seed : {101, 102}) check_fd(seed, spec, &total);
  gs::test::SceneSpec edge;  // half the Gaussians beyond the image edge: the tan clamp is active
  edge.frac_outside = 0.5;
  edge.count = 16;
  check_fd(111, edge, &total);
  check_fd(121, gs::test::opaque_stack_spec(), &total, true);
  gs::test::SceneSpec odd;  // image size not a multiple of the tile size
  odd.width = 37;
  odd.height = 19;
  check_fd(131, odd, &total);
  MESSAGE("all scenes: " << total.checked << " entries, worst relative error " << total.worst << ", "
                         << total.flipped << " of " << total.probes << " twists in the boundary band");
}

TEST_CASE("pose jacobian: the edge and opaque scenes exercise the tan clamp and the alpha clamp") {
  // Guards the FD test above against silently losing its hard cases.
  gs::test::SceneSpec edge;
  edge.frac_outside = 0.5;
  edge.count = 16;
  const Case ce = make_case(111, edge);
  int clamped_visible = 0;
  {
    const Forward<double> f = gs::ref::render_fwd(ce.scene, ce.view);
    const View<double>& v = ce.view;
    const double lim_xp = (v.width - v.cx) / v.fx + 0.3 * 0.5 * v.width / v.fx;
    const double lim_xn = v.cx / v.fx + 0.3 * 0.5 * v.width / v.fx;
    for (size_t i = 0; i < ce.scene.n; ++i) {
      if (f.radii[i] == 0) continue;
      double m[3];
      for (int r = 0; r < 3; ++r)
        m[r] = v.R[r * 3] * ce.scene.means[3 * i] + v.R[r * 3 + 1] * ce.scene.means[3 * i + 1] +
               v.R[r * 3 + 2] * ce.scene.means[3 * i + 2] + v.t[r];
      if (m[0] / m[2] > lim_xp || m[0] / m[2] < -lim_xn) ++clamped_visible;
    }
  }
  CHECK(clamped_visible > 0);
  const Case co = make_case(121, gs::test::opaque_stack_spec(), true);
  const Forward<double> f = gs::ref::render_fwd(co.scene, co.view);
  int early_stops = 0;
  for (double T : f.final_T) early_stops += T < 1e-3 ? 1 : 0;
  int alpha_clamps = 0;  // (pixel, splat) pairs blended with alpha clamped at 0.99
  const int tiles_x = (co.view.width + gs::simd::kTileSize - 1) / gs::simd::kTileSize;
  for (int y = 0; y < co.view.height; ++y)
    for (int x = 0; x < co.view.width; ++x) {
      const int tile = (y / gs::simd::kTileSize) * tiles_x + x / gs::simd::kTileSize;
      const size_t pix = size_t(y) * co.view.width + x;
      for (int32_t k = 0; k < f.last[pix]; ++k) {
        gs::simd::SplatEval<double> e;
        if (gs::simd::eval_splat_ref(&f.splats[(f.tile_offsets[tile] + k) * gs::simd::kSplatStride], x + 0.5, y + 0.5,
                                     &e))
          alpha_clamps += e.clamped ? 1 : 0;
      }
    }
  CHECK(early_stops > 0);
  CHECK(alpha_clamps > 0);
}

TEST_CASE("pose jacobian: J transpose v equals the backward pose gradient") {
  gs::test::SceneSpec spec;
  check_backward_consistency(201, spec);
  gs::test::SceneSpec edge;
  edge.frac_outside = 0.5;
  edge.count = 16;
  check_backward_consistency(211, edge);
  check_backward_consistency(221, gs::test::opaque_stack_spec(), true);
}

namespace {

struct Problem {
  Scene<float> sf;
  View<float> vf;
  Scene<double> sd;  // exactly the float scene, in double
  View<double> vd;
  std::vector<float> target, mask;
};

// A scene (every fourth Gaussian nearly opaque, so the 0.99 alpha clamp and early stops occur), a
// target rendered from a slightly different pose plus noise and 5% outlier pixels (so Huber
// weights engage), and a random mask keeping ~70% of the pixels.
Problem make_problem(uint64_t seed, int width, int height, size_t count) {
  std::mt19937_64 rng(seed);
  gs::test::SceneSpec spec;
  spec.width = width;
  spec.height = height;
  spec.count = count;
  View<double> v0 = gs::test::random_view(rng, width, height);
  v0.background[0] = 0.2;
  v0.background[1] = 0.1;
  v0.background[2] = 0.4;
  Scene<double> s0 = gs::test::random_scene(rng, v0, spec);
  for (size_t i = 0; i < s0.n; i += 4) s0.opacities[i] = 0.999;  // some alphas hit the 0.99 clamp
  Problem p;
  p.sf = gs::test::to_float(s0);
  p.vf = gs::test::to_float(v0);
  p.sd.n = p.sf.n;
  p.sd.means = gs::test::cast_vec<double>(p.sf.means);
  p.sd.log_scales = gs::test::cast_vec<double>(p.sf.log_scales);
  p.sd.quats = gs::test::cast_vec<double>(p.sf.quats);
  p.sd.opacities = gs::test::cast_vec<double>(p.sf.opacities);
  p.sd.colors = gs::test::cast_vec<double>(p.sf.colors);
  for (int k = 0; k < 9; ++k) p.vd.R[k] = double(p.vf.R[k]);
  for (int k = 0; k < 3; ++k) p.vd.t[k] = double(p.vf.t[k]), p.vd.background[k] = double(p.vf.background[k]);
  p.vd.fx = p.vf.fx; p.vd.fy = p.vf.fy; p.vd.cx = p.vf.cx; p.vd.cy = p.vf.cy;
  p.vd.width = width; p.vd.height = height;
  const double xi[6] = {0.01, -0.015, 0.02, 0.008, -0.006, 0.01};
  const Forward<double> ft = gs::ref::render_fwd(p.sd, perturbed(p.vd, xi));
  std::normal_distribution<double> noise(0, 0.01);
  std::uniform_real_distribution<double> u01(0, 1);
  p.target.resize(ft.rgb.size());
  for (size_t e = 0; e < ft.rgb.size(); ++e) p.target[e] = float(ft.rgb[e] + noise(rng));
  const size_t P = size_t(width) * height;
  for (size_t pix = 0; pix < P; ++pix)
    if (u01(rng) < 0.05)
      for (int c = 0; c < 3; ++c) p.target[3 * pix + c] = float(u01(rng));
  p.mask.resize(P);
  for (float& m : p.mask) m = u01(rng) < 0.7 ? 1.0f : 0.0f;
  return p;
}

struct RefNormal {
  double JtJ[36] = {}, Jtr[6] = {}, cost = 0, weight_sum = 0;
  size_t pixels = 0;
};

RefNormal ref_normal(const Problem& p, const Forward<double>& f, const std::vector<double>& J, const float* mask,
                     float huber) {
  RefNormal n;
  const size_t P = size_t(p.vd.width) * p.vd.height;
  for (size_t pix = 0; pix < P; ++pix) {
    if (mask && mask[pix] == 0.0f) continue;
    double r[3], r2 = 0;
    for (int c = 0; c < 3; ++c) {
      r[c] = f.rgb[3 * pix + c] - double(p.target[3 * pix + c]);
      r2 += r[c] * r[c];
    }
    const double w = huber > 0 && std::sqrt(r2) > huber ? huber / std::sqrt(r2) : 1.0;
    const double* Jp = &J[18 * pix];
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j)
        n.JtJ[i * 6 + j] += w * (Jp[i] * Jp[j] + Jp[6 + i] * Jp[6 + j] + Jp[12 + i] * Jp[12 + j]);
      n.Jtr[i] += w * (Jp[i] * r[0] + Jp[6 + i] * r[1] + Jp[12 + i] * r[2]);
    }
    n.cost += 0.5 * w * r2;
    n.weight_sum += w;
    ++n.pixels;
  }
  return n;
}

gs::RenderOptions options_for(const View<float>& v) {
  gs::RenderOptions opt;
  std::memcpy(opt.background, v.background, sizeof(opt.background));
  return opt;
}

}  // namespace

TEST_CASE("pose normal equations: renderer in float matches the double reference") {
  const Problem p = make_problem(301, 70, 52, 300);
  const Forward<double> f = gs::ref::render_fwd(p.sd, p.vd);
  const std::vector<double> J = gs::ref::render_pose_jacobian(p.sd, p.vd, f);
  gs::platform::ThreadPool pool(2);
  gs::Renderer r;
  REQUIRE(r.init(gs::RenderCapacity{p.sf.n, 0, p.vf.width, p.vf.height}, &pool).ok());
  std::vector<float> rgb(f.rgb.size());
  REQUIRE(r.forward(gs::test::to_camera(p.vf), gs::test::to_params(p.sf), options_for(p.vf), rgb.data()).ok());

  // The per-pixel Jacobian: float vs double, relative to each twist column's largest entry.
  std::vector<float> Jf(J.size(), -1.0f);
  gs::PoseNormalEquations ne{};
  REQUIRE(r.pose_normal_equations(p.target.data(), nullptr, 0.0f, &ne, Jf.data()).ok());
  double col_max[6] = {0, 0, 0, 0, 0, 0};
  for (size_t e = 0; e < J.size(); ++e) col_max[e % 6] = std::max(col_max[e % 6], std::fabs(J[e]));
  size_t outliers = 0;
  double worst = 0;
  for (size_t e = 0; e < J.size(); ++e) {
    const double err = std::fabs(double(Jf[e]) - J[e]) / col_max[e % 6];
    worst = std::max(worst, err);
    outliers += err > 1e-3 ? 1 : 0;
  }
  MESSAGE("per-pixel Jacobian float vs double: worst error " << worst << " of the column scale, " << outliers
                                                             << " entries above 1e-3 of " << J.size());
  // Outliers: pixels where float and double disagree on a discrete decision (1/255 threshold,
  // early stop); measured 0 on this scene, bounded at 0.1% rather than widening the tolerance.
  CHECK(outliers <= J.size() / 1000);

  struct Variant {
    const char* name;
    const float* mask;
    float huber;
  };
  const Variant variants[] = {{"plain", nullptr, 0.0f},
                              {"mask", p.mask.data(), 0.0f},
                              {"huber", nullptr, 0.05f},
                              {"mask and huber", p.mask.data(), 0.05f}};
  for (const Variant& var : variants) {
    const std::string name = var.name;
    CAPTURE(name);
    const RefNormal rn = ref_normal(p, f, J, var.mask, var.huber);
    REQUIRE(r.pose_normal_equations(p.target.data(), var.mask, var.huber, &ne).ok());
    CHECK(ne.pixels == rn.pixels);
    if (var.huber > 0) CHECK(rn.weight_sum < 0.97 * double(rn.pixels));  // Huber really downweights
    if (var.mask) CHECK(rn.pixels < size_t(0.8 * p.vf.width * p.vf.height));
    // Scales: JtJ_ij against sqrt(JtJ_ii JtJ_jj) (off-diagonal entries may be near zero), Jtr_i
    // against its Cauchy-Schwarz bound sqrt(JtJ_ii sum w r^2). 1e-3: float forward and tangents
    // (~1e-6 relative per value) summed over thousands of pixels, plus rare float/double
    // threshold flips; measured worst below 1e-4.
    double worst_jtj = 0, worst_jtr = 0;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        const double scale = std::sqrt(rn.JtJ[i * 6 + i] * rn.JtJ[j * 6 + j]);
        const double err = std::fabs(ne.JtJ[i * 6 + j] - rn.JtJ[i * 6 + j]) / scale;
        worst_jtj = std::max(worst_jtj, err);
        CHECK(ne.JtJ[i * 6 + j] == ne.JtJ[j * 6 + i]);
      }
      const double scale = std::sqrt(rn.JtJ[i * 6 + i] * 2 * rn.cost);
      worst_jtr = std::max(worst_jtr, std::fabs(ne.Jtr[i] - rn.Jtr[i]) / scale);
    }
    MESSAGE(name << ": JtJ worst " << worst_jtj << ", Jtr worst " << worst_jtr << ", cost " << ne.cost << " vs "
                     << rn.cost << ", weight sum " << ne.weight_sum << " vs " << rn.weight_sum);
    CHECK(worst_jtj <= 1e-3);
    CHECK(worst_jtr <= 1e-3);
    CHECK(std::fabs(ne.cost - rn.cost) <= 1e-3 * rn.cost);
    CHECK(std::fabs(ne.weight_sum - rn.weight_sum) <= 1e-3 * rn.weight_sum);
  }
}

TEST_CASE("pose normal equations: bit-identical with 1 and 3 threads and allocation-free") {
  const Problem p = make_problem(401, 90, 70, 800);
  const gs::Camera cam = gs::test::to_camera(p.vf);
  const gs::GaussianParams params = gs::test::to_params(p.sf);
  const gs::RenderOptions opt = options_for(p.vf);
  const gs::RenderCapacity cap{p.sf.n, 0, p.vf.width, p.vf.height};
  gs::platform::ThreadPool pool(3);
  gs::Renderer r1, r3;
  REQUIRE(r1.init(cap, nullptr).ok());
  REQUIRE(r3.init(cap, &pool).ok());
  std::vector<float> rgb(p.target.size());
  std::vector<float> J1(p.target.size() * 6), J3(J1.size());
  gs::PoseNormalEquations a{}, b{};

  gs::PoseNormalEquations early{};
  CHECK_FALSE(r1.pose_normal_equations(p.target.data(), nullptr, 0.0f, &early).ok());  // no forward yet

  REQUIRE(r1.forward(cam, params, opt, rgb.data()).ok());
  REQUIRE(r1.pose_normal_equations(p.target.data(), p.mask.data(), 0.05f, &a, J1.data()).ok());
  REQUIRE(r3.forward(cam, params, opt, rgb.data()).ok());
  REQUIRE(r3.pose_normal_equations(p.target.data(), p.mask.data(), 0.05f, &b, J3.data()).ok());
  CHECK(std::memcmp(a.JtJ, b.JtJ, sizeof(a.JtJ)) == 0);
  CHECK(std::memcmp(a.Jtr, b.Jtr, sizeof(a.Jtr)) == 0);
  CHECK(a.cost == b.cost);
  CHECK(a.weight_sum == b.weight_sum);
  CHECK(a.pixels == b.pixels);
  CHECK(J1 == J3);
  CHECK(a.JtJ[0] > 0);

  // Repeated forward + normal equations on the 3-thread renderer allocate nothing.
  gs::test::AllocationScope scope;
  for (int frame = 0; frame < 3; ++frame) {
    REQUIRE(r3.forward(cam, params, opt, rgb.data()).ok());
    REQUIRE(r3.pose_normal_equations(p.target.data(), p.mask.data(), 0.05f, &b).ok());
  }
  CHECK(scope.count() == 0);
  CHECK(std::memcmp(a.JtJ, b.JtJ, sizeof(a.JtJ)) == 0);
}
