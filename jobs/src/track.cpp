// SPDX-License-Identifier: MIT
// The tracking job (gs/jobs/track.h): model, intrinsics and candidates, the frame loop with its
// realtime dropping, and the files.
#include "gs/jobs/track.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <thread>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/tum.h"
#include "gs/model/hybrid_model.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/stats.h"
#include "camera_input.h"

namespace gs::jobs {
namespace {

namespace fs = std::filesystem;

// ---- The image folder stream ----

// Announces each file as a frame of the first image's size; decodes it only when its pixels are
// asked for (a dropped frame is never decoded).
class ImageFolderStream final : public FrameStream {
 public:
  ImageFolderStream(std::string folder, std::vector<std::string> files, double fps, io::Image8 first)
      : folder_(std::move(folder)), files_(std::move(files)), fps_(fps), image_(std::move(first)),
        width_(image_.width), height_(image_.height) {}
  std::string name() const override { return "images:" + folder_; }
  bool live() const override { return false; }
  Status next(StreamFrame* frame, bool* end) override {
    ++current_;
    *end = current_ >= files_.size();
    if (*end) return Status::Ok();
    frame->width = width_;
    frame->height = height_;
    frame->time = double(current_) / fps_;
    frame->sequence = current_;
    return Status::Ok();
  }
  Status pixels(const uint8_t** rgb) override {
    if (current_ >= files_.size()) return invalid_argument(name() + ": no current frame");
    if (current_ != decoded_) {  // the first image was read at open
      const std::string path = (fs::path(folder_) / files_[current_]).string();
      Expected<io::Image8> img = io::read_image(path, 3);
      if (!img.ok()) return Status(img.status().code(), "image folder " + folder_ + ": " + img.status().message());
      if (img->width != width_ || img->height != height_)
        return invalid_argument("image folder " + folder_ + ": " + files_[current_] + " is " + std::to_string(img->width) +
                                "x" + std::to_string(img->height) + ", the first image " + files_[0] + " is " +
                                std::to_string(width_) + "x" + std::to_string(height_));
      image_ = std::move(img).value();
      decoded_ = current_;
    }
    *rgb = image_.pixels.data();
    return Status::Ok();
  }

 private:
  std::string folder_;
  std::vector<std::string> files_;
  double fps_;
  io::Image8 image_;
  int width_, height_;
  size_t current_ = size_t(-1), decoded_ = 0;
};

// ---- gs::pose::Tracker behind FrameTracker ----

class PoseTracker final : public FrameTracker {
 public:
  explicit PoseTracker(std::unique_ptr<pose::Tracker> t) : t_(std::move(t)) {}
  Status set_candidates(const std::vector<Pose>& poses) override { return t_->set_candidates(poses); }
  Status reset(const Pose& start) override { return t_->reset(start); }
  void reset() override { t_->reset(); }
  Status track(const uint8_t* rgb, double time, pose::TrackResult* r) override { return t_->track(rgb, time, r); }
  uint64_t planned_bytes() const override { return t_->planned_bytes(); }

