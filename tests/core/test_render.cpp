// SPDX-License-Identifier: MIT
// gs::Renderer (the ref table and one case per SIMD table, skipped where the CPU lacks it) against the float reference pipeline, on
// random scenes with the hard cases of the issue; plus input validation, thread-count invariance
// and the zero-allocation guarantee after warm-up.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/render_ref.h"
#include "gs/simd/kernel_table.h"
#include "support/alloc_counter.h"
#include "support/random_scene.h"
#include "support/simd_isa.h"

namespace {

using gs::ref::Scene;
using gs::ref::View;

struct Frame {
  std::vector<float> rgb, v_means, v_log_scales, v_quats, v_opacities, v_colors, v_sh, v_means2d;
  double v_pose[6];
};

Frame render_with(gs::Renderer& r, const Scene<float>& s, const View<float>& v, const std::vector<float>& w) {
  Frame f;
  const gs::Camera cam = gs::test::to_camera(v);
  const gs::GaussianParams p = gs::test::to_params(s);
  gs::RenderOptions opt;
  std::memcpy(opt.background, v.background, sizeof(opt.background));
  f.rgb.assign(size_t(3) * v.width * v.height, -1.0f);
  const gs::Status st = r.forward(cam, p, opt, f.rgb.data());
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  const size_t n = s.n;
  f.v_means.assign(3 * n, 0); f.v_log_scales.assign(3 * n, 0); f.v_quats.assign(4 * n, 0);
  f.v_opacities.assign(n, 0); f.v_colors.assign(3 * n, 0); f.v_sh.assign(s.sh.size(), 0); f.v_means2d.assign(2 * n, 0);
  gs::GaussianGrads g;
  g.v_means = f.v_means.data(); g.v_log_scales = f.v_log_scales.data(); g.v_quats = f.v_quats.data();
  g.v_opacities = f.v_opacities.data(); g.v_colors = f.v_colors.data(); g.v_sh = f.v_sh.data();
  g.v_means2d = f.v_means2d.data();
  REQUIRE(r.backward(w.data(), &g).ok());
  std::memcpy(f.v_pose, g.v_pose, sizeof(f.v_pose));
  return f;
}

// Tolerance model for SIMD vs reference (both float): values agree to a relative 2e-5 of the
// array's scale (xsimd's exp differs from libm's by a few ULP and errors compound through up to
// ~100 blended layers; measured worst 2.1e-6 over sse2/avx2/avx512, so 10x margin), except where a splat sits within rounding of the alpha >= 1/255 threshold
// or the 1e-4 stop: such a "flip" changes one pixel by up to one splat's weight. We bound the
// number of outliers instead of widening the tolerance.
struct Agreement {
  size_t outliers = 0;
  double worst = 0;
};
Agreement compare(const std::vector<float>& a, const std::vector<float>& b, double rel) {
  double scale = 1e-6;
  for (float x : b) scale = std::max(scale, double(std::fabs(x)));
  Agreement ag;
  for (size_t i = 0; i < a.size(); ++i) {
    const double e = std::fabs(double(a[i]) - double(b[i])) / scale;
    ag.worst = std::max(ag.worst, e);
    if (e > rel || std::isnan(a[i]) != std::isnan(b[i])) ++ag.outliers;
  }
  return ag;
}

void check_against_ref(const Scene<float>& s, const View<float>& v, uint64_t seed, const gs::simd::KernelTable* kt,
                       gs::platform::ThreadPool* pool) {
  CAPTURE(seed);
  CAPTURE(kt->isa);
  std::mt19937_64 rng(seed * 7 + 1);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> w(size_t(3) * v.width * v.height);
  for (float& x : w) x = u(rng);
  const auto fref = gs::ref::render_fwd(s, v);
  const auto gref = gs::ref::render_bwd(s, v, fref, w.data());
  gs::Renderer r;
  gs::RenderCapacity cap;
  cap.max_gaussians = s.n;
  cap.max_isects = std::max<size_t>(64, fref.tile_ids.size());
  cap.max_width = v.width;
  cap.max_height = v.height;
  REQUIRE(r.init(cap, pool, kt).ok());
  const Frame f = render_with(r, s, v, w);
  const bool exact = std::strcmp(kt->isa, "ref") == 0;
  const double rel = exact ? 0.0 : 2e-5;
  // Outliers allowed (flips): 1% of entries, at least 2; exact for the ref table.
  auto bound = [&](size_t n) { return exact ? size_t(0) : std::max<size_t>(2, n / 100); };
  auto check = [&](const char* what, const std::vector<float>& a, const std::vector<float>& b) {
    if (b.empty()) return;
    const Agreement ag = compare(a, b, rel);
    INFO(what << ": worst relative error " << ag.worst << ", outliers " << ag.outliers << " of " << a.size());
    CHECK(ag.outliers <= bound(a.size()));
  };
  check("image", f.rgb, fref.rgb);
  check("v_means", f.v_means, gref.v_means);
  check("v_log_scales", f.v_log_scales, gref.v_log_scales);
  check("v_quats", f.v_quats, gref.v_quats);
  check("v_opacities", f.v_opacities, gref.v_opacities);
  check("v_means2d", f.v_means2d, gref.v_means2d);
  if (s.sh_degree >= 0) check("v_sh", f.v_sh, gref.v_sh); else check("v_colors", f.v_colors, gref.v_colors);
  double pose_scale = 1e-6;
  for (double x : gref.v_pose) pose_scale = std::max(pose_scale, std::fabs(x));
  for (int k = 0; k < 6; ++k) {
    INFO("pose component " << k << ": " << f.v_pose[k] << " vs " << gref.v_pose[k]);
    CHECK(std::fabs(f.v_pose[k] - gref.v_pose[k]) <= (exact ? 1e-9 : 1e-4) * pose_scale);
  }
}

void run_cases(const gs::simd::KernelTable* kt, const gs::test::SceneSpec& spec, std::initializer_list<uint64_t> seeds,
               void (*mutate)(Scene<double>&, std::mt19937_64&) = nullptr) {
  gs::platform::ThreadPool pool(2);
  for (uint64_t seed : seeds) {
    std::mt19937_64 rng(seed);
    View<double> vd = gs::test::random_view(rng, spec.width, spec.height);
    vd.background[0] = 0.1;
    vd.background[2] = 0.3;
    Scene<double> sd = gs::test::random_scene(rng, vd, spec);
    if (mutate) mutate(sd, rng);
    const Scene<float> s = gs::test::to_float(sd);
    const View<float> v = gs::test::to_float(vd);
    check_against_ref(s, v, seed, kt, &pool);
  }
}

}  // namespace

