// SPDX-License-Identifier: MIT
// The tracking job (gs/jobs/track.h) driven by a stand-in tracker: what it writes (the TUM
// trajectory and the COLMAP images.txt in the user's frame, names in frame order, the lost list,
// track.json), the JSON line of each frame, the intrinsics and the box filter that fit the frames to
// them, the start and the candidates it hands the tracker, and --realtime's pacing and dropping with
// an injected clock. The stand-in reads its verdict from each frame's colour: R = 10 tracking,
// 20 relocalized, 30 lost; G = the frame's number, which sets its pose (a turn of G degrees about y
// and a centre of its own), so every output can be checked against numbers computed here.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/tum.h"
#include "gs/jobs/track.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/file.h"
#include "gs/pose/pose.h"
#include "support/model_fixtures.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using gs::jobs::TrackedFrame;

constexpr int kW = 64, kH = 48;                       // the dataset's camera
constexpr double kFx = 50, kFy = 52, kCx = 32, kCy = 24;
const double kCentre[3] = {100, -50, 20};             // the model's scene frame: x_frame = 0.5 (x_user - centre)
constexpr double kScale = 0.5;

// The pose the stand-in gives frame g (model frame): R = a turn of g degrees about y, centre
// (0.1 g, 0.2, -3).
gs::Pose pose_of(int g) {
  const double a = g * M_PI / 180, c = std::cos(a), s = std::sin(a);
  const double R[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
  const double C[3] = {0.1 * g, 0.2, -3};
  gs::Pose p;
  for (int i = 0; i < 9; ++i) p.R[i] = float(R[i]);
  for (int i = 0; i < 3; ++i) p.t[i] = float(-(R[3 * i] * C[0] + R[3 * i + 1] * C[1] + R[3 * i + 2] * C[2]));
  return p;
}

// What the stand-in saw.
struct Seen {
  gs::PinholeIntrinsics K;
  gs::pose::TrackOptions options;
  std::vector<gs::Pose> candidates;
  int resets_to_candidates = 0, resets_to_pose = 0;
  gs::Pose start;
  std::vector<double> times, clock_at_track;
  std::vector<std::vector<uint8_t>> first_pixels;  // RGB of each frame's pixel 0
};

struct FakeClock {
  double now = 1000;
  int sleeps = 0;
};

class StandInTracker final : public gs::jobs::FrameTracker {
 public:
  StandInTracker(Seen* seen, FakeClock* clock, double cost) : seen_(seen), clock_(clock), cost_(cost) {}
  gs::Status set_candidates(const std::vector<gs::Pose>& poses) override {
    seen_->candidates = poses;
    return gs::Status::Ok();
  }
  gs::Status reset(const gs::Pose& start) override {
    ++seen_->resets_to_pose;
    seen_->start = start;
    return gs::Status::Ok();
  }
  void reset() override { ++seen_->resets_to_candidates; }
  gs::Status track(const uint8_t* rgb, double time, gs::pose::TrackResult* r) override {
    seen_->times.push_back(time);
    seen_->first_pixels.push_back({rgb[0], rgb[1], rgb[2]});
    if (clock_) {
      seen_->clock_at_track.push_back(clock_->now);
      clock_->now += cost_;
    }
    *r = gs::pose::TrackResult();
    r->verdict = rgb[0] == 10 ? gs::pose::TrackVerdict::kTracking
                 : rgb[0] == 20 ? gs::pose::TrackVerdict::kRelocalized
                                : gs::pose::TrackVerdict::kLost;
    r->pose = pose_of(rgb[1]);
    r->rmse = 0.01 * rgb[1];
    r->iterations = 3;
    r->keyframes = 1 + rgb[1] / 4;
    r->ms.align = 2, r->ms.total = 4 + rgb[1];
    return gs::Status::Ok();
  }
  uint64_t planned_bytes() const override { return 12345; }

 private:
  Seen* seen_;
  FakeClock* clock_;
  double cost_;
};

// cost: fake seconds per track(); setup: fake seconds that making the tracker takes.
gs::jobs::TrackerFactory stand_in(Seen* seen, FakeClock* clock = nullptr, double cost = 0, double setup = 0) {
  return [=](const gs::model::HybridModel&, const gs::PinholeIntrinsics& K, const gs::pose::TrackOptions& o,
             gs::platform::ThreadPool*) -> gs::Expected<std::unique_ptr<gs::jobs::FrameTracker>> {
    seen->K = K;
    seen->options = o;
    if (clock) clock->now += setup;
    return std::unique_ptr<gs::jobs::FrameTracker>(new StandInTracker(seen, clock, cost));
  };
}

gs::io::Image8 solid(int w, int h, uint8_t r, uint8_t g, uint8_t b) {
  gs::io::Image8 img;
  img.width = w, img.height = h, img.channels = 3;
  img.pixels.resize(size_t(w) * size_t(h) * 3);
  for (size_t i = 0; i < img.pixels.size(); i += 3) img.pixels[i] = r, img.pixels[i + 1] = g, img.pixels[i + 2] = b;
  return img;
}

// A model file (scene frame kCentre / kScale) and a COLMAP dataset of 9 views (views 0 and 8 are
// test views by the llffhold-8 split, 1..7 training ones) with user-frame centres (10 + i, 0, 0) - far from the
// model's frame origin, so a wrong frame shows.
struct Fixture {
  gs::test::TempDir dir{"gs_track_job"};
  std::string model, dataset;
  Fixture() {
    gs::model::HybridModel m = gs::test::sphere_model(
        gs::test::small_file_test_config(gs::model::ImageFeatureMode::kNone, 64, 640), 40, 3.0f, 5);
    for (int k = 0; k < 3; ++k) m.frame.centre[k] = kCentre[k];
    m.frame.scale = kScale;
    model = dir / "model.hbgs";
    REQUIRE(gs::model::save_model(m, model).ok());
    dataset = dir / "dataset";
    fs::create_directories(dataset + "/images");
    gs::io::ColmapModel cm;
    cm.cameras.push_back({1, "PINHOLE", kW, kH, {kFx, kFy, kCx, kCy}});
    for (int i = 0; i < 9; ++i) {
      gs::io::ColmapImage im;
      im.id = uint32_t(i + 1);
      im.camera_id = 1;
      im.name = "view_" + std::to_string(i) + ".png";
      im.tvec[0] = -(10.0 + i);  // identity rotation: t = -C
      cm.images.push_back(im);
      REQUIRE(gs::io::write_png(dataset + "/images/" + im.name, solid(kW, kH, 1, 2, 3)).ok());
    }
    REQUIRE(gs::io::write_colmap_text(cm, dataset + "/sparse/0").ok());
  }
  // Frames of w x h: codes[i] is frame i's R channel, G = i.
  std::string frames(const std::string& name, int w, int h, const std::vector<uint8_t>& codes) const {
    const std::string folder = dir / name;
    fs::create_directories(folder);
    for (size_t i = 0; i < codes.size(); ++i) {
      char file[32];
      std::snprintf(file, sizeof(file), "f%03zu.png", i);
      REQUIRE(gs::io::write_png(folder + "/" + file, solid(w, h, codes[i], uint8_t(i), 7)).ok());
    }
    return folder;
  }
};

std::vector<std::string> lines_of(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);)
    if (!l.empty() && l[0] != '#') out.push_back(l);
  return out;
}