 private:
  std::unique_ptr<pose::Tracker> t_;
};

// ---- Set-up ----

// The model, the dataset behind it (when there is one) and what the job takes from them.
struct TrackSetup {
  ModelSource source;
  model::HybridModel model;
  bool have_camera = false;      // the dataset's shared camera (else --intrinsics)
  io::ColmapCamera camera;       // as stored (full resolution)
  PinholeIntrinsics intrinsics;  // the wanted frames: the camera at the training resolution, or --intrinsics (size 0 x 0)
  std::vector<Pose> candidates;  // in the model's frame
  std::string first_candidate;   // its view's name
  float background[3] = {0, 0, 0};
  std::vector<std::string> notes;
};

Status check_model_input(const std::string& input) {
  if (input.empty()) return invalid_argument("no model given (a run folder, .hbgs or .hbgc file)");
  if (!platform::file_exists(input)) return invalid_argument("model " + input + " not found");
  if (is_splat_file(input))
    return invalid_argument(input + " holds plain Gaussians; tracking needs an anchor model (a run folder, .hbgs or .hbgc file)");
  if (!is_model_input(input))
    return invalid_argument(input + " is neither a run folder (with run.json or model.hbgs) nor a model file (.hbgs, .hbgc)");
  return Status::Ok();
}

// The candidate poses (in the model's frame): a run's training views, or every view of a dataset
// given with --dataset.
void read_candidates(const io::DatasetFiles& files, bool training_only, const SceneFrame& frame, TrackSetup* s) {
  for (const io::DatasetFileView& v : files.views) {
    if (training_only && v.is_test) continue;
    const io::ColmapImage& im = files.model.images[v.model_image];
    double R[9];
    pose::rotation_from_quaternion(im.qvec, R);
    s->candidates.push_back(pose_to_frame(frame, R, im.tvec));
    if (s->first_candidate.empty()) s->first_candidate = v.name;
  }
}

Status set_up(const TrackRunOptions& a, TrackSetup* s) {
  GS_RETURN_IF_ERROR(check_model_input(a.input));
  const bool given = !a.intrinsics.empty();
  if (given) GS_RETURN_IF_ERROR(parse_intrinsics_text(a.intrinsics, "--intrinsics", &s->intrinsics));
  Expected<ModelSource> resolved = resolve_model_source(a.input, a.dataset, -1);
  if (resolved.ok()) {
    s->source = *resolved;
  } else if (given && !platform::is_directory(a.input)) {
    s->source.model_path = a.input;  // a model file alone: --intrinsics, no candidates
    s->source.run_dir = fs::path(a.input).has_parent_path() ? fs::path(a.input).parent_path().string() : ".";
  } else {
    return Status(resolved.status().code(), resolved.status().message() + (given ? "" : " (or pass --intrinsics fx,fy,cx,cy)"));
  }
  Expected<model::Background> background = model_background(s->source, a.background);
  if (!background.ok()) return background.status();
  if (background->random && !a.background.empty())
    return invalid_argument("--background random is for training; give black, white or r,g,b");
  std::copy(background->rgb, background->rgb + 3, s->background);

  Expected<model::HybridModel> m = model::load_model(s->source.model_path);
  if (!m.ok()) return m.status();
  s->model = std::move(m).value();

  if (!s->source.dataset.empty()) {
    GS_RETURN_IF_ERROR(check_dataset_path(s->source.dataset));
    Expected<io::DatasetFiles> files = io::read_dataset_files(s->source.dataset);
    if (!files.ok()) return files.status();
    read_candidates(*files, a.dataset.empty(), s->model.frame, s);
    if (!given) {
      std::string note;
      GS_RETURN_IF_ERROR(shared_dataset_camera(*files, s->source.dataset, "pass --intrinsics fx,fy,cx,cy", &s->camera, &note));
      if (!note.empty()) s->notes.push_back(note);
      s->have_camera = true;
      // The training resolution: the dataset loader's downscale to the run's max_width.
      int w = s->camera.width, h = s->camera.height;
      if (s->source.max_width > 0 && w > s->source.max_width) {
        h = std::max(1, int(std::lround(double(h) * s->source.max_width / w)));
        w = s->source.max_width;
      }
      s->intrinsics = scaled_intrinsics(s->camera, w, h);
    }
  }
  return Status::Ok();
}

// The start: "candidates", "first" or a pose text (checked before anything is loaded).
Status check_start(const std::string& start, Pose* pose) {
  if (start == "candidates" || start == "first") return Status::Ok();
  if (Status st = pose::parse_pose(start, "--start-pose", pose); !st.ok())
    return invalid_argument(st.message() + " (--start-pose takes first, candidates or \"qw qx qy qz tx ty tz\")");
  return Status::Ok();
}

// The frames' intrinsics and the box-filter factor that brings the source's frames to them.
Status fit_frames(const TrackSetup& s, const std::string& stream, int sw, int sh, PinholeIntrinsics* K, int* downscale,
                  std::vector<std::string>* notes) {
  *downscale = 1;
  *K = s.intrinsics;
  if (!s.have_camera) {  // --intrinsics: for the frames as delivered
    K->width = sw, K->height = sh;
    return Status::Ok();
  }
  const int W = s.intrinsics.width, H = s.intrinsics.height;
  if (sw == W && sh == H) return Status::Ok();
  if (sw % W == 0 && sh % H == 0 && sw / W == sh / H) {
    *downscale = sw / W;
    return Status::Ok();
  }
  if (is_uniform_scale(s.camera, sw, sh)) {
    *K = scaled_intrinsics(s.camera, sw, sh);
    notes->push_back("the frames (" + std::to_string(sw) + "x" + std::to_string(sh) + ") are not a whole multiple of the model's " +
                     std::to_string(W) + "x" + std::to_string(H) + "; they are tracked at their own size with the intrinsics scaled");
    return Status::Ok();
  }
  const std::string camera = std::to_string(s.camera.width) + "x" + std::to_string(s.camera.height);
  const std::string wanted = std::to_string(W) + "x" + std::to_string(H);
  return invalid_argument(stream + " delivers " + std::to_string(sw) + "x" + std::to_string(sh) + " frames, but the intrinsics are for " +
                          wanted + " (the dataset's camera" + (camera == wanted ? "" : " " + camera + " at the model's training resolution") +
                          "), and the frames are not a uniform scale of that; pass --intrinsics fx,fy,cx,cy for the source's frames");
}

Expected<std::unique_ptr<FrameStream>> open_folder_only(const std::string& source) {
  if (platform::is_directory(source)) return open_image_folder_stream(source);
  if (!platform::file_exists(source)) return io_error("no such file or folder: " + source);
  return unsupported("cannot read " + source + ": this program reads image folders only (it is built without the capture "
                     "library, so without video files and cameras; `hbgs track` reads those)");
}

// ---- Outputs ----

double percentile95(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t rank = size_t(std::ceil(0.95 * double(v.size())));
  return v[std::max<size_t>(rank, 1) - 1];
}

// "frame_000123.png": at least 6 digits, more when the frame numbers need them, so names sort in
// frame order.
std::string frame_name(int64_t index, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "frame_%0*lld.png", digits, static_cast<long long>(index));
  return buf;
}

struct Outputs {
  std::vector<TrackedFrame> placed;  // frames with a pose, in order
  std::vector<std::pair<int64_t, double>> lost;
  std::vector<int64_t> dropped;
};

nlohmann::ordered_json summary_json(const TrackRunOptions& a, const TrackRunSummary& s, const pose::TrackOptions& to,
                                    const Outputs& o) {
  const PinholeIntrinsics& K = s.intrinsics;
  nlohmann::ordered_json stages = nlohmann::ordered_json::object();
  for (const StageFigures& f : s.stages) stages[f.stage] = {{"mean", f.mean}, {"median", f.median}, {"p95", f.p95}};
  const int64_t tracked = s.frames - s.dropped;
  return {{"model", absolute_path(s.source.model_path)},
          {"dataset", s.source.dataset.empty() ? std::string() : absolute_path(s.source.dataset)},
          {"source", a.source},
          {"stream", s.stream},
          {"live", s.live},
          {"frames", s.frames},
          {"tracked", tracked},
          {"verdicts", {{"tracking", s.tracking}, {"relocalized", s.relocalized}, {"lost", s.lost}}},
          {"dropped", s.dropped},
          {"source_gaps", s.source_gaps},
          {"stopped", s.stopped},
          {"keyframes", s.keyframes},
          {"seconds", s.seconds},
          {"fps", s.fps},
          {"ms_per_frame", stages},
          {"ms_definition", "wall milliseconds per tracked frame: decode = reading, converting and resizing the frame; "
                            "prepare .. relocalize = the tracker's stages (gs::pose::TrackStageMs); total = the tracker's call"},
          {"source_size", {s.source_width, s.source_height}},
          {"downscale", s.downscale},
          {"intrinsics", {{"fx", K.fx}, {"fy", K.fy}, {"cx", K.cx}, {"cy", K.cy}, {"width", K.width}, {"height", K.height}}},
          {"candidates", s.candidates},
          {"start", s.start},
          {"threads", s.threads},
          {"planned_bytes", s.planned_bytes},
          {"options",
           {{"realtime", a.realtime},
            {"fixed_point", to.fixed_point},
            {"threads", a.threads},
            {"max_frames", a.max_frames},
            {"start_pose", a.start_pose},
            {"background", {to.background[0], to.background[1], to.background[2]}},
            {"track_downscale", to.track_downscale},
            {"levels", to.levels},
            {"iterations_per_level", to.iterations_per_level},
            {"keyframe_rotation_deg", to.keyframe_rotation_deg},
            {"keyframe_translation", to.keyframe_translation},
            {"keyframe_rmse_growth", to.keyframe_rmse_growth},
            {"huber_delta", to.huber_delta},
            {"max_correction_deg", to.max_correction_deg},
            {"max_correction_translation", to.max_correction_translation},
            {"verify_correction_deg", to.verify_correction_deg},
            {"max_rmse_growth", to.max_rmse_growth},
            {"basin_check_deg", to.basin_check_deg},
            {"chroma_weight", to.chroma_weight},
            {"max_rmse", to.max_rmse},
            {"min_explained", to.min_explained},
            {"min_coverage", to.min_coverage},
            {"motion_model", to.motion_model},
            {"relocalize_candidates", to.relocalize_candidates}}},
          {"files",
           {{"trajectory", kTrackTrajectoryFile}, {"colmap", kTrackColmapDir}, {"lost", kTrackLostFile}}},
          {"trajectory_format", "TUM: time tx ty tz qx qy qz qw (camera centre, camera-to-world rotation; user's frame); "
                                "time in seconds since the first frame"},
          {"notes", s.notes},
          {"dropped_frames", o.dropped}};
}

Status write_outputs(const TrackRunOptions& a, const pose::TrackOptions& to, const Outputs& o, TrackRunSummary* s) {
  const fs::path out(a.out);
  GS_RETURN_IF_ERROR(platform::make_dirs(a.out));
  s->trajectory_path = (out / kTrackTrajectoryFile).string();
  s->colmap_dir = (out / kTrackColmapDir).string();
  s->lost_path = (out / kTrackLostFile).string();
  s->json_path = (out / kTrackJson).string();

  std::vector<io::TimedPose> poses;
  poses.reserve(o.placed.size());
  for (const TrackedFrame& f : o.placed) poses.push_back({f.time, f.result.pose});
  GS_RETURN_IF_ERROR(io::write_tum_trajectory(poses, s->trajectory_path, s->frame));

  io::ColmapModel colmap;
  const PinholeIntrinsics& K = s->intrinsics;
  colmap.cameras.push_back({1, "PINHOLE", K.width, K.height, {double(K.fx), double(K.fy), double(K.cx), double(K.cy)}});
  int digits = 6;
  for (int64_t n = s->frames; n >= 1000000; n /= 10) ++digits;
  uint32_t id = 0;
  for (const TrackedFrame& f : o.placed) {
    io::ColmapImage im;
    im.id = ++id;
    im.camera_id = 1;
    im.name = frame_name(f.index, digits);
    io::pose_to_colmap(s->frame, f.result.pose, im.qvec, im.tvec);
    colmap.images.push_back(std::move(im));
  }
  GS_RETURN_IF_ERROR(io::write_colmap_text(colmap, s->colmap_dir));

  // Time first, as in the trajectory: `hbgs compare-poses --lost` reads the first word of a line.
  std::string lost = "# time frame: the frames the tracker could not place (time: seconds since the first frame; frame: 0-based number in the source)\n";
  char line[64];
  for (const auto& [index, time] : o.lost) {
    std::snprintf(line, sizeof(line), "%.6f %lld\n", time, static_cast<long long>(index));
    lost += line;
  }
  GS_RETURN_IF_ERROR(platform::write_file_atomic(s->lost_path, lost));
  return platform::write_file_atomic(s->json_path, summary_json(a, *s, to, o).dump(2) + "\n");
}

}  // namespace

