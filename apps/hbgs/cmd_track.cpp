// SPDX-License-Identifier: MIT
// `hbgs track RUN|MODEL SOURCE --out DIR`: the flags of gs::jobs::track_run (gs/jobs/track.h), one
// JSON line per frame on stdout (for piping), a progress line on stderr and the summary on stderr
// at the end. `hbgs-device track`: the same, fixed point by default, frames from image folders (it
// links no capture library).
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/jobs/track.h"
#ifndef HBGS_DEVICE
#include "track_source.h"
#endif

namespace hbgs::cli {
namespace {

constexpr const char* kCmd = "track";

#ifdef HBGS_DEVICE
constexpr bool kDevice = true;
#else
constexpr bool kDevice = false;
#endif

std::atomic<bool> g_stop{false};
extern "C" void request_stop(int) { g_stop.store(true); }

struct TrackArgs {
  gs::jobs::TrackRunOptions options;
  bool fixed_point = false, float_blending = false, quiet = false;
};

// The progress line on stderr: rewritten in place on a terminal (at most twice a second), a line
// every 5 s otherwise (as `hbgs train`).
class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}
  void frame(const gs::jobs::TrackedFrame& f) {
    ++frames_;
    if (f.dropped) {
      ++dropped_;
    } else {
      ++tracked_;
      ms_ += f.result.ms.total + f.decode_ms;
      ++timed_;
      if (f.result.verdict == gs::pose::TrackVerdict::kLost) ++lost_;
    }
    const double now = gs::platform::now_seconds(), dt = now - last_;
    if (quiet_ || dt < (tty_ ? 0.5 : 5.0)) return;
    print(f.index, (tracked_ - tracked_at_last_) / dt);
    last_ = now;
    tracked_at_last_ = tracked_;
    ms_ = 0;
    timed_ = 0;
  }
  void finish() {
    if (open_) std::fputc('\n', stderr);
    open_ = false;
  }

 private:
  void print(int64_t index, double fps) {
    std::fprintf(stderr, "%sframe %lld: %.1f fps, %.1f ms per frame (decode included), %lld tracked, %lld lost, %lld dropped%s",
                 tty_ ? "\r\033[K" : "", static_cast<long long>(index), fps, timed_ > 0 ? ms_ / double(timed_) : 0.0,
                 static_cast<long long>(tracked_ - lost_), static_cast<long long>(lost_), static_cast<long long>(dropped_),
                 tty_ ? "" : "\n");
    std::fflush(stderr);
    open_ = tty_;
  }
  bool quiet_, tty_, open_ = false;
  double last_ = gs::platform::now_seconds(), ms_ = 0;
  int64_t frames_ = 0, tracked_ = 0, lost_ = 0, dropped_ = 0, timed_ = 0, tracked_at_last_ = 0;
};

void print_summary(const gs::jobs::TrackRunOptions& a, const gs::jobs::TrackRunSummary& s) {
  const gs::PinholeIntrinsics& K = s.intrinsics;
  for (const std::string& note : s.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  std::fprintf(stderr, "hbgs track: %lld frames of %s (%dx%d%s) against %s, %s%s\n", static_cast<long long>(s.frames),
               s.stream.c_str(), s.source_width, s.source_height,
               s.downscale > 1 ? (", tracked at " + std::to_string(K.width) + "x" + std::to_string(K.height)).c_str() : "",
               s.source.model_path.c_str(), a.tracker.fixed_point ? "fixed point" : "float",
               s.stopped ? " (stopped)" : "");
  std::fprintf(stderr, "  start: %s; verdicts: tracking %lld, relocalized %lld, lost %lld; dropped %lld%s; %llu keyframes\n",
               s.start.c_str(), static_cast<long long>(s.tracking), static_cast<long long>(s.relocalized),
               static_cast<long long>(s.lost), static_cast<long long>(s.dropped),
               s.source_gaps > 0 ? (" (and " + std::to_string(s.source_gaps) + " skipped by the source)").c_str() : "",
               static_cast<unsigned long long>(s.keyframes));
  std::string stages;
  for (const gs::jobs::StageFigures& f : s.stages) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%s%s %.2f", stages.empty() ? "" : ", ", f.stage.c_str(), f.median);
    stages += buf;
  }
  std::fprintf(stderr, "  %.1f fps over %.2f s (decode included, %d threads); median ms per frame: %s\n", s.fps, s.seconds, s.threads,
               stages.c_str());
  if (!s.json_path.empty())
    std::fprintf(stderr, "  files: %s, %s/images.txt, %s, %s\n", s.trajectory_path.c_str(), s.colmap_dir.c_str(), s.lost_path.c_str(),
                 s.json_path.c_str());
}