// A frame's camera centre in the user's frame, from pose_of: C_user = C_frame / scale + centre.
void user_centre(int g, double c[3]) {
  const double C[3] = {0.1 * g, 0.2, -3};
  for (int k = 0; k < 3; ++k) c[k] = C[k] / kScale + kCentre[k];
}

}  // namespace

TEST_CASE("track job: files, JSON lines and verdicts from a stand-in tracker (frames at twice the model's size)") {
  Fixture fx;
  // 10 frames: tracking, lost, relocalized, ...
  const std::vector<uint8_t> codes = {10, 10, 30, 30, 20, 10, 10, 30, 10, 10};
  gs::jobs::TrackRunOptions o;
  o.input = fx.model;
  o.dataset = fx.dataset;
  o.source = fx.frames("frames", 2 * kW, 2 * kH, codes);
  o.out = fx.dir / "out";
  o.threads = 1;
  Seen seen;
  o.make_tracker = stand_in(&seen);
  std::vector<std::string> json_lines;
  gs::jobs::TrackRunSummary s;
  const gs::Status st = gs::jobs::track_run(o, [&](const TrackedFrame& f) { json_lines.push_back(gs::jobs::tracked_frame_json(f)); }, &s);
  REQUIRE_MESSAGE(st.ok(), st.to_string());

  // Frames 128 x 96 box-filtered by 2 to the dataset camera's 64 x 48 and its intrinsics.
  CHECK(s.downscale == 2);
  CHECK(seen.K.width == kW);
  CHECK(seen.K.height == kH);
  CHECK(seen.K.fx == doctest::Approx(kFx));
  CHECK(seen.K.cy == doctest::Approx(kCy));
  REQUIRE(seen.first_pixels.size() == codes.size());
  for (size_t i = 0; i < codes.size(); ++i) CHECK(seen.first_pixels[i] == std::vector<uint8_t>{codes[i], uint8_t(i), 7});
  // Image-folder times: index / 30 s.
  for (size_t i = 0; i < seen.times.size(); ++i) CHECK(seen.times[i] == doctest::Approx(double(i) / 30));
  // --dataset given: every view is a candidate, in the model's frame: s (C_user - centre).
  REQUIRE(seen.candidates.size() == 9);
  for (int i = 0; i < 9; ++i) {
    double C[3];
    gs::pose::centre(seen.candidates[size_t(i)], C);
    CHECK(C[0] == doctest::Approx(kScale * (10.0 + i - kCentre[0])));
    CHECK(C[1] == doctest::Approx(kScale * (0 - kCentre[1])));
    CHECK(C[2] == doctest::Approx(kScale * (0 - kCentre[2])));
  }
  CHECK(seen.resets_to_candidates == 1);  // --start-pose candidates (the default)
  CHECK(seen.resets_to_pose == 0);

  CHECK(s.frames == 10);
  CHECK(s.tracking == 6);
  CHECK(s.relocalized == 1);
  CHECK(s.lost == 3);
  CHECK(s.dropped == 0);
  CHECK(s.planned_bytes == 12345);

  // TUM: the 7 placed frames, centres and camera-to-world rotations in the user's frame.
  gs::Expected<std::vector<gs::io::TimedPose>> tum = gs::io::read_tum_trajectory(s.trajectory_path);
  REQUIRE(tum.ok());
  const std::vector<std::string> tum_lines = lines_of(s.trajectory_path);
  const std::vector<int> placed = {0, 1, 4, 5, 6, 8, 9};
  REQUIRE(tum_lines.size() == placed.size());
  for (size_t k = 0; k < placed.size(); ++k) {
    const int g = placed[k];
    CAPTURE(g);
    std::istringstream in(tum_lines[k]);
    double v[8];
    for (double& x : v) in >> x;
    double c[3];
    user_centre(g, c);
    CHECK(v[0] == doctest::Approx(g / 30.0));
    for (int i = 0; i < 3; ++i) CHECK(v[1 + i] == doctest::Approx(c[i]).epsilon(1e-6));
    // Camera-to-world = a turn of -g degrees about y: (qx, qy, qz, qw) = (0, -sin(g/2), 0, cos(g/2)).
    const double half = 0.5 * g * M_PI / 180;
    CHECK(v[4] == doctest::Approx(0).epsilon(1e-6));
    CHECK(v[5] == doctest::Approx(-std::sin(half)).epsilon(1e-6));
    CHECK(v[6] == doctest::Approx(0).epsilon(1e-6));
    CHECK(v[7] == doctest::Approx(std::cos(half)).epsilon(1e-6));
  }

  // COLMAP: the placed frames in frame order, named so that they sort in that order, world-to-camera.
  gs::Expected<gs::io::ColmapModel> cm = gs::io::read_colmap_text(s.colmap_dir);
  REQUIRE_MESSAGE(cm.ok(), cm.status().to_string());
  REQUIRE(cm->cameras.size() == 1);
  CHECK(cm->cameras[0].model == "PINHOLE");
  CHECK(cm->cameras[0].width == kW);
  CHECK(cm->cameras[0].params[0] == doctest::Approx(kFx));
  REQUIRE(cm->images.size() == placed.size());
  for (size_t k = 0; k < placed.size(); ++k) {
    const gs::io::ColmapImage& im = cm->images[k];
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%06d.png", placed[k]);
    CHECK(im.name == name);
    CHECK(im.id == k + 1);
    if (k > 0) CHECK(cm->images[k - 1].name < im.name);
    double R[9], c[3];
    gs::pose::rotation_from_quaternion(im.qvec, R);
    user_centre(placed[k], c);
    for (int i = 0; i < 3; ++i)  // t = -R C_user
      CHECK(im.tvec[i] == doctest::Approx(-(R[3 * i] * c[0] + R[3 * i + 1] * c[1] + R[3 * i + 2] * c[2])).epsilon(1e-6));
    CHECK(im.qvec[2] == doctest::Approx(std::sin(0.5 * placed[k] * M_PI / 180)).epsilon(1e-6));
  }

  // The lost list: frames 2, 3, 7 with their times.
  const std::vector<std::string> lost = lines_of(s.lost_path);
  REQUIRE(lost.size() == 3);
  const int lost_frames[3] = {2, 3, 7};
  for (int k = 0; k < 3; ++k) {
    std::istringstream in(lost[size_t(k)]);
    long long frame = -1;
    double time = -1;
    in >> time >> frame;
    CHECK(frame == lost_frames[k]);
    CHECK(time == doctest::Approx(lost_frames[k] / 30.0).epsilon(1e-5));
  }

  // One JSON line per frame: number, time, verdict, the TUM pose for placed frames only, and the
  // TUM file's numbers exactly.
  REQUIRE(json_lines.size() == codes.size());
  size_t placed_k = 0;
  for (size_t i = 0; i < json_lines.size(); ++i) {
    CAPTURE(json_lines[i]);
    CHECK(json_lines[i].find('\n') == std::string::npos);
    const nlohmann::json j = nlohmann::json::parse(json_lines[i]);
    CHECK(j["frame"] == i);
    CHECK(j["time"].get<double>() == doctest::Approx(double(i) / 30).epsilon(1e-5));
    const std::string verdict = codes[i] == 10 ? "tracking" : codes[i] == 20 ? "relocalized" : "lost";
    CHECK(j["verdict"] == verdict);
    CHECK(j["rmse"].get<double>() == doctest::Approx(0.01 * double(i)));
    CHECK(j["ms"].get<double>() == doctest::Approx(4.0 + double(i)));
    if (verdict == "lost") {
      CHECK_FALSE(j.contains("tx"));
    } else {
      std::istringstream in(tum_lines[placed_k++]);
      double v[8];
      for (double& x : v) in >> x;
      const char* keys[7] = {"tx", "ty", "tz", "qx", "qy", "qz", "qw"};
      for (int k = 0; k < 7; ++k) CHECK(j[keys[k]].get<double>() == doctest::Approx(v[1 + k]).epsilon(1e-9));
    }
  }

  // track.json: the counts, the stages and the options.
  gs::Expected<std::string> text = gs::platform::read_text_file(s.json_path);
  REQUIRE(text.ok());
  const nlohmann::json j = nlohmann::json::parse(*text);
  CHECK(j["frames"] == 10);
  CHECK(j["verdicts"]["tracking"] == 6);
  CHECK(j["verdicts"]["relocalized"] == 1);
  CHECK(j["verdicts"]["lost"] == 3);
  CHECK(j["dropped"] == 0);
  CHECK(j["downscale"] == 2);
  CHECK(j["ms_per_frame"]["align"]["median"].get<double>() == doctest::Approx(2));
  CHECK(j["ms_per_frame"]["total"]["median"].get<double>() == doctest::Approx(8.5));  // 4 + 0..9
  CHECK(j["ms_per_frame"]["total"]["p95"].get<double>() == doctest::Approx(13));     // nearest rank 10 of 10
  CHECK(j["ms_per_frame"]["total"]["mean"].get<double>() == doctest::Approx(8.5));
  CHECK(j["options"]["realtime"] == false);
  CHECK(j["options"]["fixed_point"] == false);
  CHECK(j["candidates"] == 9);
}