Expected<std::unique_ptr<FrameStream>> open_image_folder_stream(const std::string& folder, double fps) {
  const std::string where = "image folder " + folder;
  if (!platform::is_directory(folder))
    return io_error(platform::file_exists(folder) ? where + ": not a directory" : "no such file or folder: " + folder);
  Expected<std::vector<std::string>> listed = io::list_image_files(folder);  // as capture's ImageFolderSource
  if (!listed.ok()) return Status(listed.status().code(), where + ": " + listed.status().message());
  std::vector<std::string> files = std::move(listed).value();
  if (files.empty()) return invalid_argument(where + ": no .png, .jpg or .jpeg images in it");
  Expected<io::Image8> first = io::read_image((fs::path(folder) / files[0]).string(), 3);
  if (!first.ok()) return Status(first.status().code(), where + ": " + first.status().message());
  return std::unique_ptr<FrameStream>(
      new ImageFolderStream(folder, std::move(files), fps > 0 ? fps : 30.0, std::move(first).value()));
}

Expected<std::unique_ptr<FrameTracker>> make_pose_tracker(const model::HybridModel& model, const PinholeIntrinsics& frame,
                                                          const pose::TrackOptions& options, platform::ThreadPool* pool) {
  Expected<std::unique_ptr<pose::Tracker>> t = pose::Tracker::create(model, frame, options, pool);
  if (!t.ok()) return t.status();
  return std::unique_ptr<FrameTracker>(new PoseTracker(std::move(t).value()));
}

