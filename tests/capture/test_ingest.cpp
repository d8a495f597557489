// SPDX-License-Identifier: MIT
// The ingestion pipeline without the slow real COLMAP: a stub `colmap` shell script stands in for
// each stage (it writes a prepared model, or fails the way COLMAP fails), so the pipeline's own
// promises are checked quickly: the output folder appears only on success, an existing dataset is
// refused unless forced and then replaced whole, errors name what went wrong (missing COLMAP, a
// failed stage with its exit code and last lines, too few frames registered, a corrupt video),
// and the result loads with gs::io::load_dataset. Also the live capture loop with a scripted
// source (YUYV frames, dropped frames, a stalled camera). The real-COLMAP run is the
// `capture_ingest_synthetic_video` end-to-end test.
#include <doctest/doctest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/capture/capture_session.h"
#include "gs/capture/ingest.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/platform/file.h"
#include "support/rgb_image.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using gs::capture::IngestOptions;

constexpr int kW = 96, kH = 64, kFrames = 24;

// A panning textured frame (enough detail for the sharpness measure).
gs::io::Image8 frame_image(int i) {
  return gs::test::rgb_image(kW, kH, [i](int x, int y, int c) {
    const double u = x + 3.0 * i;
    const bool check = (int(u / 7) + y / 7) % 2 == 0;
    return uint8_t((check ? 200 : 40) + 15 * std::sin(0.3 * u + c));
  });
}

void write_frames(const std::string& dir) {
  REQUIRE(gs::platform::make_dirs(dir).ok());
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "img_%03d.png", i);
    REQUIRE(gs::io::write_png(dir + "/" + name, frame_image(i)).ok());
  }
}

// A COLMAP model over the given image names (camera centres on a parabola, a few points), as
// COLMAP's mapper and undistorter would leave it; the view named `turned` is turned 20 degrees
// about the vertical (a corrupted reconstruction's misplaced view).
void write_model(const std::string& dir, const std::vector<std::string>& names, bool binary, const std::string& turned = "") {
  gs::io::ColmapModel m;
  gs::io::ColmapCamera cam;
  cam.id = 1;
  cam.model = "PINHOLE";
  cam.width = kW;
  cam.height = kH;
  cam.params = {80, 80, kW / 2.0, kH / 2.0};
  m.cameras.push_back(cam);
  for (size_t i = 0; i < names.size(); ++i) {
    gs::io::ColmapImage im;
    im.id = uint32_t(i + 1);
    im.camera_id = 1;
    im.name = names[i];
    im.tvec[0] = -0.1 * double(i);
    im.tvec[1] = 0.02 * double(i) * double(i);
    im.tvec[2] = 4.0;
    if (im.name == turned) {  // the same centre (-R^T t), the rotation turned: t becomes R t
      const double a = 20.0 * M_PI / 180;
      im.qvec[0] = std::cos(a / 2);
      im.qvec[2] = std::sin(a / 2);
      const double x = im.tvec[0], z = im.tvec[2];
      im.tvec[0] = std::cos(a) * x + std::sin(a) * z;
      im.tvec[2] = -std::sin(a) * x + std::cos(a) * z;
    }
    m.images.push_back(im);
  }
  for (int p = 0; p < 10; ++p) {
    gs::io::ColmapPoint3D pt;
    pt.id = uint64_t(p + 1);
    pt.xyz[0] = 0.1 * p;
    pt.rgb[0] = 200;
    m.points.push_back(pt);
  }
  REQUIRE(gs::platform::make_dirs(dir).ok());
  REQUIRE((binary ? gs::io::write_colmap_binary(m, dir) : gs::io::write_colmap_text(m, dir)).ok());
}