GS_REF_AND_SIMD_TEST_CASE(render_typical, "renderer matches reference: typical scenes") {
  gs::test::SceneSpec spec;
  spec.width = 64;
  spec.height = 48;
  spec.count = 300;
  run_cases(kt, spec, {101, 102});
}

GS_REF_AND_SIMD_TEST_CASE(render_sh3, "renderer matches reference: SH degree 3") {
  gs::test::SceneSpec spec;
  spec.width = 48;
  spec.height = 40;
  spec.count = 120;
  spec.sh_degree = 3;
  run_cases(kt, spec, {111});
}

GS_REF_AND_SIMD_TEST_CASE(render_near_plane, "renderer matches reference: behind and crossing the near plane") {
  gs::test::SceneSpec spec;
  spec.width = 50;
  spec.height = 33;
  spec.count = 150;
  spec.min_depth = -1.0;  // some behind the camera, some straddling z = 0.2
  spec.max_depth = 1.5;
  run_cases(kt, spec, {121, 122});
}

GS_REF_AND_SIMD_TEST_CASE(render_covariances, "renderer matches reference: tiny and huge and flat covariances with opacity 0 and 1") {
  gs::test::SceneSpec spec;
  spec.width = 45;
  spec.height = 31;
  spec.count = 200;
  run_cases(kt, spec, {131, 132}, [](Scene<double>& s, std::mt19937_64& rng) {
    std::uniform_int_distribution<int> pick(0, 5);
    for (size_t i = 0; i < s.n; ++i) {
      switch (pick(rng)) {
        case 0: for (int k = 0; k < 3; ++k) s.log_scales[3 * i + k] = std::log(1e-6); break;  // tiny
        case 1: for (int k = 0; k < 3; ++k) s.log_scales[3 * i + k] = std::log(50.0); break;  // huge
        case 2: s.log_scales[3 * i + 2] = std::log(1e-6); break;                             // flat
        case 3: s.opacities[i] = 0.0; break;
        case 4: s.opacities[i] = 1.0; break;
        default: break;
      }
    }
  });
}

