// SPDX-License-Identifier: MIT
// generate_path: camera paths through the synth scenes (the sweep for video ingestion, the
// hand-held test trajectory for tracking) rendered as frames, with the true poses as a COLMAP model
// and a TUM file, a JSON description of the path and optionally an H.264 video by ffmpeg.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dataset_parts.h"
#include "gs/constants.h"
#include "gs/io/colmap.h"
#include "gs/io/composite.h"
#include "gs/io/image.h"
#include "gs/io/tum.h"
#include "gs/platform/file.h"
#include "gs/platform/process.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "hbgs/synth.h"
#include "procedural.h"

namespace hbgs::synth {
namespace {

namespace fs = std::filesystem;
using detail::kSceneTarget;
using detail::synth_intrinsics;

using gs::kPi;
constexpr double kDeg = kPi / 180.0;

// The hand-held path's schedule, seconds (see PathOptions in hbgs/synth.h).
constexpr double kPanRamp = 0.1;         // raised-cosine speed ramps at both ends of the pan
constexpr double kTurn = 2.5;            // the slow turns before and after the pan
constexpr double kLead = 0.3;            // still before the first turn starts, at the earliest
constexpr double kSettle = 0.5;          // after the turn back, before the cut, at the least
constexpr double kAfterCut = 1.0;        // the path after the cut, at the least
constexpr double kPanAt = 0.3, kCutAt = 0.6;  // preferred pan centre and cut, fractions of the duration
// Hand shake, RMS per axis: of the position (metres) and of the rotation about the camera's axes.
constexpr double kShakePositionRms = 0.002, kShakeRotationRmsDeg = 0.08;

bool is_object(const PathOptions& o) { return o.scene == PathOptions::SceneKind::kObject; }
bool is_handheld(const PathOptions& o) { return o.kind == PathOptions::Kind::kHandheld; }

// The hand-held path's events in time and frames.
struct HandheldPlan {
  double ramp = 0, pan_seconds = 0;  // ramp length; the pan's whole duration, ramps included
  double pan_start = 0, pan_end = 0;
  int cut = 0;                       // first frame after the jump
  int min_frames = 0;                // the shortest path the schedule fits in
  PathEvents events;
};

HandheldPlan plan_handheld(const PathOptions& o) {
  HandheldPlan p;
  const double plateau_and_ramp = o.pan_deg / o.pan_speed_deg_s;  // the angle is speed x (plateau + ramp)
  p.ramp = std::min(kPanRamp, plateau_and_ramp / 2);
  p.pan_seconds = plateau_and_ramp + p.ramp;
  const double duration = o.frames / o.fps;
  p.pan_start = std::max(kLead + kTurn, kPanAt * duration - p.pan_seconds / 2);
  p.pan_end = p.pan_start + p.pan_seconds;
  const int earliest_cut = int(std::ceil((p.pan_end + kTurn + kSettle) * o.fps - 1e-9));
  p.cut = std::max(int(std::lround(kCutAt * o.frames)), earliest_cut);
  // With the fewest frames the pan starts at kLead + kTurn and the cut comes as early as it may.
  const double earliest_pan_end = kLead + kTurn + p.pan_seconds;
  p.min_frames = int(std::ceil((earliest_pan_end + kTurn + kSettle) * o.fps - 1e-9)) + int(std::ceil(kAfterCut * o.fps - 1e-9));
  p.events.pan_first = int(std::ceil(p.pan_start * o.fps - 1e-9));
  p.events.pan_last = int(std::floor(p.pan_end * o.fps + 1e-9));
  p.events.cut = p.cut;
  return p;
}

// Degrees the view direction is turned (about the vertical through the camera, positive to the
// left) away from the walk's look-at point at time t of the first part of the path.
double gaze_deg(const HandheldPlan& p, const PathOptions& o, double t) {
  const double half = o.pan_deg / 2;
  const double turn_in = p.pan_start - kTurn, turn_out = p.pan_end + kTurn;
  if (t <= turn_in || t >= turn_out) return 0.0;
  if (t < p.pan_start) return -half * (1 - std::cos(kPi * (t - turn_in) / kTurn)) / 2;
  if (t > p.pan_end) return half * (1 + std::cos(kPi * (t - p.pan_end) / kTurn)) / 2;
  // The pan: speed V ramps up as V (1 - cos(pi s / r)) / 2 over r, holds, and ramps down the same.
  const double V = o.pan_speed_deg_s, r = p.ramp, T = p.pan_seconds, s = t - p.pan_start;
  const auto ramp_angle = [&](double u) { return r > 0 ? V * (u - r / kPi * std::sin(kPi * u / r)) / 2 : 0.0; };
  double angle;
  if (s < r) angle = ramp_angle(s);
  else if (s <= T - r) angle = V * r / 2 + V * (s - r);
  else angle = o.pan_deg - ramp_angle(T - s);
  return -half + angle;
}

// Smooth seeded wobble: per axis, three sinusoids of random frequency and phase whose sum has the
// given RMS.
struct Wobble {
  double amp[3][3], freq[3][3], phase[3][3];  // [axis][component]
  void at(double t, double out[3]) const {
    for (int a = 0; a < 3; ++a) {
      out[a] = 0;
      for (int k = 0; k < 3; ++k) out[a] += amp[a][k] * std::sin(2 * kPi * freq[a][k] * t + phase[a][k]);
    }
  }
};

Wobble make_wobble(detail::Rng& rng, double rms, double f_lo, double f_hi) {
  Wobble w;
  for (int a = 0; a < 3; ++a) {
    double sum2 = 0;
    for (int k = 0; k < 3; ++k) {
      w.amp[a][k] = rng.uniform(0.5, 1.0);
      w.freq[a][k] = rng.uniform(f_lo, f_hi);
      w.phase[a][k] = rng.uniform(0.0, 2 * kPi);
      sum2 += w.amp[a][k] * w.amp[a][k];
    }
    const double scale = rms * std::sqrt(2.0 / sum2);  // RMS of a sum of sinusoids: sqrt(sum a^2 / 2)
    for (int k = 0; k < 3; ++k) w.amp[a][k] *= scale;
  }
  return w;
}

// One part of the walk (before or after the cut): where the camera stands and looks, as smooth
// functions of the time since the part began.
struct WalkPart {
  double azimuth_deg, elevation_deg, distance;
};

struct HandheldRig {
  double centre[3];
  double wander;  // metres the look-at point wanders from the centre
  WalkPart before, after;
  Wobble position, rotation;  // metres; radians (camera axes)
};

HandheldRig make_rig(const PathOptions& o, const gs::PinholeIntrinsics& intr) {
  detail::Rng rng(detail::hash_combine(o.seed, 0x4a9d4e1dULL));
  HandheldRig rig;
  if (is_object(o)) {
    std::copy(kObjectCentre, kObjectCentre + 3, rig.centre);
    const double d = detail::object_camera_distance(intr), az = rng.uniform(0.0, 360.0);
    rig.wander = 0.02;
    rig.before = {az, detail::kObjectRingElevationsDeg[1], d};
    rig.after = {az + 180.0, detail::kObjectRingElevationsDeg[2], d};
  } else {
    std::copy(kSceneTarget, kSceneTarget + 3, rig.centre);
    rig.wander = 0.12;
    rig.before = {-95.0, 17.0, 4.5};  // the dataset's forward arc
    rig.after = {85.0, 30.0, 5.0};    // the far side, near its orbit
  }
  rig.position = make_wobble(rng, kShakePositionRms, 0.5, 2.0);
  rig.rotation = make_wobble(rng, kShakeRotationRmsDeg * kDeg, 0.8, 3.0);
  return rig;
}

gs::Pose handheld_pose(const HandheldPlan& p, const HandheldRig& rig, const PathOptions& o, int frame) {
  const double t = frame / o.fps;
  const bool after_cut = frame >= p.cut;
  const double tau = after_cut ? t - p.cut / o.fps : t;  // time since this part began
  const WalkPart& w = after_cut ? rig.after : rig.before;
  const double az = (w.azimuth_deg + 12.0 * std::sin(2 * kPi * tau / 24.0)) * kDeg;
  const double el = (w.elevation_deg + 2.0 * std::sin(2 * kPi * tau / 9.0 + 1.0)) * kDeg;
  const double dist = w.distance * (1 + 0.03 * std::sin(2 * kPi * tau / 7.0 + 2.0));
  double shake[3];
  rig.position.at(t, shake);
  const double eye[3] = {rig.centre[0] + dist * std::cos(el) * std::cos(az) + shake[0],
                         rig.centre[1] + dist * std::cos(el) * std::sin(az) + shake[1],
                         rig.centre[2] + dist * std::sin(el) + shake[2]};
  const double look[3] = {rig.centre[0] + rig.wander * std::sin(2 * kPi * tau / 11.0),
                          rig.centre[1] + rig.wander * std::sin(2 * kPi * tau / 13.0 + 1.0),
                          rig.centre[2] + 0.5 * rig.wander * std::sin(2 * kPi * tau / 8.0 + 2.0)};
  // Turn the view direction about the vertical through the eye.
  const double g = after_cut ? 0.0 : gaze_deg(p, o, t) * kDeg;
  const double f[3] = {look[0] - eye[0], look[1] - eye[1], look[2] - eye[2]};
  const double at[3] = {eye[0] + std::cos(g) * f[0] - std::sin(g) * f[1], eye[1] + std::sin(g) * f[0] + std::cos(g) * f[1],
                        eye[2] + f[2]};
  const gs::Pose base = detail::look_at(eye, at);
  // Hand shake in rotation: a small rotation about the camera's own axes, R = Exp(w) R_base.
  double phi[3], E[9];
  rig.rotation.at(t, phi);
  gs::pose::so3_exp(phi, E);
  gs::Pose pose;
  for (int r = 0; r < 3; ++r) {
    double row[3];
    for (int c = 0; c < 3; ++c)
      row[c] = E[3 * r] * base.R[c] + E[3 * r + 1] * base.R[3 + c] + E[3 * r + 2] * base.R[6 + c];
    for (int c = 0; c < 3; ++c) pose.R[3 * r + c] = float(row[c]);
    pose.t[r] = float(-(row[0] * eye[0] + row[1] * eye[1] + row[2] * eye[2]));
  }
  return pose;
}

// The views of a path: cameras with the COLMAP (qvec, tvec) their poses are read back from.
std::vector<detail::ViewSetup> sweep_views(const PathOptions& o) {
  std::vector<detail::ViewSetup> views;
  const gs::PinholeIntrinsics intr = synth_intrinsics(o.width, o.height);
  for (int i = 0; i < o.frames; ++i) {
    const double s = double(i) / double(o.frames - 1);  // 0..1 along the path
    const double az = (-90.0 - o.sweep_deg / 2 + o.sweep_deg * s) * kPi / 180;
    const double el = (20.0 + 6.0 * std::sin(2.0 * kPi * s)) * kPi / 180;  // the hand rises and falls
    const double radius = 4.4 + 0.3 * std::sin(3.0 * kPi * s);
    const double eye[3] = {kSceneTarget[0] + radius * std::cos(el) * std::cos(az),
                           kSceneTarget[1] + radius * std::cos(el) * std::sin(az), kSceneTarget[2] + radius * std::sin(el)};
    const double at[3] = {kSceneTarget[0] + 0.15 * std::sin(4.0 * kPi * s), kSceneTarget[1] + 0.1 * std::cos(3.0 * kPi * s),
                          kSceneTarget[2] + 0.08 * std::sin(5.0 * kPi * s)};
    views.push_back(detail::make_view(intr, eye, at));
  }
  return views;
}

std::vector<detail::ViewSetup> handheld_views(const PathOptions& o) {
  const gs::PinholeIntrinsics intr = synth_intrinsics(o.width, o.height);
  const HandheldPlan plan = plan_handheld(o);
  const HandheldRig rig = make_rig(o, intr);
  std::vector<detail::ViewSetup> views;
  views.reserve(size_t(o.frames));
  for (int i = 0; i < o.frames; ++i) views.push_back(detail::make_view(intr, handheld_pose(plan, rig, o, i)));
  return views;
}

std::vector<detail::ViewSetup> path_views(const PathOptions& o) { return is_handheld(o) ? handheld_views(o) : sweep_views(o); }

// Camera centres of the training views (all but every 8th by name) of the default dataset of this
// seed and size, and their radius (gs::pose::scene_frame, as hbgs measures pose errors).
double dataset_radius(const PathOptions& o) {
  std::vector<gs::Camera> cams;
  if (is_object(o)) {
    ObjectOptions d;
    d.seed = o.seed, d.width = o.width, d.height = o.height;
    cams = make_object_cameras(d);
  } else {
    SynthOptions d;
    d.seed = o.seed, d.width = o.width, d.height = o.height;
    cams = make_cameras(d);
  }
  std::vector<gs::Pose> train;
  for (size_t i = 0; i < cams.size(); ++i)
    if (i % 8 != 0) train.push_back(cams[i].pose);
  double centre[3], radius = 0;
  gs::pose::scene_frame(train.data(), train.size(), centre, &radius);
  return radius;
}

// A frame as the dataset would show it: the scene's render, or the object's subject composited on
// the background through its coverage.
gs::io::Image8 render_frame(const Scene& scene, const PathOptions& o, const gs::Camera& cam, uint64_t jitter_seed) {
  if (!is_object(o)) return scene.render(cam, o.samples_per_axis, jitter_seed, o.threads);
  gs::io::Image8 rgba;
  scene.render_layers(cam, o.samples_per_axis, jitter_seed, o.threads, nullptr, &rgba);
  const size_t n = size_t(rgba.width) * size_t(rgba.height);
  gs::io::Image8 rgb{rgba.width, rgba.height, 3, std::vector<uint8_t>(3 * n)};
  gs::io::Image8 alpha{rgba.width, rgba.height, 1, std::vector<uint8_t>(n)};
  for (size_t i = 0; i < n; ++i) {
    std::copy(&rgba.pixels[4 * i], &rgba.pixels[4 * i] + 3, &rgb.pixels[3 * i]);
    alpha.pixels[i] = rgba.pixels[4 * i + 3];
  }
  return gs::io::composite_rgb8(rgb, alpha, o.background);
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// video.mp4 from the frames by the ffmpeg command line; skipped (note set) without ffmpeg or for
// odd sides.
gs::Status encode_video(const PathOptions& o, const fs::path& root, PathSummary* summary) {
  if (o.width % 2 != 0 || o.height % 2 != 0) {
    summary->video_note = "the video is skipped: H.264 in 4:2:0 needs an even width and height, got " +
                          std::to_string(o.width) + "x" + std::to_string(o.height);
    return gs::Status::Ok();
  }
  const std::string ffmpeg = gs::platform::find_program(o.ffmpeg);
  if (ffmpeg.empty()) {
    summary->video_note = "the video is skipped: " + o.ffmpeg +
                          " was not found on PATH (install ffmpeg, or encode the frames yourself: ffmpeg -framerate " +
                          number(o.fps) + " -i frames/frame_%06d.png -c:v libx264 -pix_fmt yuv420p " + kPathVideoFile + ")";
    return gs::Status::Ok();
  }
  // ffmpeg reads the frames through a printf-style pattern: a '%' of the folder must be doubled.
  std::string pattern;
  for (char c : (root / kPathFramesDir).string()) pattern += c == '%' ? std::string("%%") : std::string(1, c);
  pattern += "/frame_%06d.png";
  const fs::path final_path = root / kPathVideoFile, partial = root / "video.partial.mp4";
  const std::vector<std::string> argv = {ffmpeg, "-v", "error", "-nostdin", "-y", "-framerate", number(o.fps),
                                         "-start_number", "0", "-i", pattern, "-frames:v", std::to_string(o.frames),
                                         "-c:v", "libx264", "-preset", "medium", "-crf", "18", "-pix_fmt", "yuv420p",
                                         // BT.601 limited range, as ffmpeg converts the RGB frames: said in
                                         // the stream so no decoder guesses another matrix.
                                         "-colorspace", "smpte170m", "-color_primaries", "smpte170m",
                                         "-color_trc", "smpte170m", "-color_range", "tv", "-threads", "1", "-map_metadata", "-1", "-fflags", "+bitexact",
                                         "-flags:v", "+bitexact", partial.string()};
  std::string output;
  const auto t0 = std::chrono::steady_clock::now();
  gs::Expected<gs::platform::ProcessResult> run =
      gs::platform::run_process(argv, "", [&](const std::string& line) { output += line + "\n"; });
  summary->video_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!run.ok()) return run.status();
  std::error_code ec;
  if (run->exit_code != 0) {
    fs::remove(partial, ec);
    return gs::io_error("ffmpeg (" + ffmpeg + ") failed with exit code " + std::to_string(run->exit_code) +
                        " encoding " + final_path.string() + (output.empty() ? std::string() : ":\n" + output));
  }
  fs::rename(partial, final_path, ec);
  if (ec) return gs::io_error("cannot rename " + partial.string() + " to " + final_path.string() + ": " + ec.message());
  summary->video_written = true;
  return gs::Status::Ok();
}

gs::Status write_json(const PathOptions& o, const gs::PinholeIntrinsics& K, const PathSummary& s, const fs::path& root) {
  nlohmann::json scene = {{"kind", is_object(o) ? "object" : "scene"},
                          {"seed", o.seed},
                          {"dataset", std::string("hbgs synth") + (is_object(o) ? " --object" : "") + " --seed " +
                                          std::to_string(o.seed) + " --width " + std::to_string(o.width) +
                                          " --height " + std::to_string(o.height)},
                          {"dataset_radius", dataset_radius(o)}};
  if (is_object(o)) scene["background"] = {o.background[0], o.background[1], o.background[2]};
  nlohmann::json j = {{"kind", is_handheld(o) ? "handheld" : "sweep"},
                      {"scene", scene},
                      {"fps", o.fps},
                      {"frames", o.frames},
                      {"duration_s", o.frames / o.fps},
                      {"width", o.width},
                      {"height", o.height},
                      {"intrinsics", {{"fx", K.fx}, {"fy", K.fy}, {"cx", K.cx}, {"cy", K.cy}}},
                      {"samples_per_axis", o.samples_per_axis},
                      {"pan", nullptr},
                      {"cut", nullptr},
                      {"files",
                       {{"frames", std::string(kPathFramesDir) + "/frame_%06d.png"},
                        {"video", s.video_written ? nlohmann::json(kPathVideoFile) : nlohmann::json(nullptr)},
                        {"tum", kPathTumFile},
                        {"colmap", kPathTruePosesDir}}}};
  if (is_handheld(o)) {
    j["pan"] = {{"first_frame", s.events.pan_first},
                {"last_frame", s.events.pan_last},
                {"degrees", o.pan_deg},
                {"peak_deg_per_s", o.pan_speed_deg_s}};
    j["cut"] = {{"frame", s.events.cut}, {"time_s", s.events.cut / o.fps}};
    j["shake"] = {{"position_rms_per_axis_m", kShakePositionRms}, {"rotation_rms_per_axis_deg", kShakeRotationRmsDeg}};
  } else {
    j["sweep_deg"] = o.sweep_deg;
  }
  return gs::platform::write_file_atomic((root / kPathJsonFile).string(), j.dump(2) + "\n");
}

gs::Expected<PathSummary> generate_path_impl(const PathOptions& o, const std::string& out_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const std::vector<detail::ViewSetup> views = path_views(o);
  const gs::PinholeIntrinsics& intr = views.front().camera.intr;
  std::unique_ptr<Scene> scene;
  {
    auto scene_or = is_object(o) ? Scene::create_object(o.seed, false, detail::object_camera_distance(intr)) : Scene::create(o.seed);
    if (!scene_or.ok()) return scene_or.status();
    scene = std::move(scene_or.value());
  }
  const fs::path root(out_dir), frames = root / kPathFramesDir;
  GS_RETURN_IF_ERROR(gs::platform::make_dirs(frames.string()));

  PathSummary summary;
  summary.frames = o.frames;
  summary.events = path_events(o);
  gs::io::ColmapModel model;
  model.cameras.push_back(detail::colmap_pinhole(intr));
  std::vector<gs::io::TimedPose> timed;
  // The sweep keeps its jitter stream (its frames are unchanged); the hand-held path has its own.
  const uint64_t stream = is_handheld(o) ? 0x5000000ULL : 0x2000000ULL;
  // Render a batch of frames (rows in parallel), then encode their PNGs in parallel.
  constexpr int kBatch = 16;
  gs::platform::ThreadPool pool(o.threads);
  std::vector<gs::io::Image8> images(kBatch);
  std::vector<std::string> names(kBatch);
  std::vector<gs::Status> written(kBatch);
  for (int first = 0; first < o.frames; first += kBatch) {
    const int count = std::min(kBatch, o.frames - first);
    for (int b = 0; b < count; ++b) {
      const int i = first + b;
      char name[32];
      std::snprintf(name, sizeof name, "frame_%06d.png", i);
      names[size_t(b)] = name;
      gs::io::ColmapImage im;
      im.id = uint32_t(i + 1);
      im.camera_id = 1;
      im.name = name;
      const detail::ViewSetup& view = views[size_t(i)];
      std::copy(view.qvec, view.qvec + 4, im.qvec);
      std::copy(view.tvec, view.tvec + 3, im.tvec);
      model.images.push_back(im);
      timed.push_back({i / o.fps, view.camera.pose});
      images[size_t(b)] = render_frame(*scene, o, view.camera, detail::hash_combine(o.seed, stream + uint64_t(i)));
    }
    pool.for_each_index(size_t(count), [&](size_t b) {
      written[b] = gs::io::write_png((frames / names[b]).string(), images[b]);
    });
    for (int b = 0; b < count; ++b) GS_RETURN_IF_ERROR(written[size_t(b)]);
    if (o.verbose && ((first + count) / 64 != first / 64 || first + count == o.frames))
      std::fprintf(stderr, "synth path: %d / %d frames, %.1f s\n", first + count, o.frames, elapsed());
  }
  summary.render_seconds = elapsed();
  GS_RETURN_IF_ERROR(gs::io::write_colmap_text(model, (root / kPathTruePosesDir).string()));
  GS_RETURN_IF_ERROR(gs::io::write_tum_trajectory(timed, (root / kPathTumFile).string()));
  if (o.video) GS_RETURN_IF_ERROR(encode_video(o, root, &summary));
  GS_RETURN_IF_ERROR(write_json(o, intr, summary, root));
  summary.seconds = elapsed();
  return summary;
}

}  // namespace

gs::Status validate_path(const PathOptions& o) {
  if (o.width < 8 || o.height < 8 || o.width > gs::io::kMaxImageSide || o.height > gs::io::kMaxImageSide)
    return gs::invalid_argument("synth path: image size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                " out of range");
  if (o.frames < 2 || o.frames > 100000) return gs::invalid_argument("synth path: frames must be in [2, 100000]");
  if (!(o.sweep_deg > 0.0 && o.sweep_deg <= 360.0)) return gs::invalid_argument("synth path: sweep must be in (0, 360]");
  if (o.samples_per_axis < 1 || o.samples_per_axis > 16) return gs::invalid_argument("synth path: samples out of range");
  if (!(o.fps >= 1.0 && o.fps <= 1000.0)) return gs::invalid_argument("synth path: fps must be in [1, 1000]");
  for (float c : o.background)
    if (!(c >= 0.0f && c <= 1.0f)) return gs::invalid_argument("synth path: background colour values must be in [0, 1]");
  if (is_object(o) && (2 * o.width < o.height || 2 * o.height < o.width))
    return gs::invalid_argument("synth path: the object's image sides may differ by a factor of 2 at most, got " +
                                std::to_string(o.width) + "x" + std::to_string(o.height));
  if (!is_handheld(o)) {
    if (is_object(o)) return gs::invalid_argument("synth path: the sweep runs through the built-in scene only");
    return gs::Status::Ok();
  }
  if (!(o.pan_deg > 0.0 && o.pan_deg <= 180.0)) return gs::invalid_argument("synth path: pan must be in (0, 180] degrees");
  if (!(o.pan_speed_deg_s >= 1.0 && o.pan_speed_deg_s <= 720.0))
    return gs::invalid_argument("synth path: pan speed must be in [1, 720] degrees per second");
  const HandheldPlan plan = plan_handheld(o);
  if (o.frames < plan.min_frames)
    return gs::invalid_argument("synth path: a hand-held trajectory needs at least " + std::to_string(plan.min_frames) +
                                " frames at " + number(o.fps) + " fps for its turns, its pan (" + number(plan.pan_seconds) +
                                " s) and its cut, got " + std::to_string(o.frames));
  return gs::Status::Ok();
}

std::vector<gs::Camera> make_path_cameras(const PathOptions& o) {
  std::vector<gs::Camera> cams;
  if (!validate_path(o).ok()) return cams;
  for (const detail::ViewSetup& v : path_views(o)) cams.push_back(v.camera);
  return cams;
}

PathEvents path_events(const PathOptions& o) {
  if (!is_handheld(o) || !validate_path(o).ok()) return PathEvents{};
  return plan_handheld(o).events;
}

gs::Expected<PathSummary> generate_path(const PathOptions& o, const std::string& out_dir) {
  GS_RETURN_IF_ERROR(validate_path(o));
  if (out_dir.empty()) return gs::invalid_argument("synth path: empty output directory");
  // Thread start-up, allocation and filesystem failures surface as exceptions; hbgs reports errors
  // as Status, never by throwing past its API.
  try {
    return generate_path_impl(o, out_dir);
  } catch (const std::exception& e) {
    return gs::Status(gs::StatusCode::kInternal, std::string("synth path: ") + e.what());
  }
}

}  // namespace hbgs::synth
