// SPDX-License-Identifier: MIT
// Live tracking against a model (gs/model/tracker.h) on a generated model (an asymmetric textured
// object, as test_register.cpp) with frames rendered by the same model along a smooth orbit: the
// poses follow the path, the same with 1 and 2 threads, nothing is allocated per frame, a cut is
// relocalised from candidate poses, and images of something else are reported lost, never placed.
// Reduced builds: 12 frames instead of 30. Under qemu only the fixed-point path and the input
// checks run (the rest is architecture-independent float code, 20-45 s a case emulated); the ASan
// build also runs relocalisation and the allocation count (GS_NATIVE_ONLY).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "gs/io/image.h"
#include "gs/model/model_renderer.h"
#include "gs/model/tracker.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/simd/kernel_table.h"
#include "support/alloc_counter.h"
#include "support/model_fixtures.h"
#include "support/reduced.h"

namespace gs::model {
namespace {

constexpr int kW = 192, kH = 144;
const PinholeIntrinsics kIntr{160, 160, kW / 2.0f, kH / 2.0f, kW, kH};

// The camera on an orbit of radius 6 around the object at angle a (degrees) and height y.
Camera orbit(double a_deg, double y) {
  const double a = a_deg * M_PI / 180.0;
  const double C[3] = {6.0 * std::sin(a), y, -6.0 * std::cos(a)}, at[3] = {0.1, 0.0, 0.0};
  return test::look_at(C, at, kIntr);
}

struct Fixture {
  HybridModel model;
  std::vector<Camera> path;                 // 0.8 degrees per frame of orbit with a slow rise
  std::vector<std::vector<uint8_t>> frames; // the model's renders of the path, 8-bit