GS_REF_AND_SIMD_TEST_CASE(render_small_images, "renderer matches reference: 1x1 and 1xN and 17x17 images") {
  for (auto wh : {std::pair<int, int>{1, 1}, {1, 23}, {23, 1}, {17, 17}}) {
    gs::test::SceneSpec spec;
    spec.width = wh.first;
    spec.height = wh.second;
    spec.count = 30;
    spec.min_scale = 0.3;
    spec.max_scale = 1.0;
    run_cases(kt, spec, {141});
  }
}

// Every output, forward and backward, is bit-identical for 1, 2, 3 and 5 threads: the reduce's
// tile bands then split many Gaussians (the scene's splats span several of the 5x4 tiles), whose
// sums continue across bands in key order.
TEST_CASE("renderer: results do not depend on the thread count") {
  std::mt19937_64 rng(151);
  View<double> vd = gs::test::random_view(rng, 70, 52);
  gs::test::SceneSpec spec;
  spec.count = 500;
  const Scene<float> s = gs::test::to_float(gs::test::random_scene(rng, vd, spec));
  const View<float> v = gs::test::to_float(vd);
  std::vector<float> w(size_t(3) * v.width * v.height);
  std::uniform_real_distribution<float> weight(-1.0f, 1.0f);
  for (float& x : w) x = weight(rng);
  gs::RenderCapacity cap{s.n, 0, v.width, v.height};
  gs::Renderer r1;
  REQUIRE(r1.init(cap, nullptr).ok());
  const Frame a = render_with(r1, s, v, w);
  for (int threads : {2, 3, 5}) {
    CAPTURE(threads);
    gs::platform::ThreadPool pool(threads);
    gs::Renderer r2;
    REQUIRE(r2.init(cap, &pool).ok());
    const Frame b = render_with(r2, s, v, w);
    CHECK(a.rgb == b.rgb);
    CHECK(a.v_means == b.v_means);
    CHECK(a.v_log_scales == b.v_log_scales);
    CHECK(a.v_quats == b.v_quats);
    CHECK(a.v_opacities == b.v_opacities);
    CHECK(a.v_colors == b.v_colors);
    CHECK(a.v_means2d == b.v_means2d);
    for (int k = 0; k < 6; ++k) CHECK(a.v_pose[k] == b.v_pose[k]);
  }
}

TEST_CASE("renderer: forward and backward allocate nothing after warm-up") {
  std::mt19937_64 rng(161);
  View<double> vd = gs::test::random_view(rng, 96, 64);
  gs::test::SceneSpec spec;
  spec.count = 2000;
  spec.sh_degree = 2;
  const Scene<float> s = gs::test::to_float(gs::test::random_scene(rng, vd, spec));
  const View<float> v = gs::test::to_float(vd);
  gs::platform::ThreadPool pool(2);
  gs::Renderer r;
  REQUIRE(r.init(gs::RenderCapacity{s.n, 0, v.width, v.height}, &pool).ok());
  const gs::Camera cam = gs::test::to_camera(v);
  const gs::GaussianParams p = gs::test::to_params(s);
  std::vector<float> rgb(size_t(3) * v.width * v.height), v_rgb(rgb.size(), 0.25f);
  std::vector<float> vm(3 * s.n), vs(3 * s.n), vq(4 * s.n), vo(s.n), vsh(s.sh.size()), vm2(2 * s.n);
  gs::GaussianGrads g;
  g.v_means = vm.data(); g.v_log_scales = vs.data(); g.v_quats = vq.data(); g.v_opacities = vo.data();
  g.v_sh = vsh.data(); g.v_means2d = vm2.data();
  gs::RenderOptions opt;
  REQUIRE(r.forward(cam, p, opt, rgb.data()).ok());  // warm-up
  REQUIRE(r.backward(v_rgb.data(), &g).ok());
  gs::test::AllocationScope scope;
  for (int frame = 0; frame < 5; ++frame) {
    REQUIRE(r.forward(cam, p, opt, rgb.data()).ok());
    REQUIRE(r.backward(v_rgb.data(), &g).ok());
  }
  CHECK(scope.count() == 0);
  CHECK(r.stats().visible > 0);
}

