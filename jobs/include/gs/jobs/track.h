// SPDX-License-Identifier: MIT
// The tracking job (`hbgs track`, `hbgs-device track`): the pose of every frame of a stream (a
// video file, an image folder, a camera) against a trained model, frame by frame with
// gs::pose::Tracker (gs/model/tracker.h), each frame reported through a callback, and the results
// written into a folder: a TUM trajectory, a COLMAP model of the placed frames, the lost frames and
// a summary. The model comes from a run folder (its dataset gives the intrinsics, the background
// and the training views' poses as relocalisation candidates) or a model file (.hbgs, .hbgc;
// intrinsics from --intrinsics or --dataset).
//
// Frames come through a FrameStream, the seam between this library and gs_capture's frame sources
// (the on-device library set links no capture code): `hbgs` passes an opener over gs::capture (video
// files, image folders, V4L2 devices, libcamera cameras); without one the job reads image folders
// itself (open_image_folder_stream), which is what `hbgs-device` does.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/jobs/run_folder.h"
#include "gs/model/tracker.h"
#include "gs/scene_frame.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::jobs {

// ---- Frames ---------------------------------------------------------------------------------

// One frame of a stream as next() announces it; its pixels come from FrameStream::pixels().
struct StreamFrame {
  int width = 0, height = 0;
  double time = 0;        // seconds on the source's clock (a video's presentation time, a camera's
                          // timestamp, index / fps for an image folder)
  uint64_t sequence = 0;  // the source's frame counter: a gap means frames the source dropped
};

class FrameStream {
 public:
  virtual ~FrameStream() = default;
  virtual std::string name() const = 0;  // for messages, e.g. "video:clip.mp4"
  // A camera delivers frames in real time (frames the job is not ready for wait in its ring or are
  // dropped by it); a file source delivers them as fast as they are asked for.
  virtual bool live() const = 0;
  // Moves to the next frame (the previous one is given back to the source); *end = true, and no
  // frame, at the end of a file source. Errors name the source (a device that went away).
  virtual Status next(StreamFrame* frame, bool* end) = 0;
  // The current frame as RGB24 [height, width, 3], rows packed; valid until the next next().
  // Converted on demand, so a frame the job drops costs no conversion.
  virtual Status pixels(const uint8_t** rgb) = 0;
};

// Opens SOURCE as the user gave it. width, height: the size the job would like (the intrinsics';
// 0 when not known), which a camera may be asked for; a file source delivers its own size.
using FrameStreamOpener =
    std::function<Expected<std::unique_ptr<FrameStream>>(const std::string& source, int width, int height)>;

// A folder of .png, .jpg and .jpeg images (any letter case; other files ignored) in byte-wise name
// order, as frames at index / fps seconds, each the size of the first (else an error naming the
// file): the ordering and times of gs::capture::ImageFolderSource, for programs without gs_capture.
Expected<std::unique_ptr<FrameStream>> open_image_folder_stream(const std::string& folder, double fps = 30);

// ---- The tracker ------------------------------------------------------------------------------

// What the job asks of a tracker: gs::pose::Tracker's calls (see gs/model/tracker.h). The job uses
// gs::pose::Tracker (make_pose_tracker); tests drive the job with a stand-in through
// TrackRunOptions::make_tracker.
class FrameTracker {
 public:
  virtual ~FrameTracker() = default;
  virtual Status set_candidates(const std::vector<Pose>& poses) = 0;
  virtual Status reset(const Pose& start) = 0;
  virtual void reset() = 0;
  virtual Status track(const uint8_t* rgb, double time_seconds, pose::TrackResult* result) = 0;
  virtual uint64_t planned_bytes() const = 0;
};
using TrackerFactory = std::function<Expected<std::unique_ptr<FrameTracker>>(
    const model::HybridModel& model, const PinholeIntrinsics& frame, const pose::TrackOptions& options,
    platform::ThreadPool* pool)>;
// gs::pose::Tracker::create behind FrameTracker.
Expected<std::unique_ptr<FrameTracker>> make_pose_tracker(const model::HybridModel& model, const PinholeIntrinsics& frame,
                                                          const pose::TrackOptions& options, platform::ThreadPool* pool);

// ---- The job ----------------------------------------------------------------------------------

// The files the job writes into TrackRunOptions::out.
inline constexpr const char* kTrackTrajectoryFile = "trajectory.txt";  // TUM: time tx ty tz qx qy qz qw
inline constexpr const char* kTrackColmapDir = "colmap";               // cameras.txt, images.txt, points3D.txt
inline constexpr const char* kTrackLostFile = "lost.txt";              // "frame time" per lost frame
inline constexpr const char* kTrackJson = "track.json";                // the summary