std::string tracked_frame_json(const TrackedFrame& f) {
  char buf[640];
  const char* verdict = f.dropped ? "dropped" : pose::track_verdict_name(f.result.verdict);
  int n = std::snprintf(buf, sizeof(buf), "{\"frame\":%lld,\"time\":%.6f,\"verdict\":\"%s\"", static_cast<long long>(f.index),
                        f.time, verdict);
  if (!f.dropped) {
    if (f.has_pose)
      n += std::snprintf(buf + n, sizeof(buf) - size_t(n),
                         ",\"tx\":%.9g,\"ty\":%.9g,\"tz\":%.9g,\"qx\":%.9g,\"qy\":%.9g,\"qz\":%.9g,\"qw\":%.9g", f.tum[0], f.tum[1],
                         f.tum[2], f.tum[3], f.tum[4], f.tum[5], f.tum[6]);
    const pose::TrackResult& r = f.result;
    n += std::snprintf(buf + n, sizeof(buf) - size_t(n),
                       ",\"rmse\":%.6g,\"explained\":%.4g,\"coverage\":%.4g,\"iterations\":%d,\"keyframe\":%s,\"ms\":%.3f,"
                       "\"decode_ms\":%.3f",
                       r.rmse, r.explained, r.coverage, r.iterations, r.new_keyframe ? "true" : "false", r.ms.total, f.decode_ms);
  }
  std::snprintf(buf + n, sizeof(buf) - size_t(n), "}");
  return buf;
}