TEST_CASE("track job: the start, a run's training views as candidates, max frames and the stop flag") {
  Fixture fx;
  const std::string frames = fx.frames("frames", kW, kH, {10, 10, 10, 10, 10, 10});
  // A run folder: run.json names the dataset, so the candidates are its training views (1..7).
  const std::string run = fx.dir / "run";
  fs::create_directories(run);
  fs::copy_file(fx.model, run + "/model.hbgs");
  REQUIRE(gs::platform::write_file_atomic(run + "/run.json", "{\"dataset\": \"" + fx.dataset + "\"}").ok());

  Seen seen;
  gs::jobs::TrackRunOptions o;
  o.input = run;
  o.source = frames;
  o.start_pose = "first";
  o.max_frames = 4;
  o.threads = 1;
  o.make_tracker = stand_in(&seen);
  gs::jobs::TrackRunSummary s;
  REQUIRE(gs::jobs::track_run(o, nullptr, &s).ok());
  CHECK(s.frames == 4);
  CHECK(s.downscale == 1);
  REQUIRE(seen.candidates.size() == 7);
  double C[3];
  gs::pose::centre(seen.candidates[0], C);
  CHECK(C[0] == doctest::Approx(kScale * (11.0 - kCentre[0])));  // view_1: the first training view
  CHECK(seen.resets_to_pose == 1);
  CHECK(seen.resets_to_candidates == 0);
  gs::pose::centre(seen.start, C);
  CHECK(C[0] == doctest::Approx(kScale * (11.0 - kCentre[0])));
  CHECK(s.trajectory_path.empty());  // no --out: no files

  // A start pose in the user's frame lands in the model's.
  seen = Seen();
  o.start_pose = "1 0 0 0 -104 -50 -20";  // centre (104, 50, 20)
  o.max_frames = 0;
  std::atomic<bool> stop{false};
  o.stop = &stop;
  int reported = 0;
  REQUIRE(gs::jobs::track_run(o, [&](const TrackedFrame&) { stop.store(++reported == 2); }, &s).ok());
  CHECK(s.frames == 2);
  CHECK(s.stopped);
  gs::pose::centre(seen.start, C);
  CHECK(C[0] == doctest::Approx(kScale * (104 - kCentre[0])));
  CHECK(C[1] == doctest::Approx(kScale * (50 - kCentre[1])));
  CHECK(C[2] == doctest::Approx(kScale * (20 - kCentre[2])));
}