// The on-device path: RenderOptions::fixed_point. On every kernel table the image stays within the
// fixed-point error budget of the float one (colours in [0, 1]: the fixed path clamps them), depth
// too; nothing is allocated after warm-up, and backward() refuses to follow a fixed-point forward.
// (The blending kernels are bit-exact across tables, test_qraster; the float projection before them
// is not, so images of two tables may differ by the rounding of a splat's integer record.)
TEST_CASE("renderer: fixed-point forward is close to float on every table and allocation-free") {
  std::mt19937_64 rng(171);
  View<double> vd = gs::test::random_view(rng, 83, 61);
  gs::test::SceneSpec spec;
  spec.count = 1500;
  Scene<double> sd = gs::test::random_scene(rng, vd, spec);
  for (double& c : sd.colors) c = std::clamp(c, 0.0, 1.0);
  const Scene<float> s = gs::test::to_float(sd);
  const View<float> v = gs::test::to_float(vd);
  const gs::Camera cam = gs::test::to_camera(v);
  const gs::GaussianParams p = gs::test::to_params(s);
  const size_t P = size_t(v.width) * v.height;
  gs::platform::ThreadPool pool(2);
  gs::RenderOptions fopt, qopt;
  fopt.depth = qopt.depth = true;
  qopt.fixed_point = true;
  const gs::simd::KernelTable* tables[8];
  int nt = gs::simd::available_simd_kernel_tables(tables, 8);
  tables[nt++] = &gs::simd::ref_kernel_table();
  for (int t = 0; t < nt; ++t) {
    CAPTURE(std::string(tables[t]->isa));
    gs::Renderer r;
    REQUIRE(r.init(gs::RenderCapacity{s.n, 0, v.width, v.height}, &pool, tables[t]).ok());
    std::vector<float> frgb(3 * P), fdepth(P), qrgb(3 * P), qdepth(P);
    REQUIRE(r.forward(cam, p, fopt, frgb.data(), fdepth.data()).ok());
    REQUIRE(r.forward(cam, p, qopt, qrgb.data(), qdepth.data()).ok());
    double worst = 0, sum = 0, depth_worst = 0, depth_max = 0;
    for (size_t i = 0; i < 3 * P; ++i) {
      const double e = std::fabs(double(qrgb[i]) - double(frgb[i])) * 255.0;
      worst = std::max(worst, e);
      sum += e;
    }
    for (size_t i = 0; i < P; ++i) {
      depth_worst = std::max(depth_worst, std::fabs(double(qdepth[i]) - double(fdepth[i])));
      depth_max = std::max(depth_max, double(fdepth[i]));
    }
    INFO("fixed vs float: colour max " << worst << ", mean " << sum / double(3 * P) << " 8-bit levels; depth max " << depth_worst);
    CHECK(worst < 3.0);
    CHECK(sum / double(3 * P) < 0.1);
    CHECK(depth_worst <= 2e-3 * std::max(1.0, depth_max));
    std::vector<float> v_rgb(3 * P, 0.1f), vm(3 * s.n), vs(3 * s.n), vq(4 * s.n), vo(s.n), vc(3 * s.n), vm2(2 * s.n);
    gs::GaussianGrads g;
    g.v_means = vm.data(); g.v_log_scales = vs.data(); g.v_quats = vq.data(); g.v_opacities = vo.data();
    g.v_colors = vc.data(); g.v_means2d = vm2.data();
    const gs::Status refused = r.backward(v_rgb.data(), &g);
    CHECK_FALSE(refused.ok());
    CHECK(refused.message().find("fixed-point") != std::string::npos);
    gs::test::AllocationScope scope;
    for (int frame = 0; frame < 3; ++frame) REQUIRE(r.forward(cam, p, qopt, qrgb.data(), qdepth.data()).ok());
    CHECK(scope.count() == 0);
  }
}

