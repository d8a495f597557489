// SPDX-License-Identifier: MIT
// The ingestion pipeline: analyse, select, write the kept frames, run COLMAP, publish by rename.
#include "gs/capture/ingest.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <system_error>

#include "gs/capture/convert.h"
#include "gs/capture/image_folder_source.h"
#include "gs/io/image.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#if defined(GS_HAVE_LIBAV)
#include "gs/capture/video_source.h"
#endif

namespace gs::capture {
namespace fs = std::filesystem;
namespace {

constexpr int32_t kAcquireTimeoutMs = 5000;  // a file source never times out; a stalled one errs

std::string strip_slashes(std::string p) {
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  return p;
}

// Visits every frame of a fresh source as RGB24: visit(rgb, width, height, stride, frame).
Status for_each_frame(const SourceFactory& make_source, std::string* name,
                      const std::function<Status(const uint8_t*, const FrameView&)>& visit) {
  Expected<std::unique_ptr<FrameSource>> made = make_source();
  if (!made.ok()) return made.status();
  FrameSource& src = **made;
  if (name != nullptr) *name = src.name();
  FrameFormat want, got;
  want.format = PixelFormat::kRGB24;
  GS_RETURN_IF_ERROR(src.configure(want, &got));
  GS_RETURN_IF_ERROR(src.start());
  std::vector<uint8_t> rgb;
  Status status;
  for (;;) {
    FrameView frame;
    Expected<AcquireResult> r = src.acquire(kAcquireTimeoutMs, &frame);
    if (!r.ok()) {
      status = r.status();
      break;
    }
    if (*r == AcquireResult::kEndOfStream) break;
    if (*r == AcquireResult::kTimeout) {
      status = io_error(std::string(src.name()) + ": no frame within " + std::to_string(kAcquireTimeoutMs) + " ms");
      break;
    }
    rgb.resize(size_t(frame.width) * size_t(frame.height) * 3);
    status = frame_to_rgb(frame, rgb.data(), 3 * frame.width);
    if (status.ok()) status = visit(rgb.data(), frame);
    const Status released = src.release(frame);
    if (status.ok()) status = released;
    if (!status.ok()) break;
  }
  const Status stopped = src.stop();
  return status.ok() ? stopped : status;
}

// The SfM consistency check (colmap_sfm.h): the limits, the summary, every view's agreement and the
// suspect views' names (what a view-repair step reads).
nlohmann::json consistency_json(const SfmConsistency& c, const ColmapOptions& o) {
  nlohmann::json views = nlohmann::json::array();
  for (const ViewAgreement& v : c.views)
    views.push_back({{"name", v.name}, {"check_runs", v.check_runs}, {"disagreeing", v.disagreeing},
                     {"rotation_deg", v.rotation_deg}, {"centre_fraction", v.centre_fraction}, {"suspect", v.suspect}});
  return {{"check_runs", c.check_runs},
          {"aligned_runs", c.aligned_runs},
          {"suspect_rotation_deg", o.suspect_rotation_deg},
          {"suspect_centre_fraction", o.suspect_centre_fraction},
          {"suspect", c.suspect},
          {"suspect_views", c.suspect_names()},
          {"rotation_median_deg", c.rotation_median_deg},
          {"rotation_max_deg", c.rotation_max_deg},
          {"seconds", c.seconds},
          {"views", std::move(views)}};
}

nlohmann::json report_json(const IngestReport& r, const IngestOptions& o) {
  nlohmann::json j;
  j["source"] = r.source;
  j["frames"] = {{"analysed", r.select.total}, {"blurred", r.select.blurred}, {"kept", r.select.kept},
                 {"target", o.select.target_count}, {"blur_ratio", o.select.blur_ratio},
                 {"total_motion", r.select.total_motion}, {"kept_frame_numbers", r.kept_frames}};
  j["size"] = {{"decoded", {r.width, r.height}}, {"written", {r.out_width, r.out_height}}};
  j["colmap"] = {{"camera_model", o.colmap.camera_model},
                 {"undistorted_by", is_fisheye_model_name(o.colmap.camera_model) ? "hbgs" : "colmap"},
                 {"images", r.colmap.images},
                 {"registered", r.colmap.registered},
                 {"reconstructions", r.colmap.models},
                 {"points", r.colmap.points},
                 {"seconds", {{"features", r.colmap.seconds_features},
                              {"matching", r.colmap.seconds_matching},
                              {"mapping", r.colmap.seconds_mapping},
                              {"undistortion", r.colmap.seconds_undistort}}}};
  j["colmap"]["consistency"] = consistency_json(r.colmap.consistency, o.colmap);
  j["colmap"]["consistency"]["mapping_seed"] = r.colmap.chosen_seed;
  j["colmap"]["consistency"]["first_mapping_suspect"] = r.colmap.first_run_suspect;
  j["seconds"] = {{"analyse", r.seconds_analyse}, {"write", r.seconds_write}, {"total", r.seconds_total}};
  return j;
}

// Moves `partial` to `out`; with an existing `out` (only allowed with force) the old one is moved
// aside first and deleted only after the new one is in place.
Status publish(const std::string& partial, const std::string& out) {
  std::error_code ec;
  std::string old;
  if (fs::exists(out, ec)) {
    old = out + ".old." + std::to_string(::getpid());
    fs::rename(out, old, ec);
    if (ec) return io_error("cannot move the old " + out + " aside: " + ec.message());
  }
  fs::rename(partial, out, ec);
  if (ec) {
    std::error_code ignored;
    if (!old.empty()) fs::rename(old, out, ignored);
    return io_error("cannot rename " + partial + " to " + out + ": " + ec.message());
  }
  if (!old.empty()) fs::remove_all(old, ec);
  return Status::Ok();
}

}  // namespace

std::string frame_file_name(int64_t frame_index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%06lld.png", static_cast<long long>(frame_index));
  return buf;
}

Status check_output_folder(const std::string& out_dir, bool force) {
  std::error_code ec;
  const fs::path out(out_dir);
  if (!fs::exists(out, ec)) return Status::Ok();
  if (!fs::is_directory(out, ec)) return invalid_argument(out_dir + " exists and is not a folder");
  if (fs::is_empty(out, ec) || force) return Status::Ok();
  if (fs::exists(out / "sparse", ec) || fs::exists(out / "images", ec))
    return invalid_argument(out_dir + " already holds a dataset (" +
                            (fs::exists(out / "sparse", ec) ? (out / "sparse") : (out / "images")).string() +
                            "); pass --force to replace it");
  return invalid_argument(out_dir + " is not empty; choose a new folder or pass --force to replace it");
}

Expected<std::unique_ptr<FrameSource>> open_input(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return io_error("no such file or folder: " + path);
  if (fs::is_directory(path, ec)) return std::unique_ptr<FrameSource>(new ImageFolderSource(path));
#if defined(GS_HAVE_LIBAV)
  return std::unique_ptr<FrameSource>(new VideoSource(path));
#else
  return unsupported("cannot read video " + path +
                     ": hbgs was built without FFmpeg's libraries (libavformat-dev, libavcodec-dev, libswscale-dev); "
                     "extract the frames to a folder and ingest that instead");
#endif
}

Status ingest(const SourceFactory& make_source, const std::string& out_arg, const IngestOptions& o,
              const ProgressFn& progress, IngestReport* report) {
  const double t_start = platform::now_seconds();
  const std::string out = strip_slashes(out_arg);
  GS_RETURN_IF_ERROR(check_output_folder(out, o.force));
  if (o.select.target_count < 2) return invalid_argument("--frames must be at least 2");
  GS_RETURN_IF_ERROR(check_colmap(o.colmap));
  const std::string partial = out + ".partial";
  std::error_code ec;
  fs::remove_all(partial, ec);
  if (ec) return io_error("cannot clear the stale " + partial + ": " + ec.message());
  const std::string work = partial + "/work", frames_dir = work + "/frames";
  GS_RETURN_IF_ERROR(platform::make_dirs(frames_dir));
  auto say = [&](const std::string& s) {
    if (progress) progress(s);
  };

  IngestReport rep;
  // Pass 1: statistics of every frame.
  std::vector<FrameStats> stats;
  FrameAnalyzer analyzer;
  say("analysing frames (sharpness, motion)");
  double t0 = platform::now_seconds();
  GS_RETURN_IF_ERROR(for_each_frame(make_source, &rep.source, [&](const uint8_t* rgb, const FrameView& f) -> Status {
    if (stats.empty()) {
      Expected<FrameAnalyzer> a = FrameAnalyzer::create(f.width, f.height);
      if (!a.ok()) return a.status();
      analyzer = std::move(*a);
      rep.width = f.width;
      rep.height = f.height;
    }
    Expected<FrameStats> s = analyzer.add(rgb, f.width, f.height, 3 * f.width, int64_t(stats.size()), f.timestamp_ns);
    if (!s.ok()) return s.status();
    stats.push_back(*s);
    if (stats.size() % 100 == 0) say("  " + std::to_string(stats.size()) + " frames analysed");
    return Status::Ok();
  }));
  rep.seconds_analyse = platform::now_seconds() - t0;
  if (stats.size() < 2)
    return invalid_argument(rep.source + " has " + std::to_string(stats.size()) +
                            " frame(s); structure from motion needs at least 2");

  const std::vector<size_t> kept = select_frames(stats, o.select, &rep.select);
  for (size_t k : kept) rep.kept_frames.push_back(stats[k].index);
  say("kept " + std::to_string(kept.size()) + " of " + std::to_string(stats.size()) + " frames (" +
      std::to_string(rep.select.blurred) + " rejected as blurred)");

  // Pass 2: write the kept frames (frame numbers are the analysis order, which is the source order).
  t0 = platform::now_seconds();
  size_t next = 0;
  int64_t frame_number = 0;
  rep.out_width = rep.width;
  rep.out_height = rep.height;
  if (o.max_width > 0 && rep.width > o.max_width) {
    rep.out_width = o.max_width;
    rep.out_height = std::max(1, int(double(rep.height) * o.max_width / rep.width + 0.5));
  }
  GS_RETURN_IF_ERROR(for_each_frame(make_source, nullptr, [&](const uint8_t* rgb, const FrameView& f) -> Status {
    const int64_t n = frame_number++;
    if (next >= rep.kept_frames.size() || rep.kept_frames[next] != n) return Status::Ok();
    ++next;
    io::Image8 img;
    img.width = f.width;
    img.height = f.height;
    img.channels = 3;
    img.pixels.assign(rgb, rgb + size_t(f.width) * size_t(f.height) * 3);
    if (rep.out_width != f.width) img = io::resize_area(img, rep.out_width, rep.out_height);
    return io::write_png(frames_dir + "/" + frame_file_name(n), img);
  }));
  if (next != rep.kept_frames.size())
    return io_error(rep.source + " delivered fewer frames on the second pass (" + std::to_string(frame_number) +
                    ") than on the first (" + std::to_string(stats.size()) + ")");
  rep.seconds_write = platform::now_seconds() - t0;

  const std::string log = partial + "/colmap.log";
  const Status sfm = run_colmap_sfm(frames_dir, work, partial, log, o.colmap, progress, &rep.colmap);
  rep.seconds_total = platform::now_seconds() - t_start;
  if (report != nullptr) *report = rep;
  if (!sfm.ok()) return Status(sfm.code(), sfm.message() + "\n(work kept in " + partial + ")");

  GS_RETURN_IF_ERROR(platform::write_file_atomic(partial + "/ingest.json", report_json(rep, o).dump(2) + "\n"));
  if (!o.keep_work) fs::remove_all(work, ec);
  GS_RETURN_IF_ERROR(publish(partial, out));
  say("dataset written to " + out + " (" + std::to_string(rep.colmap.registered) + " of " +
      std::to_string(rep.colmap.images) + " frames registered, " + std::to_string(rep.colmap.points) + " points)");
  return Status::Ok();
}

}  // namespace gs::capture