  Fixture() {
    model = test::asymmetric_object_model();
    ModelRenderer mr;
    REQUIRE(mr.init(model, kW, kH, nullptr).ok());
    std::vector<float> rgb(size_t(kW) * kH * 3);
    const int n = test::kReduced ? 12 : 30;
    for (int i = 0; i < n; ++i) {
      path.push_back(orbit(-10.0 + 0.8 * i, -0.3 + 0.01 * i));
      REQUIRE(mr.render(model, path.back(), rgb.data()).ok());
      frames.push_back(io::image_from_float_rgb(rgb.data(), kW, kH).pixels);
    }
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

double centre_error(const Pose& a, const Pose& b) {
  double ca[3], cb[3];
  pose::centre(a, ca);
  pose::centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

// Tracks the whole path from the true first pose; returns the poses.
std::vector<Pose> track_path(const pose::TrackOptions& opt, platform::ThreadPool* pool, double* max_rot, double* max_centre,
                             int* not_tracking, double* median_rot = nullptr) {
  const Fixture& f = fixture();
  auto t = pose::Tracker::create(f.model, kIntr, opt, pool);
  REQUIRE_MESSAGE(t.ok(), t.status().to_string());
  REQUIRE((*t)->reset(f.path[0].pose).ok());
  std::vector<Pose> out;
  std::vector<double> rots;
  *max_rot = *max_centre = 0;
  *not_tracking = 0;
  for (size_t i = 0; i < f.frames.size(); ++i) {
    pose::TrackResult r;
    REQUIRE((*t)->track(f.frames[i].data(), double(i) / 30.0, &r).ok());
    if (r.verdict != pose::TrackVerdict::kTracking) ++*not_tracking;
    *max_rot = std::max(*max_rot, pose::rotation_error_deg(r.pose, f.path[i].pose));
    *max_centre = std::max(*max_centre, centre_error(r.pose, f.path[i].pose));
    out.push_back(r.pose);
    rots.push_back(pose::rotation_error_deg(r.pose, f.path[i].pose));
  }
  std::sort(rots.begin(), rots.end());
  if (median_rot) *median_rot = rots[rots.size() / 2];
  return out;
}

TEST_CASE("tracker: follows a smooth path of the model's own renders, the same on 1 and 2 threads" * GS_FULL_SIZE_ONLY) {
  platform::ThreadPool one(1), two(2);
  pose::TrackOptions opt;
  double rot[2], centre[2], median = 0;
  int lost[2];
  const std::vector<Pose> a = track_path(opt, &one, &rot[0], &centre[0], &lost[0], &median);
  const std::vector<Pose> b = track_path(opt, &two, &rot[1], &centre[1], &lost[1]);
  MESSAGE("rotation error median " << median << ", max " << rot[0] << " deg, max centre error " << centre[0]
                                   << " (scene radius 6), frames not tracking " << lost[0]);
  // Tracked at 96 x 72: a tenth of a degree is a fifth of a pixel there.
  CHECK(lost[0] == 0);
  CHECK(median < 0.1);
  CHECK(rot[0] < 0.2);
  CHECK(centre[0] < 0.005 * 6.0);
  REQUIRE(a.size() == b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    CAPTURE(i);
    CHECK(std::memcmp(&a[i], &b[i], sizeof(Pose)) == 0);  // chunked sums in a fixed order
  }
}

TEST_CASE("tracker: the fixed-point keyframes track the path as well") {
  platform::ThreadPool pool(2);
  pose::TrackOptions opt;
  opt.fixed_point = true;
  double rot, centre, median = 0;
  int lost;
  track_path(opt, &pool, &rot, &centre, &lost, &median);
  MESSAGE("fixed point: rotation error median " << median << ", max " << rot << " deg, max centre error " << centre);
  CHECK(lost == 0);
  CHECK(median < 0.1);
  CHECK(rot < 0.2);
  CHECK(centre < 0.005 * 6.0);
}

// The on-device path gives the same poses on every CPU: the fixed-point blending is bit-exact
// between the scalar reference kernels and every SIMD table (its own tests), and in fixed-point
// mode the float kernels before it (decoder MLPs, projection) run their scalar references
// (RegisterOptions::fixed_point). So the whole tracker with the reference table and with every SIMD
// table this CPU runs (SSE2, AVX2, AVX-512 on x86; NEON under qemu-aarch64 / armhf in the reduced
// build) gives bit-identical poses. (With the SIMD decoders and projection they were 0.0008-0.0025
// degrees apart.) Between architectures, scripts/check-install.sh compares hbgs-device track on x86
// and under qemu.
TEST_CASE("tracker: fixed-point poses are bit-identical with the reference kernels and with this CPU's SIMD kernels") {
  const Fixture& f = fixture();
  platform::ThreadPool pool(2);
  pose::TrackOptions opt;
  opt.fixed_point = true;
  auto track_with = [&](const simd::KernelTable* table) {
    std::vector<Pose> poses;
    auto t = pose::Tracker::create(f.model, kIntr, opt, &pool, table);
    REQUIRE(t.ok());
    REQUIRE((*t)->reset(f.path[0].pose).ok());
    for (size_t i = 0; i < f.frames.size(); ++i) {
      pose::TrackResult r;
      REQUIRE((*t)->track(f.frames[i].data(), double(i) / 30.0, &r).ok());
      CHECK(r.verdict == pose::TrackVerdict::kTracking);
      poses.push_back(r.pose);
    }
    return poses;
  };
  const std::vector<Pose> ref = track_with(&simd::ref_kernel_table());
  int compared = 0;
  for (const char* isa : {"sse2", "avx2", "avx512", "neon64", "neon"}) {
    const simd::KernelTable* table = simd::kernel_table_by_name(isa);
    if (!table) continue;  // not built for or not supported by this CPU
    const std::vector<Pose> other = track_with(table);
    double worst = 0;
    int different = 0;
    for (size_t i = 0; i < ref.size(); ++i) {
      worst = std::max(worst, pose::rotation_error_deg(ref[i], other[i]));
      different += std::memcmp(ref[i].R, other[i].R, sizeof(ref[i].R)) != 0 || std::memcmp(ref[i].t, other[i].t, sizeof(ref[i].t)) != 0;
    }
    MESSAGE("reference vs " << std::string(isa) << ": " << different << " of " << ref.size()
                            << " poses differ, largest rotation difference " << worst << " deg");
    CHECK(different == 0);
    ++compared;
  }
  if (compared == 0) MESSAGE("no SIMD kernel table on this CPU: nothing compared");
}

TEST_CASE("tracker: nothing is allocated per frame, new keyframes and relocalisation included" * GS_NATIVE_ONLY) {
  const Fixture& f = fixture();
  platform::ThreadPool pool(2);
  pose::TrackOptions opt;
  opt.keyframe_rotation_deg = 1.0;  // a keyframe every other frame
  auto t = pose::Tracker::create(f.model, kIntr, opt, &pool);
  REQUIRE(t.ok());
  REQUIRE((*t)->set_candidates({f.path[0].pose, f.path.back().pose}).ok());
  REQUIRE((*t)->reset(f.path[0].pose).ok());
  pose::TrackResult r;
  REQUIRE((*t)->track(f.frames[0].data(), 0.0, &r).ok());  // warm-up: the first keyframe
  REQUIRE((*t)->track(f.frames[1].data(), 1 / 30.0, &r).ok());
  std::vector<uint8_t> black(f.frames[0].size(), 0);
  uint64_t keyframes_before = r.keyframes;
  test::AllocationScope scope;
  for (size_t i = 2; i < f.frames.size(); ++i) REQUIRE((*t)->track(f.frames[i].data(), double(i) / 30.0, &r).ok());
  REQUIRE((*t)->track(black.data(), 10.0, &r).ok());  // lost: relocalisation from the candidates
  CHECK(r.verdict == pose::TrackVerdict::kLost);
  REQUIRE((*t)->track(f.frames.back().data(), 11.0, &r).ok());
  CHECK(r.verdict == pose::TrackVerdict::kRelocalized);
  CHECK(scope.count() == 0);
  CHECK(r.keyframes > keyframes_before + 2);
}

TEST_CASE("tracker: a cut is relocalised from the candidates, images of something else are lost" * GS_NATIVE_ONLY) {
  const Fixture& f = fixture();
  platform::ThreadPool pool(2);
  pose::TrackOptions opt;
  auto t = pose::Tracker::create(f.model, kIntr, opt, &pool);
  REQUIRE(t.ok());
  // Candidates every 30 degrees around the orbit; the cut lands on the far side, 6 degrees from the
  // nearest candidate (inside registration's basin), far from where the motion model points.
  std::vector<Pose> cands;
  for (int a = -180; a < 180; a += 30) cands.push_back(orbit(a, -0.2).pose);
  REQUIRE((*t)->set_candidates(cands).ok());
  ModelRenderer mr;
  REQUIRE(mr.init(f.model, kW, kH, nullptr).ok());
  std::vector<float> rgb(size_t(kW) * kH * 3);
  const Camera cut = orbit(-10.0 + 0.8 * 5 + 150.0, -0.1);
  REQUIRE(mr.render(f.model, cut, rgb.data()).ok());
  const std::vector<uint8_t> cut_frame = io::image_from_float_rgb(rgb.data(), kW, kH).pixels;

  // No start pose: the first frame is relocalised.
  pose::TrackResult r;
  REQUIRE((*t)->track(f.frames[0].data(), 0.0, &r).ok());
  CHECK(r.verdict == pose::TrackVerdict::kRelocalized);
  CHECK(pose::rotation_error_deg(r.pose, f.path[0].pose) < 0.2);
  for (int i = 1; i < 5; ++i) {
    REQUIRE((*t)->track(f.frames[size_t(i)].data(), i / 30.0, &r).ok());
    CHECK(r.verdict == pose::TrackVerdict::kTracking);
  }
  REQUIRE((*t)->track(cut_frame.data(), 5 / 30.0, &r).ok());
  const double cut_error = pose::rotation_error_deg(r.pose, cut.pose);
  MESSAGE("after the cut: " << std::string(pose::track_verdict_name(r.verdict)) << ", rotation error " << cut_error << " deg, "
                            << r.ms.relocalize << " ms relocalising, rmse " << r.rmse << " explained " << r.explained << " coverage " << r.coverage << " its " << r.iterations);
  CHECK(r.verdict == pose::TrackVerdict::kRelocalized);
  CHECK(cut_error < 0.2);

  // Without the plausibility bound on a frame's correction, the verdict alone must still refuse a
  // look-alike: the cut is placed right or reported lost, never placed wrong.
  {
    pose::TrackOptions loose = opt;
    loose.max_correction_deg = 360, loose.max_correction_translation = 100;
    loose.relocalize_candidates = 0;  // and no rescue by registration
    auto u = pose::Tracker::create(f.model, kIntr, loose, &pool);
    REQUIRE(u.ok());
    REQUIRE((*u)->reset(f.path[0].pose).ok());
    for (int i = 0; i < 5; ++i) REQUIRE((*u)->track(f.frames[size_t(i)].data(), i / 30.0, &r).ok());
    REQUIRE((*u)->track(cut_frame.data(), 5 / 30.0, &r).ok());
    const double err = pose::rotation_error_deg(r.pose, cut.pose);
    MESSAGE("verdict alone after the cut: " << std::string(pose::track_verdict_name(r.verdict)) << ", rotation error " << err
                                             << " deg, rmse " << r.rmse << " explained " << r.explained);
    CHECK((r.verdict == pose::TrackVerdict::kLost || err < 2.0));
  }

  // Noise and black frames: lost (no pose claimed), then the path again: relocalised.
  std::mt19937 rng(3);
  std::vector<uint8_t> noise(f.frames[0].size());
  for (uint8_t& v : noise) v = uint8_t(rng() & 0xff);
  const std::vector<uint8_t> black(f.frames[0].size(), 0);
  int t_index = 6;
  for (const std::vector<uint8_t>* img : std::vector<const std::vector<uint8_t>*>{&noise, &black}) {
    REQUIRE((*t)->track(img->data(), t_index++ / 30.0, &r).ok());
    CHECK(r.verdict == pose::TrackVerdict::kLost);
  }
  REQUIRE((*t)->track(f.frames[10].data(), t_index++ / 30.0, &r).ok());
  CHECK(r.verdict == pose::TrackVerdict::kRelocalized);
  CHECK(pose::rotation_error_deg(r.pose, f.path[10].pose) < 0.2);
}

TEST_CASE("tracker: a relocalised frame fitted worse than the stream's usual is placed when starts from several sides meet, lost from one" * GS_NATIVE_ONLY) {
  // The stream's own frames (the model's renders) fit to about 0.002 RMSE; a frame after a cut with
  // noise of 0.06 RMSE (0.038 in the alignment's colour space) is beyond the growth bound (2.5x the
  // recent median, at least 0.03) at any pose. Candidates 5 degrees either side of the cut both register to its pose: accepted. From
  // one candidate it is lost; without the growth bound the same single registration places it,
  // so it is the agreement rule that accepts it, not a looser fit.
  const Fixture& f = fixture();
  platform::ThreadPool pool(2);
  ModelRenderer mr;
  REQUIRE(mr.init(f.model, kW, kH, nullptr).ok());
  std::vector<float> rgb(size_t(kW) * kH * 3);
  const Camera cut = orbit(120.0, -0.1);
  REQUIRE(mr.render(f.model, cut, rgb.data()).ok());
  // Noise constant over 2x2 blocks, so that the half-resolution alignment sees it undiminished.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.104f, 0.104f);  // uniform: 0.06 RMSE
  for (int y = 0; y < kH; y += 2)
    for (int x = 0; x < kW; x += 2)
      for (int c = 0; c < 3; ++c) {
        const float n = jitter(rng);
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) {
            float& v = rgb[(size_t(y + dy) * kW + size_t(x + dx)) * 3 + size_t(c)];
            v = std::clamp(v + n, 0.0f, 1.0f);
          }
      }
  const std::vector<uint8_t> noisy = io::image_from_float_rgb(rgb.data(), kW, kH).pixels;
  const std::vector<Pose> cands = {orbit(115.0, -0.1).pose, orbit(125.0, -0.1).pose, orbit(-90.0, -0.2).pose};

  struct Case {
    const char* name;
    int candidates;
    double growth;
    pose::TrackVerdict expect;
  };
  for (const Case& c : {Case{"three candidates", 3, 2.5, pose::TrackVerdict::kRelocalized},
                        Case{"one candidate", 1, 2.5, pose::TrackVerdict::kLost},
                        Case{"one candidate, no growth bound", 1, 0.0, pose::TrackVerdict::kRelocalized}}) {
    INFO(std::string(c.name));
    pose::TrackOptions opt;
    opt.relocalize_candidates = c.candidates;
    opt.max_rmse_growth = c.growth;
    auto t = pose::Tracker::create(f.model, kIntr, opt, &pool);
    REQUIRE(t.ok());
    REQUIRE((*t)->set_candidates(cands).ok());
    REQUIRE((*t)->reset(f.path[0].pose).ok());
    pose::TrackResult r;
    for (int i = 0; i < 6; ++i) {
      REQUIRE((*t)->track(f.frames[size_t(i)].data(), i / 30.0, &r).ok());
      REQUIRE(r.verdict == pose::TrackVerdict::kTracking);
    }
    REQUIRE((*t)->track(noisy.data(), 6 / 30.0, &r).ok());
    const double err = pose::rotation_error_deg(r.pose, cut.pose);
    MESSAGE(std::string(c.name) << ": " << std::string(pose::track_verdict_name(r.verdict)) << ", rmse " << r.rmse << ", explained " << r.explained
                   << ", rotation error " << err << " deg");
    CHECK(r.verdict == c.expect);
    CHECK(r.rmse > 0.03);  // the frame's fit (at tracking resolution), whatever the verdict: beyond the growth bound
    if (r.verdict != pose::TrackVerdict::kLost) CHECK(err < 1.0);
  }
}

TEST_CASE("tracker: invalid set-ups and inputs are errors with a message") {
  const Fixture& f = fixture();
  pose::TrackOptions opt;
  PinholeIntrinsics bad = kIntr;
  bad.fx = 0;
  CHECK(pose::Tracker::create(f.model, bad, opt, nullptr).status().message().find("invalid frame intrinsics") != std::string::npos);
  PinholeIntrinsics tiny = kIntr;
  tiny.width = 40, tiny.height = 30;
  CHECK(pose::Tracker::create(f.model, tiny, opt, nullptr).status().message().find("too small") != std::string::npos);
  pose::TrackOptions bad_levels = opt;
  bad_levels.levels = 0;
  CHECK_FALSE(pose::Tracker::create(f.model, kIntr, bad_levels, nullptr).ok());
  auto t = pose::Tracker::create(f.model, kIntr, opt, nullptr);
  REQUIRE(t.ok());
  pose::TrackResult r;
  CHECK_FALSE((*t)->track(nullptr, 0.0, &r).ok());
  REQUIRE((*t)->reset(f.path[0].pose).ok());
  REQUIRE((*t)->track(f.frames[0].data(), 1.0, &r).ok());
  const Status back = (*t)->track(f.frames[1].data(), 0.5, &r);
  CHECK(back.message().find("is not after the previous frame's") != std::string::npos);
  CHECK((*t)->planned_bytes() > 0);
}

}  // namespace
}  // namespace gs::model