// Writes an executable stub `colmap`. mode: "ok" (every stage succeeds; the mapper registers the
// first `registered` frames), "mapfail" (the mapper exits 3 after printing a reason), "seed1turns"
// (as "ok", but the mapper with --random_seed 1 turns frame 3 by 20 degrees).
std::string write_stub(const gs::test::TempDir& tmp, const std::string& mode, int registered) {
  const std::string model_txt = tmp / "stub_model_txt", model_bin = tmp / "stub_model_bin";
  const std::string turned_txt = tmp / "stub_model_turned";
  std::vector<std::string> names;
  for (int i = 0; i < registered; ++i) names.push_back(gs::capture::frame_file_name(i));
  write_model(model_txt, names, false);
  write_model(model_bin, names, true);
  write_model(turned_txt, names, false, gs::capture::frame_file_name(3));
  const std::string path = tmp / ("colmap_" + mode);
  std::ofstream f(path);
  f << "#!/bin/sh\n"
    << "cmd=$1; shift\n"
    << "while [ $# -gt 0 ]; do case $1 in --output_path) out=$2;; --image_path) img=$2;; --random_seed) seed=$2;; esac; shift; done\n"
    << "case $cmd in\n"
    << "  feature_extractor) echo \"Processed file [1/1]\"; exit 0;;\n"
    << "  sequential_matcher|exhaustive_matcher) echo matched; exit 0;;\n"
    << "  mapper)\n";
  if (mode == "mapfail") f << "    echo 'ERROR: not enough inliers'; exit 3;;\n";
  else if (mode == "seed1turns")
    f << "    model=" << model_txt << "; [ \"$seed\" = 1 ] && model=" << turned_txt << "\n"
      << "    mkdir -p \"$out/0\" && cp \"$model\"/* \"$out/0/\"; exit 0;;\n";
  else f << "    mkdir -p \"$out/0\" && cp " << model_txt << "/* \"$out/0/\"; echo 'Registering image #1 (1)'; exit 0;;\n";
  f << "  image_undistorter)\n"
    << "    mkdir -p \"$out/images\" \"$out/sparse\" && cp \"$img\"/* \"$out/images/\" && cp " << model_bin
    << "/*.bin \"$out/sparse/\"; exit 0;;\n"
    << "esac\n"
    << "echo \"unknown command $cmd\"; exit 2\n";
  f.close();
  REQUIRE(::chmod(path.c_str(), 0755) == 0);
  return path;
}

gs::Status run_ingest(const std::string& input, const std::string& out, const IngestOptions& o,
                      gs::capture::IngestReport* rep = nullptr) {
  return gs::capture::ingest([input] { return gs::capture::open_input(input); }, out, o, {}, rep);
}

IngestOptions options_with(const std::string& colmap, int frames) {
  IngestOptions o;
  o.colmap.colmap = colmap;
  o.select.target_count = frames;
  return o;
}

}  // namespace

TEST_CASE("ingest with a stub COLMAP writes a dataset load_dataset reads") {
  gs::test::TempDir tmp("gs_ingest");
  write_frames(tmp / "frames");
  // Every frame is kept (the stub's model names them all); selection has its own tests.
  const std::string stub = write_stub(tmp, "ok", kFrames);
  gs::capture::IngestReport rep;
  const gs::Status st = run_ingest(tmp / "frames", tmp / "ds", options_with(stub, kFrames), &rep);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  CHECK(rep.select.total == kFrames);
  CHECK(rep.select.kept == kFrames);
  CHECK(rep.kept_frames.size() == size_t(kFrames));
  CHECK(rep.colmap.registered == kFrames);
  CHECK(rep.colmap.images == kFrames);
  CHECK(fs::exists(tmp / "ds/ingest.json"));
  CHECK(fs::exists(tmp / "ds/colmap.log"));
  CHECK(!fs::exists(tmp / "ds/work"));          // removed unless --keep-work
  CHECK(!fs::exists(tmp / "ds.partial"));       // published by rename
  gs::io::DatasetOptions dopt;
  dopt.llffhold = 0;
  gs::Expected<gs::io::Dataset> ds = gs::io::load_dataset(tmp / "ds", dopt);
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  CHECK(ds->views.size() == size_t(kFrames));
  // The kept frames are written under their source frame numbers.
  for (int64_t n : rep.kept_frames) CHECK(fs::exists(tmp / ("ds/images/" + gs::capture::frame_file_name(n))));
}