TEST_CASE("renderer: NaN and Inf inputs are refused with a clear error") {
  std::mt19937_64 rng(171);
  View<double> vd = gs::test::random_view(rng, 32, 32);
  gs::test::SceneSpec spec;
  spec.count = 10;
  Scene<float> s = gs::test::to_float(gs::test::random_scene(rng, vd, spec));
  const View<float> v = gs::test::to_float(vd);
  gs::Renderer r;
  REQUIRE(r.init(gs::RenderCapacity{s.n, 0, v.width, v.height}, nullptr).ok());
  std::vector<float> rgb(size_t(3) * v.width * v.height);
  const gs::Camera cam = gs::test::to_camera(v);
  auto expect_refused = [&](const char* needle) {
    const gs::Status st = r.forward(cam, gs::test::to_params(s), gs::RenderOptions{}, rgb.data());
    CHECK(st.code() == gs::StatusCode::kInvalidArgument);
    CHECK_MESSAGE(st.message().find(needle) != std::string::npos, st.message());
  };
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  s.means[3 * 4 + 1] = nan;
  expect_refused("Gaussian 4: mean");
  s.means[3 * 4 + 1] = 0;
  s.log_scales[7] = inf;
  expect_refused("Gaussian 2: log-scale");
  s.log_scales[7] = 0;
  s.quats[4 * 3] = s.quats[4 * 3 + 1] = s.quats[4 * 3 + 2] = s.quats[4 * 3 + 3] = 0;
  expect_refused("Gaussian 3: quaternion is zero");
  s.quats[4 * 3] = 1;
  s.opacities[5] = 1.5f;
  expect_refused("Gaussian 5: opacity");
  s.opacities[5] = 0.5f;
  s.colors[0] = -inf;
  expect_refused("Gaussian 0: colour");
  s.colors[0] = 0.5f;
  CHECK(r.forward(cam, gs::test::to_params(s), gs::RenderOptions{}, rgb.data()).ok());
  gs::Camera bad = cam;
  bad.pose.t[1] = nan;
  CHECK(r.forward(bad, gs::test::to_params(s), gs::RenderOptions{}, rgb.data()).code() == gs::StatusCode::kInvalidArgument);
  bad = cam;
  bad.pose.R[0] = 2;
  CHECK(r.forward(bad, gs::test::to_params(s), gs::RenderOptions{}, rgb.data()).code() == gs::StatusCode::kInvalidArgument);
  bad = cam;
  bad.intr.fx = 0;
  CHECK(r.forward(bad, gs::test::to_params(s), gs::RenderOptions{}, rgb.data()).code() == gs::StatusCode::kInvalidArgument);
}

TEST_CASE("renderer: capacities are enforced, never silently exceeded") {
  std::mt19937_64 rng(181);
  View<double> vd = gs::test::random_view(rng, 64, 64);
  gs::test::SceneSpec spec;
  spec.count = 100;
  const Scene<float> s = gs::test::to_float(gs::test::random_scene(rng, vd, spec));
  const View<float> v = gs::test::to_float(vd);
  std::vector<float> rgb(size_t(3) * v.width * v.height);
  gs::Renderer r;
  REQUIRE(r.init(gs::RenderCapacity{s.n, 4, v.width, v.height}, nullptr).ok());
  CHECK(r.forward(gs::test::to_camera(v), gs::test::to_params(s), {}, rgb.data()).code() ==
        gs::StatusCode::kCapacityExceeded);
  REQUIRE(r.init(gs::RenderCapacity{s.n - 1, 0, v.width, v.height}, nullptr).ok());
  CHECK(r.forward(gs::test::to_camera(v), gs::test::to_params(s), {}, rgb.data()).code() ==
        gs::StatusCode::kCapacityExceeded);
  REQUIRE(r.init(gs::RenderCapacity{s.n, 0, v.width - 1, v.height}, nullptr).ok());
  CHECK(r.forward(gs::test::to_camera(v), gs::test::to_params(s), {}, rgb.data()).code() ==
        gs::StatusCode::kCapacityExceeded);
}