struct TrackRunOptions {
  std::string input;   // run folder, .hbgs or .hbgc model file
  std::string source;  // what the FrameStreamOpener opens (a path, /dev/videoN, libcamera:ID)
  std::string out;     // folder for the files above; "" : none written
  // Intrinsics "fx,fy,cx,cy" (spaces or commas) in pixels of the source's frames; "" : the
  // dataset's one camera (the run's, or --dataset's) at the model's training resolution.
  std::string intrinsics;
  std::string dataset;     // "" : the one in the run's run.json (a model file beside one uses it too)
  std::string background;  // black, white or r,g,b; "" : the run's training background (black without)
  // How the first frame is placed: "candidates" (relocalised from the candidate poses), "first"
  // (aligned from the first candidate: the dataset's first training view, or its first view) or a
  // pose "qw qx qy qz tx ty tz" (world-to-camera, COLMAP order, in the dataset's frame).
  std::string start_pose = "candidates";
  // Behave as a live camera: a frame whose successor is already due when the tracker is ready for
  // it (late by one frame interval or more) is dropped instead of tracked (counted, and reported
  // with dropped = true). A file source is played from when the tracker is ready, paced to its
  // frame times; a camera's times count from when its first frame was taken (so what it queued
  // while the tracker was set up is late).
  bool realtime = false;
  int threads = 0;         // 0: all CPUs
  int64_t max_frames = 0;  // > 0: stop after this many source frames (dropped ones included)
  pose::TrackOptions tracker;  // background is set by the job (from `background`)

  FrameStreamOpener open_source;  // null: image folders only (open_image_folder_stream)
  TrackerFactory make_tracker;    // null: gs::pose::Tracker (make_pose_tracker)
  std::function<double()> clock;  // null: platform::now_seconds (tests inject a fake clock)
  std::function<void(double)> sleep;  // seconds; null: std::this_thread::sleep_for
  const std::atomic<bool>* stop = nullptr;  // set to true: stop after the current frame (Ctrl-C)
};

// One source frame, as the job reports it.
struct TrackedFrame {
  int64_t index = 0;  // 0-based number of the frame in the source (dropped frames count)
  double time = 0;    // seconds since the source's first frame
  bool dropped = false;     // realtime: skipped; result is then empty
  bool has_pose = false;    // verdict tracking or relocalized (lost frames claim no pose)
  pose::TrackResult result;
  double tum[7] = {0, 0, 0, 0, 0, 0, 1};  // has_pose: tx ty tz qx qy qz qw in the user's frame
  double decode_ms = 0;     // getting the frame: decoding or converting it, and resizing
};
// The frame as one line of JSON (no newline): {"frame", "time", "verdict" ("tracking",
// "relocalized", "lost" or "dropped"), "tx" .. "qw" (with a pose), "rmse", "explained",
// "coverage", "iterations", "keyframe", "ms" (the tracker's), "decode_ms"}.
std::string tracked_frame_json(const TrackedFrame& frame);

// Mean, median and 95th percentile (nearest rank) of a stage's milliseconds over the tracked frames.
struct StageFigures {
  std::string stage;  // "decode", then TrackStageMs's fields: prepare, align, keyframe, verdict, relocalize, total
  double mean = 0, median = 0, p95 = 0;
};

struct TrackRunSummary {
  ModelSource source;       // source.dataset: "" when the intrinsics came from --intrinsics alone
  std::string stream;       // the frame stream's name
  bool live = false;
  PinholeIntrinsics intrinsics;  // of the frames as tracked
  int source_width = 0, source_height = 0;
  int downscale = 1;        // frames were box-filtered by this factor to the intrinsics' size
  SceneFrame frame;         // the model's scene frame (outputs are in the user's frame)
  size_t candidates = 0;
  std::string start;        // how the first frame was placed
  int64_t frames = 0;       // source frames read (tracked + dropped)
  int64_t tracking = 0, relocalized = 0, lost = 0, dropped = 0;
  int64_t source_gaps = 0;  // frames the source itself skipped (sequence gaps)
  uint64_t keyframes = 0;   // rendered by the tracker
  uint64_t planned_bytes = 0;
  double seconds = 0;       // wall time from the first frame to the last
  double fps = 0;           // tracked frames per wall second, decoding included
  std::vector<StageFigures> stages;
  int threads = 0;
  bool stopped = false;     // ended by TrackRunOptions::stop
  std::vector<std::string> notes;  // e.g. intrinsics scaled to the frames, a distorted dataset camera
  std::string trajectory_path, colmap_dir, lost_path, json_path;  // "" when out is ""
};

// Runs the job; on_frame (may be null) gets every source frame in order. Errors before the first
// frame (a missing model, an unreadable source, intrinsics that do not fit the frames, a tracker
// that cannot be made) leave no files; an error mid-stream (a camera that went away) still writes
// the files for the frames so far, and the error says so.
Status track_run(const TrackRunOptions& options, const std::function<void(const TrackedFrame&)>& on_frame,
                 TrackRunSummary* summary);

}  // namespace gs::jobs