TEST_CASE("track job: intrinsics fitted to the frames, and the errors") {
  Fixture fx;
  Seen seen;
  gs::jobs::TrackRunOptions o;
  o.input = fx.model;
  o.dataset = fx.dataset;
  o.threads = 1;
  o.out = fx.dir / "out";
  o.make_tracker = stand_in(&seen);
  gs::jobs::TrackRunSummary s;

  // Half the size: a uniform scale, the intrinsics follow the frames.
  o.source = fx.frames("half", kW / 2, kH / 2, {10, 10});
  REQUIRE(gs::jobs::track_run(o, nullptr, &s).ok());
  CHECK(s.downscale == 1);
  CHECK(seen.K.width == kW / 2);
  CHECK(seen.K.fx == doctest::Approx(kFx / 2));
  CHECK(seen.K.cy == doctest::Approx(kCy / 2));
  CHECK(s.notes.size() == 1);

  // Another aspect: refused, naming both sizes; nothing is written.
  o.source = fx.frames("other_aspect", 48, 40, {10});
  o.out = fx.dir / "out_aspect";
  gs::Status st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.code() == gs::StatusCode::kInvalidArgument);
  CHECK(st.message().find("48x40") != std::string::npos);
  CHECK(st.message().find("64x48") != std::string::npos);
  CHECK(st.message().find("--intrinsics") != std::string::npos);
  CHECK_FALSE(fs::exists(o.out));

  // --intrinsics: for the frames as delivered, whatever their size.
  o.intrinsics = "40,41,24,20";
  REQUIRE(gs::jobs::track_run(o, nullptr, &s).ok());
  CHECK(seen.K.width == 48);
  CHECK(seen.K.height == 40);
  CHECK(seen.K.fy == doctest::Approx(41));
  o.intrinsics = "40,41,24";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("--intrinsics: expected 4 numbers") != std::string::npos);
  o.intrinsics.clear();

  // A model file alone, without --intrinsics, --dataset or a run.json: no camera.
  o.dataset.clear();
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("--intrinsics") != std::string::npos);
  // With --intrinsics but no dataset: no candidates, so the start must be given.
  o.intrinsics = "40,41,24,20";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("--start-pose") != std::string::npos);
  o.start_pose = "1 0 0 0 0 0 4";
  CHECK(gs::jobs::track_run(o, nullptr, &s).ok());
  CHECK(seen.resets_to_pose == 1);
  o.start_pose = "somewhere";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("--start-pose") != std::string::npos);
  o.start_pose = "candidates";
  o.dataset = fx.dataset;
  o.intrinsics.clear();

  // A missing model, a missing source, a folder without images, a video without the capture library.
  o.input = fx.dir / "no_such_model.hbgs";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("no_such_model.hbgs not found") != std::string::npos);
  o.input = fx.model;
  o.source = fx.dir / "no_such_frames";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("no such file or folder") != std::string::npos);
  fs::create_directories(fx.dir / "empty");
  o.source = fx.dir / "empty";
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.message().find("no .png, .jpg or .jpeg images") != std::string::npos);
  o.source = fx.model;  // any file: the job's own stream reads folders only
  st = gs::jobs::track_run(o, nullptr, &s);
  CHECK(st.code() == gs::StatusCode::kUnsupported);
  CHECK(st.message().find("image folders only") != std::string::npos);
}

