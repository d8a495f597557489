// SPDX-License-Identifier: MIT
// Frame selection on synthetic video: a textured scene panned across the frame, with chosen frames
// box-blurred. The selector must drop exactly the blurred ones, keep the requested count, spread
// the kept frames along the motion (not in time), and give the same answer every time.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <vector>

#include "gs/capture/frame_select.h"

namespace {

using gs::capture::FrameAnalyzer;
using gs::capture::FrameStats;
using gs::capture::SelectOptions;

constexpr int kW = 160, kH = 120;

// A frame of a large procedural texture seen through a window at horizontal offset `shift` (px).
std::vector<uint8_t> make_frame(double shift) {
  std::vector<uint8_t> rgb(size_t(kW) * kH * 3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double u = x + shift, v = y;
      const double a = 0.5 + 0.25 * std::sin(u * 0.37) * std::cos(v * 0.29) + 0.25 * std::sin((u + 2 * v) * 0.11);
      const bool check = (int(std::floor(u / 9)) + int(std::floor(v / 9))) % 2 == 0;
      for (int c = 0; c < 3; ++c)
        rgb[(size_t(y) * kW + size_t(x)) * 3 + size_t(c)] = uint8_t(std::clamp(255.0 * (check ? a : 0.6 * a) + 20 * c, 0.0, 255.0));
    }
  return rgb;
}

// Separable box blur of radius r (what a shaken hand does to a frame, roughly).
std::vector<uint8_t> blur(const std::vector<uint8_t>& src, int r) {
  std::vector<uint8_t> tmp(src.size()), out(src.size());
  auto at = [](int x, int y, int c) { return (size_t(y) * kW + size_t(x)) * 3 + size_t(c); };
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int c = 0; c < 3; ++c) {
        int s = 0, n = 0;
        for (int d = -r; d <= r; ++d)
          if (x + d >= 0 && x + d < kW) s += src[at(x + d, y, c)], ++n;
        tmp[at(x, y, c)] = uint8_t(s / n);
      }
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int c = 0; c < 3; ++c) {
        int s = 0, n = 0;
        for (int d = -r; d <= r; ++d)
          if (y + d >= 0 && y + d < kH) s += tmp[at(x, y + d, c)], ++n;
        out[at(x, y, c)] = uint8_t(s / n);
      }
  return out;
}

std::vector<FrameStats> analyse(const std::vector<double>& shifts, const std::set<size_t>& blurred) {
  gs::Expected<FrameAnalyzer> a = FrameAnalyzer::create(kW, kH);
  REQUIRE(a.ok());
  std::vector<FrameStats> stats;
  for (size_t i = 0; i < shifts.size(); ++i) {
    std::vector<uint8_t> f = make_frame(shifts[i]);
    if (blurred.count(i)) f = blur(f, 3);
    gs::Expected<FrameStats> s = a->add(f.data(), kW, kH, 3 * kW, int64_t(i), int64_t(i) * 33333333);
    REQUIRE(s.ok());
    stats.push_back(*s);
  }
  return stats;
}

}  // namespace

TEST_CASE("frame select drops blurred frames and keeps the requested count") {
  std::vector<double> shifts;
  for (int i = 0; i < 120; ++i) shifts.push_back(2.0 * i);  // steady pan, 2 px per frame
  std::set<size_t> blurred;
  for (size_t i = 5; i < 120; i += 9) blurred.insert(i);  // 13 blurred frames
  const std::vector<FrameStats> stats = analyse(shifts, blurred);

  for (size_t i : blurred) {
    // Blurred frames are far less sharp than their neighbours.
    CHECK(stats[i].sharpness < 0.5 * stats[i - 1].sharpness);
  }
  SelectOptions o;
  o.target_count = 40;
  gs::capture::SelectReport rep;
  const std::vector<size_t> kept = gs::capture::select_frames(stats, o, &rep);
  CHECK(kept.size() == 40);
  CHECK(rep.kept == 40);
  CHECK(rep.total == 120);
  CHECK(rep.blurred == int(blurred.size()));
  for (size_t k : kept) CHECK_MESSAGE(blurred.count(k) == 0, "kept blurred frame ", k);
  CHECK(std::is_sorted(kept.begin(), kept.end()));
  CHECK(std::adjacent_find(kept.begin(), kept.end()) == kept.end());
  // Deterministic.
  CHECK(gs::capture::select_frames(stats, o) == kept);
}