TEST_CASE("ingest: the consistency check maps again with other seeds and lists the views they disagree on in ingest.json") {
  gs::test::TempDir tmp("gs_ingest");
  write_frames(tmp / "frames");
  const std::string name3 = gs::capture::frame_file_name(3);
  for (int check_runs : {0, 1, 2, 3}) {
    INFO(check_runs << " check run(s)");
    IngestOptions o = options_with(write_stub(tmp, "seed1turns", 12), 12);
    o.colmap.check_runs = check_runs;
    o.force = true;
    std::vector<std::string> lines;
    gs::capture::IngestReport rep;
    const gs::Status st = gs::capture::ingest([&] { return gs::capture::open_input(tmp / "frames"); }, tmp / "ds", o,
                                              [&](const std::string& l) { lines.push_back(l); }, &rep);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
    const gs::capture::SfmConsistency& c = rep.colmap.consistency;
    CHECK(c.check_runs == check_runs);
    CHECK(c.aligned_runs == check_runs);
    // Seed 1 turns frame 3; seeds 2 and 3 agree with the chosen reconstruction. Suspect when at
    // least half of the check runs disagree: with 1 or 2 runs, not with 3.
    const bool flagged = check_runs == 1 || check_runs == 2;
    CHECK(c.suspect_names() == (flagged ? std::vector<std::string>{name3} : std::vector<std::string>{}));
    const nlohmann::json j = nlohmann::json::parse(gs::platform::read_text_file(tmp / "ds/ingest.json").value());
    const nlohmann::json& cj = j["colmap"]["consistency"];
    CHECK(cj["check_runs"] == check_runs);
    CHECK(cj["suspect_views"] == (flagged ? nlohmann::json::array({name3}) : nlohmann::json::array()));
    CHECK(cj["views"].size() == (check_runs > 0 ? 12u : 0u));
    for (const nlohmann::json& v : cj["views"]) {
      INFO(v.dump());
      CHECK(v["check_runs"] == check_runs);
      const bool turned = v["name"] == name3;
      CHECK(v["disagreeing"] == (turned ? 1 : 0));
      CHECK(v["rotation_deg"].get<double>() == doctest::Approx(turned ? 20.0 : 0.0).epsilon(1e-6));
      CHECK(v["centre_fraction"].get<double>() < 1e-6);  // turned in place
      CHECK(v["suspect"] == (turned && flagged));
    }
    bool said = false;
    for (const std::string& l : lines) said = said || (l.find("suspect: " + name3) != std::string::npos);
    CHECK(said == flagged);
  }
}

TEST_CASE("ingest refuses an existing dataset unless forced and then replaces it whole") {
  gs::test::TempDir tmp("gs_ingest");
  write_frames(tmp / "frames");
  const std::string stub = write_stub(tmp, "ok", 12);
  REQUIRE(run_ingest(tmp / "frames", tmp / "ds", options_with(stub, 12)).ok());
  REQUIRE(gs::platform::write_file_atomic(tmp / "ds/marker.txt", std::string("old")).ok());

  const gs::Status refused = run_ingest(tmp / "frames", tmp / "ds", options_with(stub, 12));
  REQUIRE(!refused.ok());
  CHECK(refused.message().find("already holds a dataset") != std::string::npos);
  CHECK(refused.message().find("--force") != std::string::npos);
  CHECK(fs::exists(tmp / "ds/marker.txt"));

  IngestOptions forced = options_with(stub, 12);
  forced.force = true;
  REQUIRE(run_ingest(tmp / "frames", tmp / "ds", forced).ok());
  CHECK(!fs::exists(tmp / "ds/marker.txt"));  // replaced, not merged
  CHECK(fs::exists(tmp / "ds/sparse/0/images.bin"));

  // A non-empty folder that is not a dataset, and a file, are refused too.
  REQUIRE(gs::platform::make_dirs(tmp / "other").ok());
  REQUIRE(gs::platform::write_file_atomic(tmp / "other/notes.txt", std::string("x")).ok());
  CHECK(gs::capture::check_output_folder(tmp / "other", false).message().find("not empty") != std::string::npos);
  CHECK(gs::capture::check_output_folder(tmp / "other/notes.txt", true).message().find("not a folder") !=
        std::string::npos);
  CHECK(gs::capture::check_output_folder(tmp / "fresh", false).ok());
}

TEST_CASE("ingest failures leave no output folder and say why") {
  gs::test::TempDir tmp("gs_ingest");
  write_frames(tmp / "frames");

  SUBCASE("COLMAP missing is reported before any work") {
    const gs::Status st = run_ingest(tmp / "frames", tmp / "ds", options_with(tmp / "no/such/colmap", 12));
    REQUIRE(!st.ok());
    CHECK(st.message().find("COLMAP not found") != std::string::npos);
    CHECK(st.message().find("apt install colmap") != std::string::npos);
    CHECK(!fs::exists(tmp / "ds.partial"));
  }
  SUBCASE("a failing stage names itself with its exit code and output") {
    const gs::Status st = run_ingest(tmp / "frames", tmp / "ds", options_with(write_stub(tmp, "mapfail", 0), 12));
    REQUIRE(!st.ok());
    CHECK(st.message().find("mapping failed (exit code 3)") != std::string::npos);
    CHECK(st.message().find("not enough inliers") != std::string::npos);
    CHECK(st.message().find("work kept in") != std::string::npos);
    CHECK(fs::exists(tmp / "ds.partial/colmap.log"));
  }
  SUBCASE("too few registered frames says how many of how many") {
    const gs::Status st = run_ingest(tmp / "frames", tmp / "ds", options_with(write_stub(tmp, "ok", 2), 12));
    REQUIRE(!st.ok());
    CHECK(st.message().find("registered only 2 of 12 frames") != std::string::npos);
  }
  SUBCASE("a corrupt video is an error") {
    REQUIRE(gs::platform::write_file_atomic(tmp / "clip.mp4", std::string("this is not a video\n")).ok());
    const gs::Status st = run_ingest(tmp / "clip.mp4", tmp / "ds", options_with(write_stub(tmp, "ok", 12), 12));
    REQUIRE(!st.ok());
    CHECK(st.message().find("clip.mp4") != std::string::npos);
  }
  SUBCASE("a missing input is an error") {
    const gs::Status st = run_ingest(tmp / "nothing.mp4", tmp / "ds", options_with(write_stub(tmp, "ok", 12), 12));
    REQUIRE(!st.ok());
    CHECK(st.message().find("no such file") != std::string::npos);
  }
  CHECK(!fs::exists(tmp / "ds"));
}