namespace {

// Frames in memory at times i / 32 s (exact in binary), all tracking.
class MemoryStream final : public gs::jobs::FrameStream {
 public:
  MemoryStream(int n, bool live) : n_(n), live_(live), image_(solid(kW, kH, 10, 0, 0)) {}
  std::string name() const override { return "memory"; }
  bool live() const override { return live_; }
  gs::Status next(gs::jobs::StreamFrame* f, bool* end) override {
    *end = ++i_ >= n_;
    f->width = kW, f->height = kH, f->time = 5 + double(i_) / 32, f->sequence = uint64_t(i_);
    return gs::Status::Ok();
  }
  gs::Status pixels(const uint8_t** rgb) override {
    image_.pixels[1] = uint8_t(i_);
    *rgb = image_.pixels.data();
    return gs::Status::Ok();
  }

 private:
  int n_, i_ = -1;
  bool live_;
  gs::io::Image8 image_;
};

struct RealtimeRun {
  gs::jobs::TrackRunSummary summary;
  std::vector<int64_t> dropped, tracked;
  Seen seen;
  FakeClock clock;
};

void run_realtime(const Fixture& fx, bool realtime, bool live, double cost, RealtimeRun* r, double setup = 0) {
  gs::jobs::TrackRunOptions o;
  o.input = fx.model;
  o.dataset = fx.dataset;
  o.source = "memory";
  o.realtime = realtime;
  o.threads = 1;
  o.open_source = [live](const std::string&, int, int) -> gs::Expected<std::unique_ptr<gs::jobs::FrameStream>> {
    return std::unique_ptr<gs::jobs::FrameStream>(new MemoryStream(10, live));
  };
  FakeClock* clock = &r->clock;
  o.clock = [clock] { return clock->now; };
  o.sleep = [clock](double s) {
    CHECK(s > 0);
    clock->now += s;
    ++clock->sleeps;
  };
  o.make_tracker = stand_in(&r->seen, clock, cost, setup);
  const gs::Status st = gs::jobs::track_run(
      o, [r](const TrackedFrame& f) { (f.dropped ? r->dropped : r->tracked).push_back(f.index); }, &r->summary);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
}

}  // namespace