Status track_run(const TrackRunOptions& a, const std::function<void(const TrackedFrame&)>& on_frame, TrackRunSummary* summary) {
  const std::function<double()> clock = a.clock ? a.clock : [] { return platform::now_seconds(); };
  const std::function<void(double)> sleep =
      a.sleep ? a.sleep : [](double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); };
  if (a.source.empty()) return invalid_argument("no SOURCE given (a video file, an image folder or a camera)");
  if (a.max_frames < 0) return invalid_argument("--max-frames must be 0 (all) or positive");
  Pose start_pose;
  GS_RETURN_IF_ERROR(check_start(a.start_pose, &start_pose));
  if (!a.out.empty() && platform::file_exists(a.out) && !platform::is_directory(a.out))
    return invalid_argument("output " + a.out + " exists and is not a directory");

  TrackRunSummary s;
  TrackSetup setup;
  GS_RETURN_IF_ERROR(set_up(a, &setup));
  s.source = setup.source;
  s.frame = setup.model.frame;
  s.notes = setup.notes;
  s.candidates = setup.candidates.size();
  if (!a.out.empty() && !setup.source.dataset.empty()) GS_RETURN_IF_ERROR(check_output_outside_dataset(a.out, setup.source.dataset));
  // The start, in the model's frame.
  if (a.start_pose == "candidates" || a.start_pose == "first") {
    if (setup.candidates.empty())
      return invalid_argument("no candidate poses to place the first frame from (no dataset); give --dataset, or "
                              "--start-pose \"qw qx qy qz tx ty tz\"");
    if (a.start_pose == "first") start_pose = setup.candidates[0];
    s.start = a.start_pose == "first" ? "aligned from the first candidate (" + setup.first_candidate + ")"
                                      : "relocalised from " + std::to_string(setup.candidates.size()) + " candidates";
  } else {
    if (!s.frame.identity()) {  // read again in double: far from the origin float would lose the translation
      double q[4], t[3], R[9];
      pose_text_numbers(a.start_pose, q, t);
      pose::rotation_from_quaternion(q, R);
      start_pose = pose_to_frame(s.frame, R, t);
    }
    s.start = "aligned from --start-pose";
  }

  // The source and its first frame.
  const double t_open = clock();
  const FrameStreamOpener open =
      a.open_source ? a.open_source : [](const std::string& src, int, int) { return open_folder_only(src); };
  Expected<std::unique_ptr<FrameStream>> opened = open(a.source, setup.intrinsics.width, setup.intrinsics.height);
  if (!opened.ok()) return opened.status();
  FrameStream& stream = **opened;
  s.stream = stream.name();
  s.live = stream.live();
  StreamFrame frame;
  bool end = false;
  GS_RETURN_IF_ERROR(stream.next(&frame, &end));
  if (end) return invalid_argument(s.stream + " delivered no frames");
  const double t_first = clock();  // when the first frame was in hand
  double next_ms = (t_first - t_open) * 1e3;
  s.source_width = frame.width;
  s.source_height = frame.height;
  GS_RETURN_IF_ERROR(fit_frames(setup, s.stream, frame.width, frame.height, &s.intrinsics, &s.downscale, &s.notes));
  const PinholeIntrinsics& K = s.intrinsics;

  // The tracker, planned once.
  platform::ThreadPool pool(a.threads);
  s.threads = pool.num_threads();
  pose::TrackOptions to = a.tracker;
  std::copy(setup.background, setup.background + 3, to.background);
  std::copy(setup.background, setup.background + 3, to.relocalize.background);
  to.relocalize.fixed_point = to.relocalize.fixed_point || to.fixed_point;
  const TrackerFactory make = a.make_tracker ? a.make_tracker : make_pose_tracker;
  Expected<std::unique_ptr<FrameTracker>> made = make(setup.model, K, to, &pool);
  if (!made.ok()) return made.status();
  FrameTracker& tracker = **made;
  if (!setup.candidates.empty()) GS_RETURN_IF_ERROR(tracker.set_candidates(setup.candidates));
  if (a.start_pose == "candidates") tracker.reset();
  else GS_RETURN_IF_ERROR(tracker.reset(start_pose));
  s.planned_bytes = tracker.planned_bytes();
  std::vector<uint8_t> resized(s.downscale > 1 ? size_t(K.width) * size_t(K.height) * 3 : 0);

  // The frames.
  Outputs o;
  std::vector<double> ms[7];  // decode, prepare, align, keyframe, verdict, relocalize, total
  // The wall time the first frame is due at: a file's frames are there whenever they are asked for,
  // so the playback starts now; a camera's frames keep coming while the tracker is set up, so its
  // clock starts when the first frame was taken (the frames it queued meanwhile are late).
  const double wall0 = s.live ? t_first : clock(), src0 = frame.time;
  const double t_loop = clock();
  double prev_time = 0;
  uint64_t prev_sequence = frame.sequence;
  Status failure;
  for (int64_t index = 0;; ++index) {
    TrackedFrame f;
    f.index = index;
    f.time = frame.time - src0;
    if (index > 0 && frame.sequence > prev_sequence + 1) s.source_gaps += int64_t(frame.sequence - prev_sequence - 1);
    prev_sequence = frame.sequence;
    if (frame.width != s.source_width || frame.height != s.source_height) {
      failure = invalid_argument(s.stream + ": frame " + std::to_string(index) + " is " + std::to_string(frame.width) + "x" +
                                 std::to_string(frame.height) + ", the first was " + std::to_string(s.source_width) + "x" +
                                 std::to_string(s.source_height));
      break;
    }
    if (a.realtime) {
      // Due at the source's time after the first frame; a file source waits for it, and a frame
      // whose successor is due already (late by one frame interval) is dropped.
      const double due = wall0 + f.time;
      double now = clock();
      if (!s.live && now < due) {
        sleep(due - now);
        now = clock();
      }
      const double interval = f.time - prev_time;
      f.dropped = index > 0 && interval > 0 && now - due >= interval;
    }
    if (f.dropped) {
      ++s.dropped;
      o.dropped.push_back(index);
    } else {
      const double t0 = clock();
      const uint8_t* rgb = nullptr;
      failure = stream.pixels(&rgb);
      if (!failure.ok()) break;
      if (s.downscale > 1) {
        io::box_downsample_rgb8(rgb, s.source_width, s.source_height, s.downscale, K.width, K.height, resized.data());
        rgb = resized.data();
      }
      f.decode_ms = next_ms + (clock() - t0) * 1e3;
      failure = tracker.track(rgb, f.time, &f.result);
      if (!failure.ok()) {
        failure = Status(failure.code(), "frame " + std::to_string(index) + ": " + failure.message());
        break;
      }
      const pose::TrackResult& r = f.result;
      f.has_pose = r.verdict != pose::TrackVerdict::kLost;
      if (r.verdict == pose::TrackVerdict::kTracking) ++s.tracking;
      else if (r.verdict == pose::TrackVerdict::kRelocalized) ++s.relocalized;
      else ++s.lost;
      s.keyframes = r.keyframes;
      if (f.has_pose) {
        const std::string line = io::tum_line({f.time, r.pose}, s.frame);  // the file's numbers, exactly
        const char* p = line.c_str();
        char* e = nullptr;
        std::strtod(p, &e);  // the time
        for (double& v : f.tum) {
          p = e;
          v = std::strtod(p, &e);
        }
        o.placed.push_back(f);
      } else {
        o.lost.emplace_back(index, f.time);
      }
      const double stage[7] = {f.decode_ms, r.ms.prepare, r.ms.align, r.ms.keyframe, r.ms.verdict, r.ms.relocalize, r.ms.total};
      for (int k = 0; k < 7; ++k) ms[k].push_back(stage[k]);
    }
    ++s.frames;
    prev_time = f.time;
    if (on_frame) on_frame(f);
    if (a.max_frames > 0 && s.frames >= a.max_frames) break;
    if (a.stop && a.stop->load()) {
      s.stopped = true;
      break;
    }
    const double t_next = clock();
    failure = stream.next(&frame, &end);
    next_ms = (clock() - t_next) * 1e3;
    if (!failure.ok() || end) break;
  }
  s.seconds = clock() - t_loop;
  s.fps = s.seconds > 0 ? double(s.frames - s.dropped) / s.seconds : 0;
  const char* names[7] = {"decode", "prepare", "align", "keyframe", "verdict", "relocalize", "total"};
  for (int k = 0; k < 7; ++k) s.stages.push_back({names[k], mean(ms[k]), median(ms[k]), percentile95(ms[k])});

  // Files for the frames so far, also after an error mid-stream (none when no frame was reported).
  const int64_t frames = s.frames;
  Status written;
  if (!a.out.empty() && frames > 0) written = write_outputs(a, to, o, &s);
  if (summary) *summary = std::move(s);
  if (failure.ok()) return written;
  if (frames > 0 && !a.out.empty() && written.ok())
    return Status(failure.code(), failure.message() + " (the files in " + a.out + " hold the " + std::to_string(frames) +
                                      " frames before it)");
  return failure;
}

}  // namespace gs::jobs