namespace {

// A scripted live source: YUYV frames of a flat colour, sequence numbers with a gap, then either
// the end or a stall (timeouts forever).
class ScriptedCamera : public gs::capture::FrameSource {
 public:
  ScriptedCamera(int frames, bool stall) : frames_(frames), stall_(stall), buffer_(size_t(kW) * kH * 2) {
    for (size_t i = 0; i < buffer_.size(); i += 4) {
      buffer_[i] = 120;  // Y0
      buffer_[i + 1] = 90;
      buffer_[i + 2] = 120;  // Y1
      buffer_[i + 3] = 160;
    }
  }
  const char* name() const override { return "scripted"; }
  gs::Status configure(const gs::capture::FrameFormat&, gs::capture::FrameFormat* actual) override {
    actual->width = kW;
    actual->height = kH;
    actual->format = gs::capture::PixelFormat::kYUYV;
    return gs::Status::Ok();
  }
  gs::Status start() override { return gs::Status::Ok(); }
  gs::Expected<gs::capture::AcquireResult> acquire(int32_t, gs::capture::FrameView* f) override {
    if (sent_ == frames_) return stall_ ? gs::capture::AcquireResult::kTimeout : gs::capture::AcquireResult::kEndOfStream;
    f->width = kW;
    f->height = kH;
    f->format = gs::capture::PixelFormat::kYUYV;
    f->num_planes = 1;
    f->planes[0] = {buffer_.data(), buffer_.size(), 2 * kW};
    f->sequence = uint64_t(sent_ < 3 ? sent_ : sent_ + 2);  // two frames lost after the third
    f->buffer_index = 0;
    ++sent_;
    return gs::capture::AcquireResult::kFrame;
  }
  gs::Status release(const gs::capture::FrameView&) override { return gs::Status::Ok(); }
  gs::Status stop() override {
    stopped_ = true;
    return gs::Status::Ok();
  }
  bool stopped_ = false;

 private:
  int frames_, sent_ = 0;
  bool stall_;
  std::vector<uint8_t> buffer_;
};

}  // namespace

TEST_CASE("capture session saves converted frames and counts drops") {
  gs::test::TempDir tmp("gs_capture");
  ScriptedCamera cam(8, false);
  gs::capture::CaptureOptions o;
  o.every_nth = 2;
  gs::capture::CaptureReport rep;
  REQUIRE(gs::capture::capture_to_folder(cam, tmp / "raw", o, {}, &rep).ok());
  CHECK(cam.stopped_);
  CHECK(rep.received == 8);
  CHECK(rep.written == 4);
  CHECK(rep.dropped == 2);
  gs::Expected<gs::io::Image8> img = gs::io::read_image(tmp / ("raw/" + gs::capture::frame_file_name(3)));
  REQUIRE(img.ok());
  CHECK(img->width == kW);
  // Y 120, U 90, V 160 in BT.601 limited range: R = (298*104 + 409*32 + 128) >> 8 = 172.
  CHECK(int(img->pixels[0]) == 172);
}

TEST_CASE("capture session reports a stalled camera") {
  gs::test::TempDir tmp("gs_capture");
  ScriptedCamera cam(2, true);
  gs::capture::CaptureOptions o;
  o.timeout_ms = 300;
  const gs::Status st = gs::capture::capture_to_folder(cam, tmp / "raw", o, {}, nullptr);
  REQUIRE(!st.ok());
  CHECK(st.message().find("no frame for 300 ms") != std::string::npos);
  CHECK(cam.stopped_);
}