TEST_CASE("track job: --realtime drops the frames the tracker is too slow for, with an injected clock") {
  Fixture fx;
  {
    // A tracker taking 45 ms for frames 31.25 ms apart: a frame is dropped when it is late by a
    // whole interval when the tracker is ready. By hand (times after the first frame, ms): frame 1
    // due 31.25, tracker ready at 45 (13.75 late: tracked); 2 due 62.5, ready 90 (27.5: tracked);
    // 3 due 93.75, ready 135 (41.25: dropped); 4 due 125 (10: tracked, ready 180); 5 due 156.25
    // (23.75: tracked, ready 225); 6 due 187.5 (37.5: dropped); 7 (6.25: tracked, ready 270);
    // 8 (20: tracked, ready 315); 9 due 281.25 (33.75: dropped).
    RealtimeRun r;
    run_realtime(fx, true, false, 0.045, &r);
    CHECK(r.dropped == std::vector<int64_t>{3, 6, 9});
    CHECK(r.tracked == std::vector<int64_t>{0, 1, 2, 4, 5, 7, 8});
    CHECK(r.summary.dropped == 3);
    CHECK(r.summary.frames == 10);
    CHECK(r.clock.sleeps == 0);  // always behind: never waits
    // The tracker got the tracked frames' times, relative to the first frame.
    REQUIRE(r.seen.times.size() == 7);
    CHECK(r.seen.times[3] == doctest::Approx(4.0 / 32));
    // Every tracked frame was less than one interval late.
    const double t0 = r.seen.clock_at_track[0];
    for (size_t k = 0; k < r.tracked.size(); ++k)
      CHECK(r.seen.clock_at_track[k] - t0 - double(r.tracked[k]) / 32 < 1.0 / 32);
  }
  {
    // The same tracker without --realtime: every frame is tracked, however late.
    RealtimeRun r;
    run_realtime(fx, false, false, 0.045, &r);
    CHECK(r.dropped.empty());
    CHECK(r.tracked.size() == 10);
    CHECK(r.clock.sleeps == 0);
  }
  {
    // A fast tracker (10 ms): a file source is paced to its frame times (a wait before each frame
    // after the first), nothing is dropped, and each frame is tracked at its due time.
    RealtimeRun r;
    run_realtime(fx, true, false, 0.010, &r);
    CHECK(r.dropped.empty());
    CHECK(r.clock.sleeps == 9);
    const double t0 = r.seen.clock_at_track[0];
    for (size_t k = 0; k < 10; ++k) CHECK(r.seen.clock_at_track[k] - t0 == doctest::Approx(double(k) / 32));
  }
  {
    // A live source is never waited for (the camera delivers in real time); a slow tracker drops
    // frames from it by the same rule.
    RealtimeRun r;
    run_realtime(fx, true, true, 0.010, &r);
    CHECK(r.clock.sleeps == 0);
    CHECK(r.dropped.empty());
    RealtimeRun slow;
    run_realtime(fx, true, true, 0.045, &slow);
    CHECK(slow.dropped == std::vector<int64_t>{3, 6, 9});
  }
  {
    // Making the tracker takes 200 ms after the first frame was taken. A camera kept delivering
    // meanwhile: its clock starts at the first frame, so the frames it queued are late and dropped
    // until the tracker has caught up (by hand, 10 ms per frame: frame 0 tracked at 200 ms, ready at
    // 210; frames 1-5 (31.25 .. 156.25 ms) are 179 .. 54 ms late: dropped; frame 6 (187.5) is 22.5
    // late: tracked, ready at 220; 7 (218.75) 1.25 late; 8 and 9 are early and not waited for).
    RealtimeRun live;
    run_realtime(fx, true, true, 0.010, &live, 0.2);
    CHECK(live.dropped == std::vector<int64_t>{1, 2, 3, 4, 5});
    CHECK(live.clock.sleeps == 0);
    // A file is played from when the tracker is ready: nothing is late.
    RealtimeRun file;
    run_realtime(fx, true, false, 0.010, &file, 0.2);
    CHECK(file.dropped.empty());
    CHECK(file.clock.sleeps == 9);
  }
}