TEST_CASE("frame select spreads frames along the motion not the clock") {
  // The camera pans for 40 frames, holds still for 80 (noise-free: motion 0), then pans again for 40.
  std::vector<double> shifts;
  for (int i = 0; i < 40; ++i) shifts.push_back(3.0 * i);
  for (int i = 0; i < 80; ++i) shifts.push_back(120.0);
  for (int i = 0; i < 40; ++i) shifts.push_back(120.0 + 3.0 * (i + 1));
  const std::vector<FrameStats> stats = analyse(shifts, {});
  SelectOptions o;
  o.target_count = 20;
  const std::vector<size_t> kept = gs::capture::select_frames(stats, o);
  REQUIRE(kept.size() == 20);
  const size_t in_pause = size_t(std::count_if(kept.begin(), kept.end(), [](size_t k) { return k >= 41 && k < 119; }));
  // Evenly in time would put half the frames in the pause; along the motion, at most a couple.
  CHECK(in_pause <= 2);
}

TEST_CASE("frame select with fewer usable frames than requested keeps all sharp ones") {
  std::vector<double> shifts;
  for (int i = 0; i < 12; ++i) shifts.push_back(4.0 * i);
  const std::vector<FrameStats> stats = analyse(shifts, {3});
  SelectOptions o;
  o.target_count = 100;
  const std::vector<size_t> kept = gs::capture::select_frames(stats, o);
  CHECK(kept.size() == 11);
  CHECK(std::find(kept.begin(), kept.end(), size_t(3)) == kept.end());
}

TEST_CASE("frame select min motion keeps a baseline between kept frames") {
  std::vector<double> shifts;
  for (int i = 0; i < 60; ++i) shifts.push_back(1.0 * i);
  const std::vector<FrameStats> stats = analyse(shifts, {});
  const double step = stats[1].motion;  // motion of a 1 px pan
  REQUIRE(step > 0);
  SelectOptions o;
  o.target_count = 60;  // asks for every frame ...
  o.min_motion = 4.5 * step;  // ... but demands about 5 frames of pan between kept ones
  const std::vector<size_t> kept = gs::capture::select_frames(stats, o);
  REQUIRE(kept.size() >= 8);
  CHECK(kept.size() <= 13);
  double along_prev = -1e9, along = 0;
  size_t next = 0;
  for (size_t i = 0; i < stats.size(); ++i) {
    along += stats[i].motion;
    if (next < kept.size() && kept[next] == i) {
      CHECK(along - along_prev >= o.min_motion);
      along_prev = along;
      ++next;
    }
  }
}

TEST_CASE("frame analyser measures motion and refuses frames larger than planned") {
  gs::Expected<FrameAnalyzer> a = FrameAnalyzer::create(kW, kH);
  REQUIRE(a.ok());
  const std::vector<uint8_t> f0 = make_frame(0), f1 = make_frame(0), f2 = make_frame(15);
  gs::Expected<FrameStats> s0 = a->add(f0.data(), kW, kH, 3 * kW, 0, 0);
  gs::Expected<FrameStats> s1 = a->add(f1.data(), kW, kH, 3 * kW, 1, 1);
  gs::Expected<FrameStats> s2 = a->add(f2.data(), kW, kH, 3 * kW, 2, 2);
  REQUIRE((s0.ok() && s1.ok() && s2.ok()));
  CHECK(s0->motion == 0.0);
  CHECK(s1->motion == 0.0);  // identical frames
  CHECK(s2->motion > 0.01);
  std::vector<uint8_t> big(size_t(kW + 2) * kH * 3, 0);
  gs::Expected<FrameStats> bad = a->add(big.data(), kW + 2, kH, 3 * (kW + 2), 3, 3);
  REQUIRE(!bad.ok());
  CHECK(bad.status().message().find("planned") != std::string::npos);
  CHECK(!FrameAnalyzer::create(4, 4).ok());
}

TEST_CASE("laplacian variance is zero on flat images and grows with contrast") {
  std::vector<float> flat(64 * 48, 100.0f), ramp(64 * 48), checker(64 * 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      ramp[size_t(y * 64 + x)] = float(x);  // linear: Laplacian 0
      checker[size_t(y * 64 + x)] = ((x + y) % 2) ? 200.0f : 50.0f;
    }
  CHECK(gs::capture::laplacian_variance(flat.data(), 64, 48) == doctest::Approx(0.0));
  CHECK(gs::capture::laplacian_variance(ramp.data(), 64, 48) == doctest::Approx(0.0));
  // Checker: Laplacian is +-4*150 = +-600 alternating, variance 360000.
  CHECK(gs::capture::laplacian_variance(checker.data(), 64, 48) == doctest::Approx(360000.0).epsilon(1e-6));
}