int run_track(TrackArgs& args) {
  gs::jobs::TrackRunOptions& a = args.options;
  a.tracker.fixed_point = kDevice ? !args.float_blending : args.fixed_point;
#ifndef HBGS_DEVICE
  a.open_source = open_capture_stream;
#endif
  g_stop.store(false);
  a.stop = &g_stop;
  void (*previous)(int) = std::signal(SIGINT, request_stop);  // Ctrl-C ends a live run with its files written
  Progress progress(args.quiet);
  gs::jobs::TrackRunSummary s;
  const gs::Status st = gs::jobs::track_run(
      a,
      [&](const gs::jobs::TrackedFrame& f) {
        std::printf("%s\n", gs::jobs::tracked_frame_json(f).c_str());
        std::fflush(stdout);  // a reader at the other end of a pipe gets each frame as it is tracked
        progress.frame(f);
      },
      &s);
  std::signal(SIGINT, previous);
  progress.finish();
  if (!st.ok()) return fail(kCmd, st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  print_summary(a, s);
  if (s.tracking + s.relocalized == 0) {
    std::fprintf(stderr, "hbgs track: no frame could be placed (exit code %d)\n", kExitNoPose);
    return kExitNoPose;
  }
  return kExitOk;
}

}  // namespace

Command add_track_command(CLI::App& parent) {
  auto args = std::make_shared<TrackArgs>();
  gs::jobs::TrackRunOptions* o = &args->options;
  CLI::App* sub = parent.add_subcommand("track", "Track a camera against a trained model: the pose of every frame of a video, "
                                                 "an image folder or a camera");
  sub->footer(std::string("Prints one JSON line per frame on stdout; progress and the summary go to stderr. Ctrl-C stops a live "
                          "camera and writes the files. Exit codes: 0 done; 3 no frame could be placed (the files are still "
                          "written); 1 an error; 2 a usage error.") +
              (kDevice ? " hbgs-device reads image folders only (no capture library); hbgs track reads video files and cameras."
                       : ""));
  sub->add_option("model", o->input, "Run folder (from hbgs train), .hbgs or .hbgc (compact) model file")->required();
  sub->add_option("source", o->source,
                  kDevice ? "Folder of PNG/JPEG frames (name order)"
                          : "Video file, folder of PNG/JPEG frames (name order), V4L2 device (/dev/videoN) or libcamera:ID")
      ->required();
  sub->add_option("--out", o->out, "Folder for trajectory.txt (TUM), colmap/ (images.txt, cameras.txt), lost.txt and track.json")
      ->required();
  sub->add_option("--intrinsics", o->intrinsics,
                  "fx,fy,cx,cy in pixels of the source's frames (default: the dataset's camera at the model's training "
                  "resolution)");
  sub->add_option("--dataset", o->dataset,
                  "Dataset whose camera and views to use (default: the run's); its views are the relocalisation candidates");
  sub->add_option("--start-pose", o->start_pose,
                  "How the first frame is placed: candidates (relocalised from the dataset's views), first (from the first "
                  "view) or \"qw qx qy qz tx ty tz\" (world-to-camera, COLMAP order)")
      ->capture_default_str();
  sub->add_flag("--realtime", o->realtime,
                "Behave as a live camera: pace a file to its frame times, and drop frames when the tracker falls behind "
                "instead of queueing them");
  if (kDevice) {
    sub->add_flag("--float", args->float_blending, "Float blending (the default on hbgs-device is fixed point)");
  } else {
    sub->add_flag("--fixed-point", args->fixed_point, "On-device mode: fixed-point keyframe and verdict renders");
  }
  sub->add_option("--background", o->background,
                  "Colour behind the model: black, white or r,g,b (default: the run's training background)")
      ->check(background_validator());
  sub->add_option("--threads", o->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--max-frames", o->max_frames, "Stop after this many source frames (0: all)")
      ->capture_default_str()
      ->check(CLI::Range(int64_t(0), int64_t(1000000000000)));
  sub->add_option("--downscale", o->tracker.track_downscale, "Frames are aligned at 1/N of their size")
      ->capture_default_str()
      ->check(CLI::Range(1, 16));
  sub->add_flag("-q,--quiet", args->quiet, "No progress line");
  return {sub, [args] { return run_track(*args); }};
}

}  // namespace hbgs::cli
